#include "cohesive_frictional.hpp"

#include <algorithm>
#include <cmath>

#include "dem/restitution.hpp"
#include "tangential.hpp"

namespace dem {

namespace {
constexpr double kPi = 3.14159265358979323846;

// E_h = 2 E_a E_b / (E_a + E_b); a rigid side (a wall that does not deform) is the limit E_b → ∞.
double harmonicModulus(const Material& a, const Material& b) {
  if (a.rigid) return 2.0 * b.youngModulus;
  if (b.rigid) return 2.0 * a.youngModulus;
  return 2.0 * a.youngModulus * b.youngModulus / (a.youngModulus + b.youngModulus);
}
}  // namespace

CohesiveFrictional::CohesiveFrictional(const Material& a, const Material& b, double shearRatio,
                                       const Strength& strength, const InteractionParams& params)
    : twoModulus_(2.0 * harmonicModulus(a, b)),
      shearRatio_(shearRatio),
      c_(dampingForRestitution(NormalModel::kLinear, params.restitution)),
      strength_(strength),
      params_(params) {}

template <bool kFriction>
[[gnu::always_inline]] inline void CohesiveFrictional::blockLoop(detail::ContactBlock& b, double dt) const {
  const double mu = params_.friction, twoE = twoModulus_, alpha = shearRatio_, c = c_;
  const double rootAlpha = std::sqrt(alpha);
#pragma omp simd
  for (int i = 0; i < b.n; ++i) {
    const double d = b.overlap[i];
    const double kn = twoE * b.effRadius[i];
    const double vn = b.vx[i] * b.nx[i] + b.vy[i] * b.ny[i] + b.vz[i] * b.nz[i];
    const double gammaN = c * std::sqrt(b.effMass[i] * kn);
    const double fn = detail::normalLane(b, i, kn * d, gammaN, vn, dt);
    b.elastic[i] = 0.5 * kn * d * d;
    if constexpr (kFriction) detail::tangentialLane(b, i, alpha * kn, gammaN * rootAlpha, mu, fn, 1.0, 1.0, dt);
  }
}

Bond CohesiveFrictional::makeBond(double ra, double rb, double effMass, double overlap) const {
  Bond bond;
  bond.kn = twoModulus_ * ra * rb / (ra + rb);
  bond.ks = shearRatio_ * bond.kn;
  const double rmin = std::min(ra, rb);
  const double area = kPi * rmin * rmin;
  bond.tensile = strength_.tensile * area;
  bond.cohesion = strength_.cohesion * area;
  bond.friction = params_.friction;
  // A pair that overlaps keeps its compression; a pair with a gap is at rest there.
  bond.restOverlap = std::min(overlap, 0.0);
  bond.gammaN = c_ * std::sqrt(effMass * bond.kn);
  bond.gammaT = c_ * std::sqrt(effMass * bond.ks);
  return bond;
}

BondForce CohesiveFrictional::bondForce(Bond& bond, const Vec3& n, double overlap, const Vec3& relVelocity,
                                        double dt) const {
  BondForce out;
  const double vn = relVelocity.dot(n);
  const Vec3 vt = relVelocity - vn * n;
  const double fnElastic = bond.kn * (overlap - bond.restOverlap);
  // The stored shear force turned into the current tangent plane at its magnitude, then the increment
  // (as the contacts' tangential spring, README §Tangential).
  Vec3 fs = bond.shearForce;
  const double magnitude = fs.norm();
  fs -= fs.dot(n) * n;
  if (const double projected = fs.norm(); projected > 0.0) fs *= magnitude / projected;
  fs -= bond.ks * dt * vt;
  out.normalForce = fnElastic;
  out.elastic = 0.5 * fnElastic * fnElastic / bond.kn + 0.5 * fs.squaredNorm() / bond.ks;
  // Tension beyond σ_t A, or shear beyond c A + μ F_n (F_n signed: tension weakens the bond).
  if (-fnElastic > bond.tensile || fs.norm() > bond.cohesion + bond.friction * fnElastic) {
    out.broke = true;
    // The contact that replaces it starts with no shear spring and its own normal spring k_n δ.
    const double after = overlap > 0.0 ? 0.5 * bond.kn * overlap * overlap : 0.0;
    out.released = out.elastic - after;
    out.elastic = 0.0;
    return out;
  }
  bond.shearForce = fs;
  out.force = (fnElastic - bond.gammaN * vn) * n + fs - bond.gammaT * vt;
  out.damping = (bond.gammaN * vn * vn + bond.gammaT * vt.squaredNorm()) * dt;
  return out;
}

ImpactPrediction CohesiveFrictional::elasticImpact(double effRadius, double effMass, double speed) const {
  const double w = std::sqrt(twoModulus_ * effRadius / effMass);
  return {kPi / w, speed / w};
}

ContactLaw::NormalTangent CohesiveFrictional::normalTangent(double effRadius, double effMass, double overlap) const {
  const double kn = twoModulus_ * effRadius;
  return {kn, c_ * std::sqrt(kn * effMass), kn * overlap};
}

double CohesiveFrictional::criticalTimeStep(const Material&, double radius, double effMass) const {
  // The stiffest contact of a sphere of this radius is with a wall (R* = r); central differences on the
  // undamped oscillator are stable for dt < 2/ω.
  return 2.0 * std::sqrt(effMass / (twoModulus_ * radius));
}

}  // namespace dem
