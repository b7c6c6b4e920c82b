#include "hertz_mindlin.hpp"

#include <algorithm>
#include <cmath>

#include "dem/restitution.hpp"
#include "tangential.hpp"

namespace dem {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

HertzMindlin::HertzMindlin(const Material& a, const Material& b, const InteractionParams& params)
    : eStar_(1.0 / ((1 - a.poissonRatio * a.poissonRatio) / a.youngModulus +
                    (1 - b.poissonRatio * b.poissonRatio) / b.youngModulus)),
      gStar_(1.0 / ((2 - a.poissonRatio) / a.shearModulus() + (2 - b.poissonRatio) / b.shearModulus())),
      c_(dampingForRestitution(NormalModel::kHertz, params.restitution)),
      shearToNormal_(std::sqrt(4.0 * gStar_ / eStar_)),
      params_(params) {}

void HertzMindlin::pairForce(const ContactPoint& p, ContactHistory& h, ContactForce& f, double dt) const {
  const double a = std::sqrt(p.effRadius * p.overlap);  // contact radius
  const double fel = 4.0 / 3.0 * eStar_ * a * p.overlap;
  const double sn = 2.0 * eStar_ * a;
  const double vn = p.relVelocity.dot(p.normal);
  const double gammaN = c_ * std::sqrt(sn * p.effMass);
  const double fn = detail::normalForce(fel, gammaN, vn, dt, f);
  f.elasticEnergy = 0.4 * fel * p.overlap;  // ∫ F dδ = (2/5) K δ^{5/2}
  f.normalForce = fn;
  f.force = fn * p.normal;
  if (params_.friction > 0.0) {
    const double st = 8.0 * gStar_ * a;
    const double scale = p.overlap < h.lastOverlap ? std::sqrt(p.overlap / h.lastOverlap) : 1.0;
    // c √(S_t m*) = c √(S_n m*) √(S_t / S_n) with S_t / S_n = 4G*/E* fixed: one square root fewer.
    f.force += detail::tangentialForce(p, h, st, gammaN * shearToNormal_, params_.friction, fn, scale, dt, f);
  }
}

ImpactPrediction HertzMindlin::elasticImpact(double effRadius, double effMass, double speed) const {
  // Johnson (1985) §11.4: δ_max = (15 m* v² / (16 E* √R*))^{2/5}; t = 2 δ_max/v ∫₀¹ (1 − x^{5/2})^{-1/2} dx.
  const double dmax = std::pow(15.0 * effMass * speed * speed / (16.0 * eStar_ * std::sqrt(effRadius)), 0.4);
  const double integral = 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
  return {2.0 * dmax / speed * integral, dmax};
}

double HertzMindlin::criticalTimeStep(const Material& m, double radius, double) const {
  // Rayleigh-wave step of the sphere's own material (Li et al. 2005; as in LIGGGHTS/YADE): a wall's
  // material carries no particle waves.
  return kPi * radius * std::sqrt(m.density / m.shearModulus()) / (0.1631 * m.poissonRatio + 0.8766);
}

}  // namespace dem
