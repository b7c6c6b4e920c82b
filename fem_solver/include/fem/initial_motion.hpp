#pragma once
// The motion an explicit run starts with, besides rest.
//
// `explicit.initial_velocity: {value: [vx, vy, vz], axis, strain_rate, angular: [ωx, ωy, ωz], center}`:
// v(X) = value + ε̇ (e·X) e + ω × (X − center) — a rigid translation, a uniform stretching along e or a
// rigid rotation (the patch tests of a coupling zone).
//
// `explicit.initial_wave`: a travelling longitudinal pulse as the initial state of an explicit run (`explicit.initial_wave`): the
// displacement u(X) = A g(ξ) e along the axis e, ξ = (e·X − center) / half_width, with the raised cosine
// g(ξ) = (1 + cos πξ) / 2 on |ξ| ≤ 1 (zero outside), and the velocity of the same profile moving at
// `speed` c in `direction` d: v = −d c ∂u/∂s, so that u(X, t) = f(e·X − d c t) (d'Alembert). For a bar,
// c = √(E/ρ) sends the whole pulse one way; a wave problem that needs a clean incident pulse (the
// bridging domain's reflection test) starts from it.
#include "common/config.hpp"
#include "fem/model.hpp"

namespace fem {

struct InitialWave {
  Vec3 axis = Vec3::UnitX();
  double center = 0.0, halfWidth = 1.0, amplitude = 0.0, speed = 0.0, direction = 1.0;
  /// Sets the model's displacement and its initial velocity (call after Model::finalize()).
  void apply(Model& model) const;
};

InitialWave readInitialWave(const common::Config& c);

struct InitialVelocity {
  Vec3 value = Vec3::Zero(), axis = Vec3::UnitX(), angular = Vec3::Zero(), center = Vec3::Zero();
  double strainRate = 0.0;
  /// Sets the model's initial velocity (call after Model::finalize()).
  void apply(Model& model) const;
};

InitialVelocity readInitialVelocity(const common::Config& c);

}  // namespace fem
