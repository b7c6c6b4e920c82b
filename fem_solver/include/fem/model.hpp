#pragma once
// The FEM model: nodes, element blocks, boundary conditions, loads and state, with the static
// (Newton–Raphson) and explicit (central difference) solvers working on it.
//
// Degrees of freedom: 3 translations per node, dof = 3 n + k. Displacements u are from the reference
// coordinates X. Loads are dead loads (fixed direction and magnitude), scaled by the load factor in
// statics. Coupled forces (set from outside, e.g. DEM contact forces) add to them.
// Call order: fill mesh data, blocks, fixed dofs and loads → finalize() → solveStatic() and/or
// initializeExplicit() + stepExplicit() … Not thread safe; OpenMP inside.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/state_archive.hpp"
#include "fem/element.hpp"

namespace fem {

struct StaticSettings {
  enum class Method { kNewton, kDynamicRelaxation };
  Method method = Method::kNewton;
  /// Newton failing at the true prestress falls back to dynamic relaxation from its last state.
  bool fallback = true;
  int relaxationIterations = 200000;
  int loadSteps = 1;
  /// The load factor the load steps end at (1: full load). Coupled static runs with `static.ramp_time`
  /// set it per window.
  double loadFactor = 1.0;
  int maxIterations = 50;
  /// ‖residual‖ (free dofs) / max(‖load‖, ‖forces at the moving supports when their motion is applied‖)
  double tolerance = 1e-8;
  /// Prestress continuation for slack membranes: solve first with σ = this artificial prestress [Pa]
  /// (0: off), then lower it tenfold per stage down to the true prestress, each from the last solution.
  double continuationStart = 0.0;
};

struct StaticReport {
  int stages = 0, loadSteps = 0, iterations = 0;
  int relaxationIterations = 0;  ///< dynamic relaxation, when used
  double residual = 0.0;  ///< final relative residual
};

struct EnergyState {
  double kinetic = 0.0, strain = 0.0, externalWork = 0.0, damping = 0.0;
  /// The part of externalWork done by the coupled forces (what a coupled energy balance needs apart).
  double coupledWork = 0.0;
  /// The shadow form's kinetic energy at t = 0, ½ m v(−dt/2)·v(dt/2) with v(−dt/2) = v(0) − a(0) dt/2, minus
  /// ½ m v(0)²: the energy balance starts from the initial energy plus this [J].
  double initialShift = 0.0;
};

class Model {
 public:
  std::vector<Vec3> reference;                   ///< X per node [m]
  std::vector<std::unique_ptr<Element>> blocks;  ///< element blocks
  std::vector<std::uint8_t> fixed;               ///< per dof: 1 = prescribed
  std::vector<double> prescribed;                ///< per dof: prescribed displacement at full load [m]
  std::vector<double> deadLoad;                  ///< per dof: gravity + nodal + pressure at full load [N]
  std::vector<double> coupledForce;              ///< per dof: set from outside, not scaled [N]
  Vec3 gravity = Vec3::Zero();                   ///< applied as lumped mass × g in deadLoad by finalize()
  double alpha = 0.0;                            ///< mass-proportional damping [1/s]
  double beta = 0.0;                             ///< stiffness-proportional damping [s]
  /// Per dof: the velocity explicit dynamics starts with (empty: at rest) [m/s].
  std::vector<double> initialVelocity;

  std::size_t nodes() const { return reference.size(); }
  std::size_t dofs() const { return 3 * reference.size(); }

  /// Sizes the state, computes lumped masses, adds gravity to the dead load, builds the node → element
  /// slot index used to sum element forces. Call once, after the blocks and loads are set.
  void finalize();

  const std::vector<double>& displacement() const { return u_; }
  const std::vector<double>& velocity() const { return v_; }
  const std::vector<double>& nodeMass() const { return mass_; }
  /// Current coordinates X + u, 3 per node.
  std::vector<double> positions() const;
  /// Internal forces at the current displacement and the strain energy.
  const std::vector<double>& internalForce() const {
    ensureForces();
    return fint_;
  }
  double strainEnergy() const {
    ensureForces();
    return strainEnergy_;
  }

  /// Support force on node n: f_int − load − coupled at its fixed dofs (0 for free components).
  Vec3 supportForce(std::uint32_t node) const;
  /// Explicit runs: the force the supports applied at the fixed dofs during the last step (at its start
  /// time t_n), including the node's inertia m a_n when the prescribed displacement moves; 0 at free dofs.
  const std::vector<double>& dynamicSupportForce() const { return reaction_; }

