#include "membrane_tri3.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "common/errors.hpp"

namespace fem {

MembraneTri3::MembraneTri3(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& X, const Params& p)
    : conn_(std::move(connectivity)), p_(p) {
  const double c = p.young / (1 - p.poisson * p.poisson);
  D_ << c, c * p.poisson, 0, c * p.poisson, c, 0, 0, 0, c * (1 - p.poisson) / 2;
  ref_.resize(size());
  for (std::size_t e = 0; e < size(); ++e) {
    const Vec3 &a = X[conn_[3 * e]], &b = X[conn_[3 * e + 1]], &d = X[conn_[3 * e + 2]];
    const Vec3 n = (b - a).cross(d - a);
    const double twiceArea = n.norm();
    if (!(twiceArea > 1e-14 * (b - a).squaredNorm()))
      throw common::SimulationError(fmt::format("membrane_tri3 element {} (nodes {}, {}, {}) has zero area.", e,
                                                conn_[3 * e], conn_[3 * e + 1], conn_[3 * e + 2]));
    const Vec3 e1 = (b - a).normalized(), e2 = n.normalized().cross(e1);
    const Eigen::Vector2d p1(0, 0), p2((b - a).dot(e1), (b - a).dot(e2)), p3((d - a).dot(e1), (d - a).dot(e2));
    const double A2 = (p2.x() - p1.x()) * (p3.y() - p1.y()) - (p3.x() - p1.x()) * (p2.y() - p1.y());
    Ref& r = ref_[e];
    r.grad[0] = Eigen::Vector2d(p2.y() - p3.y(), p3.x() - p2.x()) / A2;
    r.grad[1] = Eigen::Vector2d(p3.y() - p1.y(), p1.x() - p3.x()) / A2;
    r.grad[2] = Eigen::Vector2d(p1.y() - p2.y(), p2.x() - p1.x()) / A2;
    r.area = 0.5 * A2;
    r.frame.col(0) = e1;
    r.frame.col(1) = e2;
    r.minAltitude = A2 / std::max({(b - a).norm(), (d - b).norm(), (a - d).norm()});
  }
}

Eigen::Matrix<double, 3, 2> MembraneTri3::displacementGradient(std::span<const double> u, std::size_t e) const {
  Eigen::Matrix<double, 3, 2> H = Eigen::Matrix<double, 3, 2>::Zero();
  for (int i = 0; i < 3; ++i) {
    const std::size_t n = conn_[3 * e + static_cast<std::size_t>(i)];
    H += Vec3(u[3 * n], u[3 * n + 1], u[3 * n + 2]) * ref_[e].grad[static_cast<std::size_t>(i)].transpose();
  }
  return H;
}

Eigen::Vector3d MembraneTri3::strain(const Eigen::Matrix<double, 3, 2>& H, const Eigen::Matrix<double, 3, 2>& F0) const {
  const Eigen::Matrix2d G = F0.transpose() * H;
  const Eigen::Matrix2d HH = H.transpose() * H;
  return {G(0, 0) + 0.5 * HH(0, 0), G(1, 1) + 0.5 * HH(1, 1), G(0, 1) + G(1, 0) + HH(0, 1)};
}

double MembraneTri3::internalForces(std::span<const double> u, std::span<double> slots) const {
  double energy = 0.0;
  const auto ne = static_cast<std::ptrdiff_t>(size());
#pragma omp parallel for schedule(static) reduction(+ : energy) if (ne > 512)
  for (std::ptrdiff_t ei = 0; ei < ne; ++ei) {
    const auto e = static_cast<std::size_t>(ei);
    const Ref& r = ref_[e];
    const auto H = displacementGradient(u, e);
    const Eigen::Matrix<double, 3, 2> F = r.frame + H;
    const Eigen::Vector3d E = strain(H, r.frame);
    const Eigen::Vector3d S = D_ * E + Eigen::Vector3d(p_.prestress, p_.prestress, 0);
    Eigen::Matrix2d Sm;
    Sm << S(0), S(2), S(2), S(1);
    const double scale = weight(e) * p_.thickness * r.area;
    const Eigen::Matrix<double, 3, 2> P = scale * F * Sm;
    for (int i = 0; i < 3; ++i) {
      const Vec3 f = P * r.grad[static_cast<std::size_t>(i)];
      for (int k = 0; k < 3; ++k) slots[9 * e + 3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(k)] = f[k];
    }
    energy += scale * (0.5 * E.dot(D_ * E) + p_.prestress * (E(0) + E(1)));
  }
  return energy;
}

void MembraneTri3::tangent(std::span<const double> u, std::vector<Triplet>& triplets) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const Ref& r = ref_[e];
    const auto H = displacementGradient(u, e);
    const Eigen::Matrix<double, 3, 2> F = r.frame + H;
    const Eigen::Vector3d S = D_ * strain(H, r.frame) + Eigen::Vector3d(p_.prestress, p_.prestress, 0);
    Eigen::Matrix2d Sm;
    Sm << S(0), S(2), S(2), S(1);
    std::array<Eigen::Matrix3d, 3> B;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector2d& g = r.grad[static_cast<std::size_t>(i)];
      B[static_cast<std::size_t>(i)].row(0) = g.x() * F.col(0).transpose();
      B[static_cast<std::size_t>(i)].row(1) = g.y() * F.col(1).transpose();
      B[static_cast<std::size_t>(i)].row(2) = g.x() * F.col(1).transpose() + g.y() * F.col(0).transpose();
    }
    const double scale = p_.thickness * r.area;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const auto ii = static_cast<std::size_t>(i), jj = static_cast<std::size_t>(j);
        Eigen::Matrix3d K = B[ii].transpose() * D_ * B[jj];
        K.diagonal().array() += r.grad[ii].dot(Sm * r.grad[jj]);
        K *= scale;
        const auto ni = conn_[3 * e + ii], nj = conn_[3 * e + jj];
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            triplets.emplace_back(static_cast<int>(3 * ni + static_cast<unsigned>(a)),
                                  static_cast<int>(3 * nj + static_cast<unsigned>(b)), K(a, b));
      }
  }
}

