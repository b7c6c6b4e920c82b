#pragma once
// Shared by the contact laws: the normal force with a zero clamp, and the incremental, force-based
// tangential spring with Coulomb cap (dem_solver/README.md §Tangential), each for one lane of a
// ContactBlock. Inline: called inside the laws' vectorised block loops.

#include <algorithm>
#include <cmath>

#include "batch_law.hpp"

namespace dem::detail {

/// Normal force of lane i: elastic part `fel` plus dashpot −γ v_n, clamped at zero (no attraction). Sets
/// the lane's dashpot dissipation, normal force and the force along the normal; returns F_n.
inline double normalLane(ContactBlock& b, int i, double fel, double gammaN, double vn, double dt) {
  const double fn = std::max(fel - gammaN * vn, 0.0);
  b.damping[i] = -(fn - fel) * vn * dt;
  b.friction[i] = 0.0;
  b.fn[i] = fn;
  b.fx[i] = fn * b.nx[i];
  b.fy[i] = fn * b.ny[i];
  b.fz[i] = fn * b.nz[i];
  return fn;
}

/// Tangential force of lane i, added to its force. `kt` the current tangential stiffness, `gammaT` the
/// dashpot, `mu` Coulomb, `fn` the normal force, `scale` the factor applied to the stored spring force
/// before the increment (Mindlin unloading: a/a_old), `stiffer` k_t / k_t,old (a/a_old for Mindlin, 1 for a
/// constant k_t; read only if the contact touched at the last step). Updates the lane's history and
/// energies.
///
/// Coulomb is checked on the spring: if the trial spring force exceeds μ F_n the contact slides, the
/// spring is cut back to μ F_n (μ F_n times the cut length is the friction dissipation) and the dashpot is
/// off. Otherwise the dashpot adds −γ v_t, reduced if needed so that the total stays within μ F_n. Both
/// dissipations are ≥ 0 by construction. Written with selects, not branches: both cases are computed
/// (a lane's discarded case may hold inf or NaN) so the laws' block loops vectorise.
inline void tangentialLane(ContactBlock& b, int i, double kt, double gammaT, double mu, double fn, double scale,
                           double stiffer, double dt) {
  const double nx = b.nx[i], ny = b.ny[i], nz = b.nz[i];
  const double vn = b.vx[i] * nx + b.vy[i] * ny + b.vz[i] * nz;
  const double vtx = b.vx[i] - vn * nx, vty = b.vy[i] - vn * ny, vtz = b.vz[i] - vn * nz;
  // Bring the stored spring force into the current tangent plane, keeping its magnitude.
  double fsx = b.sx[i], fsy = b.sy[i], fsz = b.sz[i];
  const double mag2 = fsx * fsx + fsy * fsy + fsz * fsz;
  const double fsn = fsx * nx + fsy * ny + fsz * nz;
  fsx -= fsn * nx, fsy -= fsn * ny, fsz -= fsn * nz;
  const double projected2 = fsx * fsx + fsy * fsy + fsz * fsz;
  const double keep = projected2 > 0.0 ? scale * std::sqrt(mag2 / projected2) : 1.0;
  fsx *= keep, fsy *= keep, fsz *= keep;
  // A stiffness that changes with δ (Mindlin) changes the stored energy |F_s|²/(2k_t) at constant force;
  // with the unloading rescale this only ever lowers it. That loss is the model's own: booked as friction.
  const double half = 0.5 / kt;  // 1/(2 k_t): the one division of the energy terms
  const double rescaled2 = fsx * fsx + fsy * fsy + fsz * fsz;
  // |F_s|²/(2 k_t,old) at the last step: 1/(2 k_t,old) = half · k_t / k_t,old.
  double friction = b.lastOverlap[i] > 0.0 ? mag2 * (half * stiffer) - rescaled2 * half : 0.0;
  const double step = kt * dt;
  fsx -= step * vtx, fsy -= step * vty, fsz -= step * vtz;
  const double limit = mu * fn;
  const double trial2 = fsx * fsx + fsy * fsy + fsz * fsz;
  const bool slide = trial2 > limit * limit;
  // Sliding: the spring length beyond the cap, (|f_trial| − μF_n)/k_t, is the slip of this step, made
  // against μF_n.
  const double trial = std::sqrt(trial2);
  const double cut = limit / trial;
  const double slideFriction = 2.0 * limit * (trial - limit) * half;
  // Sticking: spring plus dashpot, the dashpot scaled by s ≤ 1 to stay within the cap.
  const double fdx = -gammaT * vtx, fdy = -gammaT * vty, fdz = -gammaT * vtz;
  const double b2 = fdx * fdx + fdy * fdy + fdz * fdz;
  const double px = fsx + fdx, py = fsy + fdy, pz = fsz + fdz;
  const bool over = px * px + py * py + pz * pz > limit * limit && b2 > 0.0;
  const double ab = fsx * fdx + fsy * fdy + fsz * fdz;
  const double s = over ? (-ab + std::sqrt(std::max(ab * ab - b2 * (trial2 - limit * limit), 0.0))) / b2 : 1.0;
  const double vt2 = vtx * vtx + vty * vty + vtz * vtz;
  b.damping[i] += slide ? 0.0 : s * gammaT * vt2 * dt;
  friction += slide ? slideFriction : 0.0;
  b.friction[i] += friction;
  const double ftx = slide ? fsx * cut : fsx + s * fdx;
  const double fty = slide ? fsy * cut : fsy + s * fdy;
  const double ftz = slide ? fsz * cut : fsz + s * fdz;
  fsx = slide ? ftx : fsx, fsy = slide ? fty : fsy, fsz = slide ? ftz : fsz;
  b.elastic[i] += (fsx * fsx + fsy * fsy + fsz * fsz) * half;
  b.sx[i] = fsx, b.sy[i] = fsy, b.sz[i] = fsz;
  b.fx[i] += ftx, b.fy[i] += fty, b.fz[i] += ftz;
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
