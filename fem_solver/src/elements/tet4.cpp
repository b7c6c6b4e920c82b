#include "tet4.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "common/errors.hpp"

namespace fem {

namespace {
Vec3 at(std::span<const double> u, std::uint32_t n) { return {u[3 * n], u[3 * n + 1], u[3 * n + 2]}; }
}  // namespace

Tet4::Tet4(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& X, const Params& p)
    : conn_(std::move(connectivity)), p_(p) {
  lambda_ = p.young * p.poisson / ((1 + p.poisson) * (1 - 2 * p.poisson));
  mu_ = p.young / (2 * (1 + p.poisson));
  D_.setZero();
  D_.topLeftCorner<3, 3>().setConstant(lambda_);
  D_.topLeftCorner<3, 3>().diagonal().array() += 2 * mu_;
  D_.bottomRightCorner<3, 3>().diagonal().setConstant(mu_);
  criticalDt_ = std::numeric_limits<double>::infinity();
  for (std::size_t e = 0; e < size(); ++e) {
    Eigen::Matrix3d J;
    for (int k = 0; k < 3; ++k) J.col(k) = X[conn_[4 * e + 1 + static_cast<std::size_t>(k)]] - X[conn_[4 * e]];
    double det = J.determinant();
    if (det < 0) {  // gmsh may orient either way: swap two nodes
      std::swap(conn_[4 * e + 1], conn_[4 * e + 2]);
      for (int k = 0; k < 3; ++k) J.col(k) = X[conn_[4 * e + 1 + static_cast<std::size_t>(k)]] - X[conn_[4 * e]];
      det = -det;
    }
    if (!(det > 1e-14 * J.squaredNorm() * std::sqrt(J.squaredNorm())))
      throw common::SimulationError(fmt::format("tet4 element {} has zero volume.", e));
    const Eigen::Matrix3d G = J.inverse().transpose();  // columns: ∇N_2, ∇N_3, ∇N_4
    grad_.push_back({-(G.col(0) + G.col(1) + G.col(2)), G.col(0), G.col(1), G.col(2)});
    volume_.push_back(det / 6);
    // Exact element bound: ω_max² = λ_max(M^{-1/2} K M^{-1/2}) with the lumped mass ρV/4.
    const Eigen::Matrix<double, 12, 12> K = stiffness(Eigen::Matrix3d::Zero(), e) / (p.density * volume_.back() / 4);
    const double wmax2 = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>>(K, Eigen::EigenvaluesOnly)
                             .eigenvalues()
                             .maxCoeff();
    elementDt_.push_back(2.0 / std::sqrt(wmax2));
    criticalDt_ = std::min(criticalDt_, elementDt_.back());
  }
}

Eigen::Matrix3d Tet4::displacementGradient(std::span<const double> u, std::size_t e) const {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 4; ++i) H += at(u, conn_[4 * e + static_cast<std::size_t>(i)]) * grad_[e][static_cast<std::size_t>(i)].transpose();
  return H;
}

Tet4::Voigt Tet4::pk2(const Eigen::Matrix3d& H) const {
  const Eigen::Matrix3d E = 0.5 * (H + H.transpose() + H.transpose() * H);
  Voigt Ev;
  Ev << E(0, 0), E(1, 1), E(2, 2), 2 * E(0, 1), 2 * E(1, 2), 2 * E(0, 2);
  return D_ * Ev;
}

Eigen::Matrix<double, 12, 12> Tet4::stiffness(const Eigen::Matrix3d& H, std::size_t e) const {
  const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + H;
  const Voigt s = pk2(H);
  Eigen::Matrix3d S;
  S << s(0), s(3), s(5), s(3), s(1), s(4), s(5), s(4), s(2);
  std::array<Eigen::Matrix<double, 6, 3>, 4> B;
  for (int i = 0; i < 4; ++i) {
    const Vec3& g = grad_[e][static_cast<std::size_t>(i)];
    auto& b = B[static_cast<std::size_t>(i)];
    for (int a = 0; a < 3; ++a) b.row(a) = g[a] * F.col(a).transpose();
    b.row(3) = g[0] * F.col(1).transpose() + g[1] * F.col(0).transpose();
    b.row(4) = g[1] * F.col(2).transpose() + g[2] * F.col(1).transpose();
    b.row(5) = g[0] * F.col(2).transpose() + g[2] * F.col(0).transpose();
  }
  Eigen::Matrix<double, 12, 12> K;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const auto ii = static_cast<std::size_t>(i), jj = static_cast<std::size_t>(j);
      Eigen::Matrix3d k = B[ii].transpose() * D_ * B[jj];
      k.diagonal().array() += grad_[e][ii].dot(S * grad_[e][jj]);
      K.block<3, 3>(3 * i, 3 * j) = volume_[e] * k;
    }
  return K;
}

