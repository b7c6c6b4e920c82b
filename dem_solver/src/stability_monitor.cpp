#include "dem/stability_monitor.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "dem/contact_queries.hpp"
#include "dem/time_steps.hpp"

namespace dem {

namespace {
// The ledger sums terms as large as the potential energy m g z: its round-off is about 1e-16 of them,
// summed over many steps. A residual below this share of them is arithmetic, not physics.
constexpr double kRoundOff = 1e-9;
}  // namespace

StabilityMonitor::StabilityMonitor(double initialEnergy, double potentialEnergy, double approachSpeed,
                                   double energyTolerance)
    : tolerance_(energyTolerance),
      initialScale_(std::abs(initialEnergy) + std::abs(potentialEnergy)),
      approachSpeed_(approachSpeed) {}

void StabilityMonitor::observe(const Simulation& sim) {
  const Bodies& B = sim.bodies();
  // The two fastest bodies' speeds, squared: the largest, then the largest of the others (the largest
  // again if two bodies share it). Maxima are exact in any order, so the threads change no bit.
  const auto n = static_cast<std::ptrdiff_t>(B.size());
  double first = 0.0, second = 0.0;
  int atFirst = 0;
#pragma omp parallel for schedule(static) reduction(max : first) if (n > kParallelMin)
  for (std::ptrdiff_t b = 0; b < n; ++b) first = std::max(first, B.velocity[b].squaredNorm());
#pragma omp parallel for schedule(static) reduction(max : second) reduction(+ : atFirst) if (n > kParallelMin)
  for (std::ptrdiff_t b = 0; b < n; ++b) {
    const double v2 = B.velocity[b].squaredNorm();
    if (v2 == first) ++atFirst;
    else second = std::max(second, v2);
  }
  if (atFirst > 1) second = first;
  approachSpeed_ = std::max(approachSpeed_, std::sqrt(first) + std::sqrt(second));
  const double stable = dem::contactStableStep(sim);
  contactStable_ = std::min(contactStable_, stable);
  if (!warned_ && sim.settings().dt > stable) {
    warned_ = true;
    common::logger("dem")->warn(
        "t = {:.4g} s: dt = {:.4g} s is above the stable step of the contact network now, {:.4g} s (compressed contacts "
        "stiffen: k = 2 E* √(R* δ), summed over a sphere's contacts); the energy check stops the run if it diverges. "
        "A dt of {:.3g} s would be safe.",
        sim.time(), sim.settings().dt, stable, recommendedTimeStep(sim));
  }
}

double StabilityMonitor::recommendedTimeStep(const Simulation& sim) const {
  return std::min(safeTimeStep(sim, approachSpeed_), sim.settings().dtSafety * contactStable_);
}

void StabilityMonitor::check(const Simulation& sim, const EnergyLedger& e, double initialEnergy) {
  energyScale_ = std::max(energyScale_, std::abs(e.kinetic) + e.elastic + e.damping + e.friction + e.cundall + e.bondFracture +
                                            std::abs(e.wallWork) + std::abs(e.externalWork));
  const double residual = e.residual(initialEnergy);
  maxResidual_ = std::max(maxResidual_, std::abs(residual));
  if (std::abs(residual) <= tolerance_ * energyScale_ + kRoundOff * initialScale_) return;

  // The body that carries the most kinetic energy is where the energy went.
  const Bodies& B = sim.bodies();
  std::size_t worst = 0;
  double worstEnergy = -1.0;
  for (std::size_t b = 0; b < B.size(); ++b) {
    if (B.fixed[b]) continue;
    const double k = 0.5 * B.mass[b] * B.velocity[b].squaredNorm();
    if (k > worstEnergy) worstEnergy = k, worst = b;
  }
  // Contacts dropped behind a one-sided sheet take their elastic energy with them: that is the cause.
  for (const MeshWall& w : sim.meshWalls().walls())
    if (residual < 0 && w.oneSided && w.lostThroughSheet > 0)
      throw common::InstabilityError(
          {"contacts lost through a one-sided sheet", fmt::format("wall {}", w.name), sim.time(),
           fmt::format("sphere centres went {:.3g} radii behind the sheet, past its `depth` {:.3g}; {} sphere-steps "
                       "lost their contact, and the energy balance is off by {:.4g} J, {:.3g} of the run's energy "
                       "scale (allowed {:.3g})",
                       w.maxDepthRadii, w.depthRadii, w.lostThroughSheet, residual, std::abs(residual) / energyScale_,
                       tolerance_),
           fmt::format("raise `depth` of wall {} above {:.2g} radii, or stiffen the contact (a larger young_modulus)",
                       w.name, std::ceil(2 * w.maxDepthRadii) / 2 + 0.5)});
  // Centres behind a one-sided sheet: the overlap exceeds the radius, outside Hertz theory's range, and the
  // contact's normal jumps as the centre passes under edges and vertices; the ledger does not close. A
  // stiffer material keeps the overlap within the radius (Hertz overlap ∝ E^(-2/5) at a given force). The
  // ledger opens while the body is still sinking, so the overlap reached so far understates the final
  // one: the fix adds a factor 10 (the 1,800 kg stability case went on from 1.1 to 3.8 radii).
  for (const MeshWall& w : sim.meshWalls().walls())
    if (w.oneSided && w.maxDepthRadii > 0.0) {
      const Material& m = sim.interactions().materials()[sim.spheres().material[B.firstSphere[worst]]];
      const double stiffer = 10.0 * m.youngModulus * std::pow(w.maxDepthRadii + 1.0, 2.5);
      const std::string value = fmt::format("{:.2g}", stiffer);
      throw common::InstabilityError(
          {"deep contact behind a one-sided sheet", fmt::format("wall {}", w.name), sim.time(),
           fmt::format("sphere centres went {:.3g} radii behind the sheet (overlaps of {:.3g} radii, outside Hertz "
                       "theory), and the energy balance is off by {:.4g} J, {:.3g} of the run's energy scale (allowed "
                       "{:.3g})",
                       w.maxDepthRadii, w.maxDepthRadii + 1.0, residual, std::abs(residual) / energyScale_, tolerance_),
           fmt::format("a stiffer contact: materials.{}.young_modulus = {} Pa (10 × (overlap / radius)^(5/2) × {:.3g} "
                       "Pa: the overlap then stays within one radius while the body still sinks), or larger spheres",
                       m.name, value, m.youngModulus),
           {fmt::format("materials.{}.young_modulus={}", m.name, value)}});
    }
  const Simulation::Settings& set = sim.settings();
  const double critical = criticalTimeStep(sim), safe = recommendedTimeStep(sim);
  // A smaller step is the fix only if this one is above the safe step; below it, the energy came from
  // outside the contact physics.
  const bool driven = std::any_of(sim.meshWalls().walls().begin(), sim.meshWalls().walls().end(),
                                  [](const MeshWall& w) { return w.motion == MeshWall::Motion::kExternal; });
  const bool tooLarge = set.dt > safe;
  const std::string dtFix = common::wholeStepValue(set.endTime, safe);
  const std::string networkClause =
      std::isfinite(contactStable_)
          ? fmt::format(", and dt_safety × the stable step of the contact network seen, {:.4g} s", contactStable_)
          : std::string();
  const std::string fix =
      tooLarge
          ? fmt::format("dt = {} s (at most the smallest of dt_safety {} × critical {:.4g} s and the elastic contact "
                        "duration at the fastest approach seen, {:.4g} m/s, over steps_per_contact {}{}; end_time in "
                        "whole steps)",
                        dtFix, set.dtSafety, critical, approachSpeed_, set.stepsPerContact,
                        networkClause)
      : driven ? fmt::format("not the time step (dt = {:.3g} s is below the safe {:.3g} s): the energy came through the wall "
                             "driven from outside — a weak coupling's lag or windows that did not converge (an implicit "
                             "scheme, a smaller coupling.time_window or a tighter tolerance)",
                             set.dt, safe)
               : fmt::format("not the time step (dt = {:.3g} s is below the safe {:.3g} s): check the prescribed wall "
                             "motions and forces",
                             set.dt, safe);
  // The ledger's kinetic energy is the leapfrog shadow form ½ m v(t−dt/2)·v(t+dt/2), which turns negative
  // when a step reverses a body at a blown-up speed: a body with more kinetic energy than the whole run
  // ever had is growth, whatever the residual's sign.
  const bool growth = residual > 0 || worstEnergy > energyScale_;
  const double worstSpeed = B.size() > 0 ? B.velocity[worst].norm() : 0.0;  // a rank's share may be empty
  throw common::InstabilityError(
      {growth ? "energy growth" : "energy loss", fmt::format("body {}", bodyId_(worst)), sim.time(),
       fmt::format("the energy balance is off by {:.4g} J, {:.3g} of the run's energy scale {:.4g} J (allowed {:.3g}, "
                   "key energy_tolerance); body {} moves at {:.4g} m/s with {:.4g} J; dt = {:.4g} s is {:.3g} × the "
                   "critical step {:.4g} s",
                   residual, std::abs(residual) / std::max(energyScale_, 1e-300), energyScale_, tolerance_, bodyId_(worst),
                   worstSpeed, worstEnergy, set.dt, set.dt / critical, critical),
       fix, tooLarge ? std::vector<std::string>{"dt=" + dtFix} : std::vector<std::string>{}});
}

}  // namespace dem
