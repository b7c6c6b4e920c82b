#include "fem/initial_motion.hpp"

#include "common/bridging_zone.hpp"

#include <cmath>
#include <numbers>

namespace fem {

void InitialWave::apply(Model& model) const {
  std::vector<double> u(model.dofs(), 0.0), v(model.dofs(), 0.0);
  const double pi = std::numbers::pi;
  for (std::size_t n = 0; n < model.nodes(); ++n) {
    const double xi = (axis.dot(model.reference[n]) - center) / halfWidth;
    if (std::abs(xi) >= 1.0) continue;
    const double g = 0.5 * (1.0 + std::cos(pi * xi));
    const double dgds = -0.5 * pi * std::sin(pi * xi) / halfWidth;
    for (int k = 0; k < 3; ++k) {
      u[3 * n + static_cast<std::size_t>(k)] = amplitude * g * axis[k];
      v[3 * n + static_cast<std::size_t>(k)] = -direction * speed * amplitude * dgds * axis[k];
    }
  }
  model.setDisplacement(u);
  model.initialVelocity = std::move(v);
}

InitialWave readInitialWave(const common::Config& c) {
  using common::Interval;
  InitialWave w;
  w.axis = common::readAxis(c, "axis");
  w.center = c.get<double>("center");
  w.halfWidth = c.get("half_width", Interval::positive());
  w.amplitude = c.get<double>("amplitude");
  w.speed = c.get("speed", Interval::nonNegative());
  w.direction = c.get("direction", 1.0, Interval::closed(-1.0, 1.0));
  if (w.direction != 1.0 && w.direction != -1.0) c.failAt("direction", "is 1 (towards +axis) or -1.");
  c.checkUnknownKeys();
  return w;
}

void InitialVelocity::apply(Model& model) const {
  model.initialVelocity.assign(model.dofs(), 0.0);
  for (std::size_t n = 0; n < model.nodes(); ++n) {
    const Vec3& x = model.reference[n];
    const Vec3 v = value + strainRate * axis.dot(x) * axis + angular.cross(x - center);
    for (int k = 0; k < 3; ++k) model.initialVelocity[3 * n + static_cast<std::size_t>(k)] = v[k];
  }
}

InitialVelocity readInitialVelocity(const common::Config& c) {
  InitialVelocity v;
  v.value = c.get<Eigen::Vector3d>("value", Eigen::Vector3d::Zero());
  v.axis = common::readAxis(c, "axis", "x");
  v.strainRate = c.get<double>("strain_rate", 0.0);
  v.angular = c.get<Eigen::Vector3d>("angular", Eigen::Vector3d::Zero());
  v.center = c.get<Eigen::Vector3d>("center", Eigen::Vector3d::Zero());
  c.checkUnknownKeys();
  return v;
}

}  // namespace fem
