#include "linear_spring_dashpot.hpp"

#include <cmath>

#include "dem/restitution.hpp"
#include "tangential.hpp"

namespace dem {

LinearSpringDashpot::LinearSpringDashpot(double kn, double kt, const InteractionParams& params)
    : kn_(kn), kt_(kt), c_(dampingForRestitution(NormalModel::kLinear, params.restitution)), params_(params) {}

void LinearSpringDashpot::pairForce(const ContactPoint& p, ContactHistory& h, ContactForce& f, double dt) const {
  const double vn = p.relVelocity.dot(p.normal);
  const double root = std::sqrt(p.effMass);
  const double fel = kn_ * p.overlap;
  const double fn = detail::normalForce(fel, c_ * root * std::sqrt(kn_), vn, dt, f);
  f.elasticEnergy = 0.5 * kn_ * p.overlap * p.overlap;
  f.normalForce = fn;
  f.force = fn * p.normal;
  if (params_.friction > 0.0)
    f.force += detail::tangentialForce(p, h, kt_, c_ * root * std::sqrt(kt_), params_.friction, fn, 1.0, dt, f);
}

ImpactPrediction LinearSpringDashpot::elasticImpact(double, double effMass, double speed) const {
  const double w = std::sqrt(kn_ / effMass);
  return {3.14159265358979323846 / w, speed / w};
}

double LinearSpringDashpot::criticalTimeStep(const Material&, double, double effMass) const {
  // Central difference on an undamped oscillator is stable for dt < 2/ω.
  return 2.0 * std::sqrt(effMass / kn_);
}

}  // namespace dem
