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
    : eStar_(1.0 / (a.normalCompliance() + b.normalCompliance())),
      gStar_(1.0 / (a.shearCompliance() + b.shearCompliance())),
      c_(dampingForRestitution(NormalModel::kHertz, params.restitution)),
      shearToNormal_(std::sqrt(4.0 * gStar_ / eStar_)),
      params_(params) {}

template <bool kFriction>
[[gnu::always_inline]] inline void HertzMindlin::blockLoop(detail::ContactBlock& b, double dt) const {
  const double mu = params_.friction;
  const double gMod = gStar_, eMod = eStar_, c = c_, shearToNormal = shearToNormal_;
#pragma omp simd
  for (int i = 0; i < b.n; ++i) {
    const double d = b.overlap[i];
    const double a = std::sqrt(b.effRadius[i] * d);  // contact radius
    const double fel = 4.0 / 3.0 * eMod * a * d;
    const double sn = 2.0 * eMod * a;
    const double vn = b.vx[i] * b.nx[i] + b.vy[i] * b.ny[i] + b.vz[i] * b.nz[i];
    const double gammaN = c * std::sqrt(sn * b.effMass[i]);
    const double fn = detail::normalLane(b, i, fel, gammaN, vn, dt);
    b.elastic[i] = 0.4 * fel * d;  // ∫ F dδ = (2/5) K δ^{5/2}
    if constexpr (kFriction) {
      const double st = 8.0 * gMod * a;
      const double last = b.lastOverlap[i];
      const double ratio = std::sqrt(d / last);  // a / a_old (any value when last = 0: not read then)
      const double scale = d < last ? ratio : 1.0;
      // c √(S_t m*) = c √(S_n m*) √(S_t / S_n) with S_t / S_n = 4G*/E* fixed: one square root fewer.
      detail::tangentialLane(b, i, st, gammaN * shearToNormal, mu, fn, scale, ratio, dt);
    }
  }
}

ImpactPrediction HertzMindlin::elasticImpact(double effRadius, double effMass, double speed) const {
  // Johnson (1985) §11.4: δ_max = (15 m* v² / (16 E* √R*))^{2/5}; t = 2 δ_max/v ∫₀¹ (1 − x^{5/2})^{-1/2} dx.
  const double dmax = std::pow(15.0 * effMass * speed * speed / (16.0 * eStar_ * std::sqrt(effRadius)), 0.4);
  const double integral = 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
  return {2.0 * dmax / speed * integral, dmax};
}

ContactLaw::NormalTangent HertzMindlin::normalTangent(double effRadius, double effMass, double overlap) const {
  const double sn = 2.0 * eStar_ * std::sqrt(effRadius * overlap);  // d/dδ of (4/3) E* √R* δ^{3/2}
  return {sn, c_ * std::sqrt(sn * effMass), sn * overlap * (2.0 / 3.0)};  // (4/3) E* √R* δ^{3/2}
}

double HertzMindlin::criticalTimeStep(const Material& m, double radius, double) const {
  // Rayleigh-wave step of the sphere's own material (Li et al. 2005; as in LIGGGHTS/YADE): a wall's
  // material carries no particle waves.
  return kPi * radius * std::sqrt(m.density / m.shearModulus()) / (0.1631 * m.poissonRatio + 0.8766);
}

}  // namespace dem