  /// Newton–Raphson with load stepping and, if asked, prestress continuation. Throws
  /// common::SimulationError (exit 3) naming the dof of a singular stiffness or the stage that did not
  /// converge.
  StaticReport solveStatic(const StaticSettings& settings);

  /// Dynamic relaxation (kinetic damping, Gershgorin fictitious masses) at the full load from the current
  /// state until the relative residual is below `tolerance`. Returns the iterations; throws on failure.
  int relax(const StaticSettings& settings);

  /// Replaces the displacement (e.g. a saved static state); size dofs().
  void setDisplacement(const std::vector<double>& u);

  /// Explicit state for coupling checkpoints (save at a window start, restore to repeat it).
  struct State {
    std::vector<double> u, v;
    double time = 0.0;
    std::int64_t steps = 0;
    EnergyState energy;
    double dt = 0.0, lastDt = 0.0;
    double timeBase = 0.0;  // where time() counts steps from: a restart continues the same sums
    std::int64_t stepsBase = 0;
    /// The internal forces and strain energy at u, kept in memory so that a repeated window restores them
    /// instead of computing them again (an on-disk checkpoint leaves them out: they follow from u).
    std::vector<double> fint;
    double strainEnergy = 0.0;
    void archive(common::StateArchive& a) {
      a.io("u", u), a.io("v", v), a.io("time", time), a.io("steps", steps), a.io("energy", energy);
      a.io("dt", dt), a.io("last_dt", lastDt), a.io("time_base", timeBase), a.io("steps_base", stepsBase);
      if (a.reading()) fint.clear();  // computed again from the u just read
    }
  };
  State saveState() const {
    ensureForces();
    return {u_, v_, time_, steps_, energy_, dt_, lastDt_, timeBase_, stepsBase_, fint_, strainEnergy_};
  }
  void restoreState(const State& s);
  /// What a checkpoint must match to be this model's: its nodes and element blocks, in words.
  std::string shape() const;
  /// Replaces the time step from the next step on (subcycling a coupling window, or following the
  /// stable step as the structure deforms). Central differences with a variable step: the next kick is
  /// v(t+dt/2) = v(t−dt_old/2) + (dt_old + dt)/2 a(t), so the scheme stays second order.
  void setTimeStep(double dt);

  /// The largest stable explicit step over all elements [s], in the reference configuration.
  double criticalTimeStep() const;
  /// The model in its current configuration: the stable step now, and the most compressed element.
  struct Current {
    double criticalTimeStep = 0.0;  ///< [s]
    std::size_t block = 0, element = 0;
    double jacobian = 1.0;  ///< tet4: det F; membrane: area ratio; truss: stretch (Element::Current)
  };
  Current current() const;
  /// Starts central differences from the current displacement and initialVelocity (at rest if empty) at
  /// t = 0 (the first kick is half a step).
  void initializeExplicit(double dt);
  /// One step: a = M⁻¹(load + coupled − f_int − damping), v += dt a, u += dt v. Fixed dofs move to
  /// `prescribed` within the step (a coupling interface or a support motion set between steps).
  void stepExplicit();
  double time() const { return time_; }
  std::int64_t steps() const { return steps_; }
  double dt() const { return dt_; }
  const EnergyState& energy() const { return energy_; }

 private:
  // One static solve's state and its Newton iteration at a prestress level and load factor (model.cpp).
  class StaticSolve;
  void computeInternalForces(const std::vector<double>& u, std::vector<double>& f, double* energy) const;

  // The internal forces at u_ are computed when first needed after a step, not at its end: a step whose
  // state is restored (a repeated coupling window) never pays for the forces at its end.
  void ensureForces() const {
    if (!forcesStale_) return;
    computeInternalForces(u_, fint_, &strainEnergy_);
    forcesStale_ = false;
  }
  mutable bool forcesStale_ = false;
  mutable std::vector<double> fint_;
  std::vector<double> u_, v_, mass_, reaction_;
  std::vector<double> shifted_, fshift_;                // β K v scratch (no allocation per step)
  std::vector<std::vector<double>> slots_;              // per block: per-element force slots
  std::vector<std::uint32_t> gatherStart_;              // node → its (block, slot) entries
  std::vector<std::pair<std::uint32_t, std::uint32_t>> gather_;
  mutable double strainEnergy_ = 0.0;
  double dt_ = 0.0, time_ = 0.0;
  double lastDt_ = 0.0;                      // the step that ended at time_ (the last kick's other half)
  double timeBase_ = 0.0;                    // time_ = timeBase_ + (steps_ − stepsBase_) dt_: no drift
  std::int64_t stepsBase_ = 0;
  std::int64_t steps_ = 0;
  EnergyState energy_;
};

}  // namespace fem
