#pragma once
// What a component of dem::Simulation reads from the simulation in one call: the model (settings, laws,
// bodies, spheres), the physics the scene switched on, and the per-sphere sums that contacts add their
// forces and torques to. Simulation builds one per call; no component keeps it.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "dem/model.hpp"

namespace dem {

struct StepContext {
  const SimulationSettings& settings;
  const std::vector<std::unique_ptr<ContactLaw>>& laws;
  const std::vector<int>& lawOf;  // materials × materials → index in laws, −1: none
  std::size_t materials;
  const Bodies& bodies;
  const Spheres& spheres;
  const Vec3* centres;  // the centres a step reads: the bodies' for lone spheres, else spheres.position
  Vec3* force;          // per sphere, what contacts add to: for lone spheres the bodies' own sums
  Vec3* torque;
  bool loneSpheres;  // every body one sphere at its centre: sphere i is body i
  bool rotation;     // torques are summed and bodies turn
  bool rolling;      // some law has rolling resistance

  /// I = 2/5 m R² of sphere s with its body's mass, which caps its rolling resistance [kg m²].
  double rollingInertia(std::uint32_t s) const {
    const double r = spheres.radius[s];
    return 0.4 * bodies.mass[spheres.body[s]] * r * r;
  }
};

}  // namespace dem
