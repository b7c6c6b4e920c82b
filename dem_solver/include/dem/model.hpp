#pragma once
// The DEM model's data, apart from the Simulation that steps it: bodies, spheres, plane walls, the
// energy ledger and the settings. Simulation and each of its components (dem_solver/src: neighbour list,
// sphere pairs, plane walls, mesh walls, integrator) read these; none of them needs Simulation itself.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/bridging_zone.hpp"
#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "dem/contact_law.hpp"

namespace dem {

using Quat = Eigen::Quaterniond;

/// Bodies::fixed: how a body moves. A ghost is another rank's body near this rank's share (a run on
/// several ranks, dem_solver/src/ranked_simulation.hpp): that rank moves it and sends its state each step; here
/// it is read by the sphere pairs, with its real mass in their m* (kFixedGhost: a fixed body's, infinite),
/// and neither moved by its forces, nor in contact with walls, nor booked in the energy ledger.
enum BodyMotion : std::uint8_t { kFree = 0, kFixed = 1, kGhost = 2, kFixedGhost = 3 };
/// Whether a body of this motion counts as infinitely heavy in a contact's m*.
inline bool infiniteMass(std::uint8_t motion) { return motion == kFixed || motion == kFixedGhost; }
/// Whether a body of this motion is another rank's.
inline bool ghost(std::uint8_t motion) { return motion >= kGhost; }

/// Rigid bodies, structure of arrays. Velocities are at the half step t − dt/2 between steps, and at
/// t = 0 before the first step (whose kick is half a step).
struct Bodies {
  std::vector<Vec3> position;         ///< centre of mass [m]
  std::vector<Vec3> velocity;         ///< [m/s]
  std::vector<Vec3> angularVelocity;  ///< world frame [rad/s], derived from the angular momentum
  std::vector<Vec3> angularMomentum;  ///< world frame [kg m²/s], the integrated rotational state
  std::vector<Quat> orientation;      ///< body (principal axes) → world
  std::vector<double> mass;           ///< [kg]
  std::vector<Vec3> inertia;          ///< principal moments of inertia [kg m²]
  std::vector<Vec3> force, torque;    ///< last step's total contact force and torque about the centre of mass
  std::vector<Vec3> externalForce;    ///< prescribed force at the centre of mass, besides gravity [N]
  std::vector<std::uint8_t> fixed;    ///< BodyMotion; kFixed: moves only with its prescribed velocity, infinite mass
  std::vector<std::uint32_t> firstSphere, sphereCount;
  std::size_t size() const { return position.size(); }
  void archive(common::StateArchive& a) {
    a.io("position", position), a.io("velocity", velocity), a.io("angular_velocity", angularVelocity);
    a.io("angular_momentum", angularMomentum), a.io("orientation", orientation), a.io("mass", mass);
    a.io("inertia", inertia), a.io("force", force), a.io("torque", torque), a.io("external_force", externalForce);
    a.io("fixed", fixed), a.io("first_sphere", firstSphere), a.io("sphere_count", sphereCount);
  }
  std::size_t heapBytes() const {
    return common::heapBytes(position, velocity, angularVelocity, angularMomentum, orientation, mass, inertia, force,
                             torque, externalForce, fixed, firstSphere, sphereCount);
  }
  /// Frees what the scene's growth left unused (the arrays grow by doubling as bodies are added).
  void shrinkToFit() {
    for (auto* v : {&position, &velocity, &angularVelocity, &angularMomentum, &inertia, &force, &torque, &externalForce})
      v->shrink_to_fit();
    orientation.shrink_to_fit(), mass.shrink_to_fit(), fixed.shrink_to_fit(), firstSphere.shrink_to_fit();
    sphereCount.shrink_to_fit();
  }
};

/// Spheres, structure of arrays.
struct Spheres {
  std::vector<Vec3> local;     ///< centre in the body frame [m]
  std::vector<Vec3> position;  ///< centre in the world frame [m] (see Simulation::spheres())
  std::vector<double> radius;  ///< [m]
  std::vector<std::uint32_t> material, body;
  std::size_t size() const { return radius.size(); }
  std::size_t heapBytes() const { return common::heapBytes(local, position, radius, material, body); }
  void archive(common::StateArchive& a) {
    a.io("local", local), a.io("position", position), a.io("radius", radius), a.io("material", material);
    a.io("body", body);
  }
  void shrinkToFit() {
    local.shrink_to_fit(), position.shrink_to_fit(), radius.shrink_to_fit(), material.shrink_to_fit();
    body.shrink_to_fit();
  }
};

/// An infinite plane; spheres live on the side its normal points to. It may translate.
struct PlaneWall {
  std::string name;
  Vec3 point = Vec3::Zero();     ///< a point of the plane [m]
  Vec3 normal = Vec3::UnitZ();   ///< unit normal [-]
  Vec3 velocity = Vec3::Zero();  ///< prescribed translation velocity [m/s]
  std::uint32_t material = 0;
  void archive(common::StateArchive& a) {
    a.io("name", name), a.io("point", point), a.io("normal", normal), a.io("velocity", velocity);
    a.io("material", material);
  }
};

/// The energy ledger (it closes within 1 %); dissipations and work are accumulated.
struct EnergyLedger {
  double kinetic = 0.0;    ///< translation + rotation, leapfrog shadow form ½ m v₋·v₊ [J]
  double potential = 0.0;  ///< gravity, −Σ m g·x [J]
  double elastic = 0.0;    ///< stored in contact springs [J]
  double damping = 0.0;    ///< dissipated by contact dashpots [J]
  double friction = 0.0;   ///< dissipated by Coulomb sliding [J]
  double cundall = 0.0;    ///< dissipated by local (non-viscous) damping [J]
  double bondFracture = 0.0;  ///< released by bonds as they broke (dem/bonds.hpp) [J]
  double wallWork = 0.0;   ///< work done on the particles by moving walls [J]
  double externalWork = 0.0;  ///< work of prescribed external forces [J]
  /// total − work − the initial total: zero for a perfect balance [J]
  double residual(double initial) const { return total() - wallWork - externalWork - initial; }
  double total() const { return kinetic + potential + elastic + damping + friction + cundall + bondFracture; }
  /// Term by term: the ledgers of parts of a run (ranks' shares) summed to theirs together.
  EnergyLedger& operator+=(const EnergyLedger& o) {
    kinetic += o.kinetic, potential += o.potential, elastic += o.elastic, damping += o.damping;
    friction += o.friction, cundall += o.cundall, bondFracture += o.bondFracture, wallWork += o.wallWork;
    externalWork += o.externalWork;
    return *this;
  }
};

/// What a simulation is run with (Simulation::Settings).
struct SimulationSettings {
  double dt = 0.0;                       ///< [s]
  Vec3 gravity = Vec3::Zero();           ///< [m/s²]
  double skin = 0.0;                     ///< Verlet skin of sphere–sphere and sphere–plane pairs [m]; 0: 0.2 × the smallest radius
  double meshSkin = 0.0;                 ///< Verlet skin of sphere–mesh candidates [m]; 0: automatic (README)
  /// A run on several ranks cuts its slabs again once a sphere moved half of this [m]; 0: 4 × skin
  double rankMargin = 0.0;
  double localDamping = 0.0;             ///< Cundall λ [-]
  double dtSafety = 0.5;                 ///< largest accepted dt / criticalTimeStep() [-]
  int stepsPerContact = 20;              ///< fewest steps a contact at the fastest approach may take [-]
  /// The scene's end_time [s]: a fix's dt reaches it in whole steps (0: any dt; a coupled run fills each
  /// window with whole substeps of its own).
  double endTime = 0.0;
  bool bondAtStart = true;               ///< initialize() forms the laws' bonds; false: formBonds() does, later
  /// A bridging domain's zone (dem/bridging.cpp), read at initialize(): there the particles carry the share
  /// β of their energy — each body's mass and inertia scaled by β at its centre, each bond's stiffnesses,
  /// dashpots and strengths by β at its midpoint (raised to the zone's min_weight).
  std::optional<common::BridgingZone> bridging;
};

}  // namespace dem
