#include "linear_spring_dashpot.hpp"

#include <cmath>

#include "dem/restitution.hpp"
#include "tangential.hpp"

namespace dem {

LinearSpringDashpot::LinearSpringDashpot(double kn, double kt, const InteractionParams& params)
    : kn_(kn), kt_(kt), c_(dampingForRestitution(NormalModel::kLinear, params.restitution)), params_(params) {}

template <bool kFriction>
[[gnu::always_inline]] inline void LinearSpringDashpot::blockLoop(detail::ContactBlock& b, double dt) const {
  const double mu = params_.friction, kn = kn_, kt = kt_, c = c_;
  const double rootKn = std::sqrt(kn), rootKt = std::sqrt(kt);
#pragma omp simd
  for (int i = 0; i < b.n; ++i) {
    const double d = b.overlap[i];
    const double vn = b.vx[i] * b.nx[i] + b.vy[i] * b.ny[i] + b.vz[i] * b.nz[i];
    const double root = std::sqrt(b.effMass[i]);
    const double fn = detail::normalLane(b, i, kn * d, c * root * rootKn, vn, dt);
    b.elastic[i] = 0.5 * kn * d * d;
    if constexpr (kFriction) detail::tangentialLane(b, i, kt, c * root * rootKt, mu, fn, 1.0, 1.0, dt);
  }
}

ImpactPrediction LinearSpringDashpot::elasticImpact(double, double effMass, double speed) const {
  const double w = std::sqrt(kn_ / effMass);
  return {3.14159265358979323846 / w, speed / w};
}

ContactLaw::NormalTangent LinearSpringDashpot::normalTangent(double, double effMass, double overlap) const {
  return {kn_, c_ * std::sqrt(kn_ * effMass), kn_ * overlap};
}

double LinearSpringDashpot::criticalTimeStep(const Material&, double, double effMass) const {
  // Central difference on an undamped oscillator is stable for dt < 2/ω.
  return 2.0 * std::sqrt(effMass / kn_);
}

}  // namespace dem