void MembraneTri3::addLumpedMass(std::span<double> m) const {
  for (std::size_t e = 0; e < size(); ++e)
    for (int i = 0; i < 3; ++i) m[conn_[3 * e + static_cast<std::size_t>(i)]] += weight(e) * p_.density * p_.thickness * ref_[e].area / 3;
}

double MembraneTri3::criticalTimeStep() const {
  // Element eigenvalue analysis of the lumped CST: dt_crit ≥ 0.827 h_min / c for any shape and ν ≤ 0.3
  // over the element's shapes, c = √(E / (ρ (1 − ν²))) — the plate wave speed, not the bulk one.
  const double c = std::sqrt(p_.young / (p_.density * (1 - p_.poisson * p_.poisson)));
  double dt = std::numeric_limits<double>::infinity();
  for (const auto& r : ref_) dt = std::min(dt, 0.827 * r.minAltitude / c);
  return dt;
}

Element::Current MembraneTri3::current(std::span<const double> u) const {
  // The lumped CST bound of criticalTimeStep() with the wave modulus of the current state: under a
  // stretch λ the St. Venant–Kirchhoff tangent of the nominal stress is E λ² (d(λS)/dλ = S + λ² E), and a
  // tensile stress S adds the string's S to ρ c².
  Current out{std::numeric_limits<double>::infinity(), 0, std::numeric_limits<double>::infinity()};
  const double plate = p_.young / (1 - p_.poisson * p_.poisson);
  for (std::size_t e = 0; e < size(); ++e) {
    const Ref& r = ref_[e];
    const auto H = displacementGradient(u, e);
    const Eigen::Matrix<double, 3, 2> F = r.frame + H;
    const Eigen::Matrix2d C = F.transpose() * F;
    const Eigen::Vector3d S = D_ * strain(H, r.frame) + Eigen::Vector3d(p_.prestress, p_.prestress, 0);
    Eigen::Matrix2d Sm;
    Sm << S(0), S(2), S(2), S(1);
    const double stretch2 = std::max(C.trace() / 2 + std::sqrt(std::pow((C(0, 0) - C(1, 1)) / 2, 2) + C(0, 1) * C(0, 1)), 0.0);
    const double sMax = Sm.trace() / 2 + std::sqrt(std::pow((Sm(0, 0) - Sm(1, 1)) / 2, 2) + Sm(0, 1) * Sm(0, 1));
    const double c = std::sqrt((plate * std::max(stretch2, 1.0) + std::max(sMax, 0.0)) / p_.density);
    out.criticalTimeStep = std::min(out.criticalTimeStep, 0.827 * r.minAltitude / c);
    const double area = std::sqrt(std::max(C.determinant(), 0.0));
    if (area < out.jacobian) out.jacobian = area, out.element = e;
  }
  return out;
}

void MembraneTri3::stress(std::span<const double> u, std::span<double> out) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const Eigen::Vector3d S =
        D_ * strain(displacementGradient(u, e), ref_[e].frame) + Eigen::Vector3d(p_.prestress, p_.prestress, 0);
    for (int k = 0; k < 3; ++k) out[3 * e + static_cast<std::size_t>(k)] = S[k];
  }
}

void MembraneTri3::addPressure(double q, const Vec3& dir, std::span<double> force) const {
  for (std::size_t e = 0; e < size(); ++e)
    for (int i = 0; i < 3; ++i) {
      const auto n = conn_[3 * e + static_cast<std::size_t>(i)];
      for (int k = 0; k < 3; ++k) force[3 * n + static_cast<std::size_t>(k)] += q * ref_[e].area / 3 * dir[k];
    }
}

}  // namespace fem
