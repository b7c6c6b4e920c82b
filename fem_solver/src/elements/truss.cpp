#include "truss.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "common/errors.hpp"

namespace fem {

namespace {
Vec3 at(std::span<const double> u, std::uint32_t n) { return {u[3 * n], u[3 * n + 1], u[3 * n + 2]}; }
}  // namespace

Truss::Truss(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& X, const Params& p)
    : conn_(std::move(connectivity)), p_(p) {
  for (std::size_t e = 0; e < size(); ++e) {
    axis_.push_back(X[conn_[2 * e + 1]] - X[conn_[2 * e]]);
    length_.push_back(axis_.back().norm());
    if (!(length_.back() > 0))
      throw common::SimulationError(
          fmt::format("truss element {} (nodes {}, {}) has zero length.", e, conn_[2 * e], conn_[2 * e + 1]));
  }
}

std::pair<Vec3, double> Truss::kinematics(std::span<const double> u, std::size_t e) const {
  const Vec3 du = at(u, conn_[2 * e + 1]) - at(u, conn_[2 * e]);
  const double L = length_[e];
  return {axis_[e] + du, (2 * axis_[e].dot(du) + du.squaredNorm()) / (2 * L * L)};
}

double Truss::pk2(double strain) const {
  const double s = p_.young * strain + p_.prestress;
  return p_.tensionOnly && s < 0.0 ? 0.0 : s;
}

double Truss::internalForces(std::span<const double> u, std::span<double> slots) const {
  double energy = 0.0;
  for (std::size_t e = 0; e < size(); ++e) {
    const double L = length_[e];
    const auto [d, strain] = kinematics(u, e);
    const double S = pk2(strain);
    const Vec3 f = weight(e) * S * p_.area / L * d;
    for (int k = 0; k < 3; ++k) {
      slots[6 * e + static_cast<std::size_t>(k)] = -f[k];
      slots[6 * e + 3 + static_cast<std::size_t>(k)] = f[k];
    }
    if (S != 0.0 || !p_.tensionOnly)
      energy += weight(e) * p_.area * L * (0.5 * p_.young * strain * strain + p_.prestress * strain);
  }
  return energy;
}

void Truss::tangent(std::span<const double> u, std::vector<Triplet>& triplets) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const double L = length_[e];
    const auto [d, strain] = kinematics(u, e);
    const double S = pk2(strain);
    const bool slack = p_.tensionOnly && p_.young * strain + p_.prestress < 0.0;
    Eigen::Matrix3d K = (slack ? 0.0 : p_.young / (L * L)) * d * d.transpose();
    K.diagonal().array() += S;
    K *= p_.area / L;
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        const double sign = i == j ? 1.0 : -1.0;
        const auto ni = conn_[2 * e + static_cast<std::size_t>(i)], nj = conn_[2 * e + static_cast<std::size_t>(j)];
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            triplets.emplace_back(static_cast<int>(3 * ni + static_cast<unsigned>(a)),
                                  static_cast<int>(3 * nj + static_cast<unsigned>(b)), sign * K(a, b));
      }
  }
}

void Truss::addLumpedMass(std::span<double> m) const {
  for (std::size_t e = 0; e < size(); ++e)
    for (int i = 0; i < 2; ++i) m[conn_[2 * e + static_cast<std::size_t>(i)]] += weight(e) * p_.density * p_.area * length_[e] / 2;
}

double Truss::criticalTimeStep() const {
  // Lumped two-node bar: ω_max = 2c/L exactly, so dt_crit = L / c, c = √((E + σ₀⁺)/ρ).
  const double c = std::sqrt((p_.young + std::max(p_.prestress, 0.0)) / p_.density);
  double dt = std::numeric_limits<double>::infinity();
  for (double L : length_) dt = std::min(dt, L / c);
  return dt;
}

Element::Current Truss::current(std::span<const double> u) const {
  // Lumped bar in the current state: the axial stiffness of the nominal force is (E λ² + S) A / L with
  // S the PK2 stress (d(λ S)/dλ, S = E (λ² − 1)/2 + σ₀), so dt = L / √((E λ² + S⁺)/ρ).
  Current out{std::numeric_limits<double>::infinity(), 0, std::numeric_limits<double>::infinity()};
  for (std::size_t e = 0; e < size(); ++e) {
    const auto [d, strain] = kinematics(u, e);
    const double stretch = d.norm() / length_[e];
    const double c = std::sqrt((p_.young * std::max(stretch * stretch, 1.0) + std::max(pk2(strain), 0.0)) / p_.density);
    out.criticalTimeStep = std::min(out.criticalTimeStep, length_[e] / c);
    if (stretch < out.jacobian) out.jacobian = stretch, out.element = e;
  }
  return out;
}

void Truss::stress(std::span<const double> u, std::span<double> out) const {
  for (std::size_t e = 0; e < size(); ++e) {
    const double L = length_[e];
    const auto [d, strain] = kinematics(u, e);
    out[e] = pk2(strain) * p_.area * d.norm() / L;  // axial force N
  }
}

}  // namespace fem
