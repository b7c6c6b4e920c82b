#pragma once
// The time integration of dem::Simulation: leapfrog over the rigid bodies (velocities at half steps,
// positions at whole steps; dem/model.hpp) and the clock it keeps. The scene gives v(0), so the
// first step kicks by half a step; the step count is the integrator's state for that reason.
//
// Call order: prepare() once the bodies are built (Simulation::initialize()), then advance() once per
// step after the forces. Not thread safe; advance() uses OpenMP inside. Units SI.
#include <array>
#include <cstdint>
#include <vector>

#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "dem/model.hpp"

namespace dem {

class Integrator {
 public:
  /// The energy terms of one step over the free bodies, each summed in a fixed order [J]: the shadow
  /// kinetic energy ½ m v₋·v₊ (+ ½ ω₋·L₊), the potential −Σ m g·x, Cundall's dissipation, the work of the
  /// external forces, and at the first step the shadow form's shift from ½ m v(0)².
  struct StepEnergy {
    double kinetic = 0.0, potential = 0.0, cundall = 0.0, external = 0.0, shift = 0.0;
  };

  /// Picks the loops the bodies allow. `loneSpheres`: every body is one sphere at its centre with
  /// isotropic inertia (Simulation::physics()).
  void prepare(const Bodies& bodies, bool loneSpheres);
  /// Moves the bodies by one step of settings.dt under their last forces, gravity and the external forces
  /// (`externalForces`: some is non-zero; else they are not read), with Cundall's local damping if set,
  /// and counts the step. `rotation` false: orientations and angular momenta stay.
  StepEnergy advance(Bodies& bodies, const Spheres& spheres, const SimulationSettings& settings, bool rotation,
                    bool externalForces);

  std::int64_t steps() const { return steps_; }
  double time() const { return time_; }  ///< steps × dt [s]
  void archive(common::StateArchive& a) { a.io("time", time_), a.io("steps", steps_); }
  std::size_t heapBytes() const { return common::heapBytes(prepared_.loneInertia); }

 private:
  template <bool kRotation, bool kCundall>
  void lone(Bodies& bodies, const SimulationSettings& settings, std::array<double, 5>& sums);
  template <bool kRotation>
  void loneVector(Bodies& bodies, const SimulationSettings& settings, bool externalForces,
                  std::array<double, 5>& sums);

  std::int64_t steps_ = 0;
  double time_ = 0.0;
  struct Prepared {
    bool loneSpheres = false;
    bool anyFixed = false;            // some body is fixed
    std::vector<double> loneInertia;  // lone spheres: each body's moment of inertia (isotropic)
  };
  // Derived from the bodies by prepare(): copied with the integrator, so a copy works alone; not
  // archived, a restart builds the scene again.
  Prepared prepared_;
};

}  // namespace dem