double Tet4::internalForces(std::span<const double> u, std::span<double> slots) const {
  double energy = 0.0;
  const auto ne = static_cast<std::ptrdiff_t>(size());
#pragma omp parallel for schedule(static) reduction(+ : energy) if (ne > 512)
  for (std::ptrdiff_t ei = 0; ei < ne; ++ei) {
    const auto e = static_cast<std::size_t>(ei);
    const Eigen::Matrix3d H = displacementGradient(u, e);
    const Eigen::Matrix3d E = 0.5 * (H + H.transpose() + H.transpose() * H);
    const Eigen::Matrix3d S = lambda_ * E.trace() * Eigen::Matrix3d::Identity() + 2 * mu_ * E;
    const Eigen::Matrix3d P = weight(e) * volume_[e] * (Eigen::Matrix3d::Identity() + H) * S;
    for (int i = 0; i < 4; ++i) {
      const Vec3 f = P * grad_[e][static_cast<std::size_t>(i)];
      for (int k = 0; k < 3; ++k) slots[12 * e + 3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(k)] = f[k];
    }
    energy += weight(e) * volume_[e] * (0.5 * lambda_ * E.trace() * E.trace() + mu_ * (E.array() * E.array()).sum());
  }
  return energy;
}

void Tet4::tangent(std::span<const double> u, std::vector<Triplet>& triplets) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const auto K = stiffness(displacementGradient(u, e), e);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            triplets.emplace_back(static_cast<int>(3 * conn_[4 * e + static_cast<std::size_t>(i)] + static_cast<unsigned>(a)),
                                  static_cast<int>(3 * conn_[4 * e + static_cast<std::size_t>(j)] + static_cast<unsigned>(b)),
                                  K(3 * i + a, 3 * j + b));
  }
}

void Tet4::addLumpedMass(std::span<double> m) const {
  for (std::size_t e = 0; e < size(); ++e)
    for (int i = 0; i < 4; ++i) m[conn_[4 * e + static_cast<std::size_t>(i)]] += weight(e) * p_.density * volume_[e] / 4;
}

Element::Current Tet4::current(std::span<const double> u) const {
  // Each element's exact reference bound, scaled by its wave modulus now: the tangent of the nominal
  // stress grows as λ_max² E and a tensile S_max adds to ρ c² (as for the bar: d(λ S)/dλ = S + λ² E),
  // so dt_e = dt_e,ref / √(max(λ_max², 1) + S_max⁺ / (λ + 2μ)). A 12 × 12 eigen-solve per element at every
  // check would cost more than the steps between checks.
  Current out{std::numeric_limits<double>::infinity(), 0, std::numeric_limits<double>::infinity()};
  const double pWave = lambda_ + 2 * mu_;
  for (std::size_t e = 0; e < size(); ++e) {
    const Eigen::Matrix3d H = displacementGradient(u, e);
    const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + H;
    const double J = F.determinant();
    if (J < out.jacobian) out.jacobian = J, out.element = e;
    const Voigt s = pk2(H);
    Eigen::Matrix3d S;
    S << s(0), s(3), s(5), s(3), s(1), s(4), s(5), s(4), s(2);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> c, st;
    c.computeDirect(F.transpose() * F, Eigen::EigenvaluesOnly);
    st.computeDirect(S, Eigen::EigenvaluesOnly);
    const double factor = std::max(c.eigenvalues().maxCoeff(), 1.0) + std::max(st.eigenvalues().maxCoeff(), 0.0) / pWave;
    out.criticalTimeStep = std::min(out.criticalTimeStep, elementDt_[e] / std::sqrt(factor));
  }
  return out;
}

void Tet4::stress(std::span<const double> u, std::span<double> out) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const Voigt s = pk2(displacementGradient(u, e));
    for (int k = 0; k < 6; ++k) out[6 * e + static_cast<std::size_t>(k)] = s(k);
  }
}

}  // namespace fem
