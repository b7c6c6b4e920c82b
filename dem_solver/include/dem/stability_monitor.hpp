#pragma once
// Watches a running Simulation for a run gone wrong and stops it with a diagnosis instead
// of letting it report success on garbage: the energy ledger's residual (energy that appeared or vanished
// without a cause: dashpots, friction, walls and external forces are booked) beyond a set fraction of the
// run's energy scale. Non-finite states are caught by Simulation::step itself.
//
// Call order: construct after Simulation::initialize() → check() after every step() → the getters, for
// the summary. check() costs O(1) (the ledger is summed by the step); observe() costs O(bodies): call it
// at output steps, not every step.

#include <cstdint>
#include <algorithm>
#include <functional>
#include <limits>

#include "dem/simulation.hpp"
#include "dem/time_steps.hpp"

namespace dem {

class StabilityMonitor {
 public:
  /// `energyTolerance`: the largest |residual| / energy scale accepted [-].
  StabilityMonitor(const Simulation& sim, double energyTolerance)
      : StabilityMonitor(sim.initialEnergy(), sim.energy().potential, approachSpeedEstimate(sim), energyTolerance) {}
  /// The same from the numbers it takes from the simulation: the initial energy and potential energy [J]
  /// and the fastest approach estimated before the run [m/s] (a run on several ranks: the whole run's).
  StabilityMonitor(double initialEnergy, double potentialEnergy, double approachSpeed, double energyTolerance);

  /// Throws common::InstabilityError (exit 3) when the residual exceeds the tolerance: the body with
  /// the most kinetic energy, the energies, and a dt computed to resolve the fastest approach seen.
  void check(const Simulation& sim) { check(sim, sim.energy(), sim.initialEnergy()); }
  /// The same with the ledger `e` and initial energy of a run on several ranks (all ranks' sums), the
  /// body named in the diagnosis by `bodyId` (its number in the whole scene).
  void check(const Simulation& sim, const EnergyLedger& e, double initialEnergy);
  void nameBodies(std::function<std::uint64_t(std::size_t)> bodyId) { bodyId_ = std::move(bodyId); }
  /// Records the fastest approach speed now (the two fastest bodies head-on) and the stable step of the
  /// contact network now (dem::contactStableStep, dem/contact_queries.hpp), for the diagnosis and the summary; warns once
  /// when dt exceeds the latter (compressed contacts stiffen).
  void observe(const Simulation& sim);

  /// max |residual| / max energy scale over the run [-]
  /// A coupled system's energy [J], which the residual of this side's ledger is judged against when this
  /// side's own energy is smaller: the particles of a bridging domain before the pulse reaches them hold
  /// only the explicit scheme's precursor (1e-60 J), whose ledger closes to no useful fraction.
  void setScaleFloor(double energy) { energyScale_ = std::max(energyScale_, energy); }
  double energyError() const { return energyScale_ > 0 ? maxResidual_ / energyScale_ : 0.0; }
  /// The fastest approach observed at the sampled steps, or the estimate before the run if larger [m/s]
  double approachSpeed() const { return approachSpeed_; }
  /// The smallest stable step of the contact network seen at the sampled steps [s] (inf: no contact)
  double contactStableStep() const { return contactStable_; }
  /// The step to recommend: min(the safe step at the fastest approach, dt_safety × the contact network's) [s]
  double recommendedTimeStep(const Simulation& sim) const;

 private:
  double tolerance_;
  double initialScale_;  // |E(0)| and the potential energy: round-off in the ledger scales with them
  double maxResidual_ = 0.0, energyScale_ = 0.0;
  double approachSpeed_ = 0.0;
  double contactStable_ = std::numeric_limits<double>::infinity();
  bool warned_ = false;
  std::function<std::uint64_t(std::size_t)> bodyId_ = [](std::size_t b) { return b; };

 public:
  void archive(common::StateArchive& a) {
    a.io("initial_scale", initialScale_), a.io("max_residual", maxResidual_), a.io("energy_scale", energyScale_);
    a.io("approach_speed", approachSpeed_), a.io("contact_stable", contactStable_), a.io("warned", warned_);
  }
};

}  // namespace dem
