#pragma once
// The strain-controlled fracture test (lattice_solver/README.md "Fracture" and "Loading"): the applied
// strain grows by a fixed increment; at each increment the lattice is brought to equilibrium, rods whose
// strain passes their phase's critical value are removed, and the lattice is re-equilibrated at the same
// applied strain until no rod is over its limit (BrittleEquilibrium, with its removal strategy).
//
// Call order: construct → step() until it returns false. The model and solver are borrowed and must
// outlive the test. Throws common::SimulationError when a solve fails.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "lattice/brittle_equilibrium.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"

namespace common {
class StateArchive;
}

namespace lattice {

struct LoadingSettings {
  double strainIncrement = 5e-6;  ///< |Δε| per increment
  double maxStrain = 1e-3;        ///< |ε| where the test ends
  double direction = 1.0;         ///< +1 tension, −1 compression
  RemovalStrategy removal = RemovalStrategy::kAll;
  int maxRounds = 1000000;        ///< removal rounds per increment before moving on (with a warning)
  double stopFraction = 0.0;      ///< after the peak, end when the stress falls below this × peak (0: never)
};

struct IncrementResult {
  int increment = 0;
  double strain = 0.0;   ///< applied ε (signed)
  double stress = 0.0;   ///< reaction / loaded area [Pa] (signed; positive in tension)
  std::size_t removedNow = 0, removedTotal = 0;
  int rounds = 0;        ///< equilibria solved in this increment (1 + removal rounds)
  long iterations = 0;   ///< solver iterations in this increment
  double seconds = 0.0;  ///< wall time of the increment
};

struct RemovalRecord {
  std::uint32_t rod;
  int increment;
  double appliedStrain;  ///< ε applied when it broke
  double rodStrain;      ///< its own strain then
};

class FractureTest {
 public:
  FractureTest(Model& model, EquilibriumSolver& solver, const LoadingSettings& settings);

  /// One increment; false once the test has ended (before doing anything).
  bool step();
  bool finished() const { return finished_; }

  const std::vector<IncrementResult>& curve() const { return curve_; }
  const std::vector<RemovalRecord>& removals() const { return removals_; }
  /// Per rod: the increment it was removed in, −1 while intact.
  const std::vector<int>& removedAt() const { return removedAt_; }
  /// E = σ/ε of the first equilibrium, before any removal [Pa].
  double youngsModulus() const { return youngsModulus_; }
  /// The applied strain at which the first rod reaches its limit, from the first (linear) solution.
  double firstCriticalStrain() const { return firstCritical_; }
  /// Index in curve() of the largest direction × stress, −1 before the first step.
  int peakIndex() const { return peak_; }
  const Eigen::VectorXd& state() const { return x_; }
  /// Full displacement (6 per node) of the current state.
  std::vector<double> displacement() const;
  double appliedStrain() const { return strain_; }
  long totalIterations() const { return brittle_.iterations(); }
  long solves() const { return brittle_.solves(); }
  double solveSeconds() const { return brittle_.solveSeconds(); }
  /// Wall time in rod removal (K update, fragment search), in solver updates (preconditioner), and in
  /// the strain checks [s].
  double removalSeconds() const { return brittle_.removalSeconds(); }
  double updateSeconds() const { return brittle_.updateSeconds(); }
  double checkSeconds() const { return brittle_.checkSeconds(); }
  /// The test's progress (increment, strain, state, curve, removals, counters) to or from disk; the
  /// model is archived on its own (Model::archive). After reading, call the solver's update().
  void archive(common::StateArchive& a);

 private:
  Model& model_;
  EquilibriumSolver& solver_;
  LoadingSettings settings_;
  BrittleEquilibrium brittle_;
  Eigen::VectorXd x_;
  double strain_ = 0.0;
  int increment_ = 0;
  bool finished_ = false;
  int peak_ = -1;
  double youngsModulus_ = 0.0, firstCritical_ = 0.0;
  std::vector<IncrementResult> curve_;
  std::vector<RemovalRecord> removals_;
  std::vector<int> removedAt_;
};

}  // namespace lattice
