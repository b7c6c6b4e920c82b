#pragma once
// Shared by the contact laws: the normal force with a zero clamp, and the incremental, force-based
// tangential spring with Coulomb cap (dem_solver/README.md §Tangential). Inline: called per contact
// inside the laws' batch loops.

#include <cmath>

#include "dem/contact_law.hpp"

namespace dem::detail {

/// Normal force: elastic part `fel` plus dashpot −γ v_n, clamped at zero (no attraction). Adds the
/// dashpot's dissipation to out.dampingEnergy and returns F_n.
inline double normalForce(double fel, double gammaN, double vn, double dt, ContactForce& out) {
  const double fn = std::max(fel - gammaN * vn, 0.0);
  out.dampingEnergy += -(fn - fel) * vn * dt;
  return fn;
}

/// Tangential force on a. `kt` the current tangential stiffness, `gammaT` the dashpot, `mu` Coulomb,
/// `fn` the normal force, `scale` the factor applied to the stored spring force before the increment
/// (Mindlin unloading: a/a_old). Updates the history and the energies of `out`.
///
/// Coulomb is checked on the spring: if the trial spring force exceeds μ F_n the contact slides, the
/// spring is cut back to μ F_n (μ F_n times the cut length is the friction dissipation) and the dashpot is off. Otherwise
/// the dashpot adds −γ v_t, reduced if needed so that the total stays within μ F_n. Both dissipations are
/// ≥ 0 by construction.
inline Vec3 tangentialForce(const ContactPoint& p, ContactHistory& h, double kt, double gammaT, double mu, double fn,
                            double scale, double dt, ContactForce& out) {
  const Vec3& n = p.normal;
  const Vec3 vt = p.relVelocity - p.relVelocity.dot(n) * n;
  // Bring the stored spring force into the current tangent plane, keeping its magnitude.
  Vec3 fs = h.shearForce;
  const double mag2 = fs.squaredNorm();
  fs -= fs.dot(n) * n;
  const double projected2 = fs.squaredNorm();
  if (projected2 > 0.0) fs *= scale * std::sqrt(mag2 / projected2);
  // A stiffness that changes with δ (Mindlin) changes the stored energy |F_s|²/(2k_t) at constant force;
  // with the unloading rescale this only ever lowers it. That loss is the model's own: booked as friction.
  const double half = 0.5 / kt;  // 1/(2 k_t): the one division of the energy terms
  if (h.lastHalfCompliance > 0.0) out.frictionEnergy += mag2 * h.lastHalfCompliance - fs.squaredNorm() * half;
  h.lastHalfCompliance = half;
  fs -= kt * dt * vt;
  const double limit = mu * fn;
  const double trial2 = fs.squaredNorm();
  Vec3 ft;
  if (trial2 > limit * limit) {
    const double trial = std::sqrt(trial2);
    const Vec3 capped = fs * (limit / trial);
    // The spring length beyond the cap, (|f_trial| − μF_n)/k_t, is the slip of this step, made against μF_n.
    out.frictionEnergy += 2.0 * limit * (trial - limit) * half;
    fs = capped;
    ft = capped;
  } else {
    const Vec3 fd = -gammaT * vt;
    double s = 1.0;
    const double b2 = fd.squaredNorm();
    if ((fs + fd).squaredNorm() > limit * limit && b2 > 0.0) {
      const double ab = fs.dot(fd);
      s = (-ab + std::sqrt(std::max(ab * ab - b2 * (trial2 - limit * limit), 0.0))) / b2;
    }
    ft = fs + s * fd;
    out.dampingEnergy += s * gammaT * vt.squaredNorm() * dt;
  }
  out.elasticEnergy += fs.squaredNorm() * half;
  h.shearForce = fs;
  return ft;
}

/// Rolling resistance, constant directional torque (README §Rolling resistance), applied by the
/// simulation after the law (a pass that only runs when some interaction has μ_r > 0): the couple on a is
/// −μ_r R* F_n along the rolling part of ω_a − ω_b (its component in the tangent plane), capped at the
/// couple that stops that rolling within the step (I* |ω_r| / dt), so a ball comes to rest instead of
/// rocking. Books its dissipation |M| |ω_r| dt as friction.
inline Vec3 rollingTorque(const Vec3& normal, const Vec3& relAngularVelocity, double effRadius, double effInertia,
                          double muR, double fn, double dt, ContactForce& out) {
  const Vec3 wr = relAngularVelocity - relAngularVelocity.dot(normal) * normal;
  const double w = wr.norm();
  if (w == 0.0) return Vec3::Zero();
  const double m = std::min(muR * effRadius * fn, effInertia * w / dt);
  out.frictionEnergy += m * w * dt;
  return -m / w * wr;
}

}  // namespace dem::detail
