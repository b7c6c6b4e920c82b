// Simulation's state as data (dem/simulation.hpp): the checkpoint a coupling iteration restores, the
// archive a restart reads, what it must match (shape), what it holds (memoryUse), and a run on several
// ranks replacing its bodies with the share a cut gives it.
#include "dem/simulation.hpp"

#include <algorithm>
#include <optional>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "contact_set.hpp"
#include "integrator.hpp"
#include "mesh_walls.hpp"
#include "neighbour_list.hpp"
#include "plane_walls.hpp"
#include "sphere_pairs.hpp"

namespace dem {

// What a coupling iteration needs to start a window again: the components' values and the simulation's own
// state. Not the spheres (only their centres change, and those follow from the bodies), the per-step force
// sums nor the components' work space (detail::Transient): a 22,000-sphere block is restored thousands of
// times per run.
struct Simulation::Checkpoint {
  Bodies bodies;
  // None in a Keep::kMotion checkpoint: a move leaves the contacts as the forces left them.
  std::optional<BondSet> bonds;
  std::optional<NeighbourList> neighbours;
  std::optional<SpherePairs> pairs;
  PlaneWalls planes;
  MeshWalls meshes;
  Integrator integrator;
  EnergyLedger energy;
  double initialEnergy;  // moved by the first step's shadow-energy shift
  bool rotation;         // formBonds() may switch it on
  void archive(common::StateArchive& a) {  // of a Keep::kAll checkpoint (a restart holds everything)
    a.io("bodies", bodies), a.io("bonds", bonds.value()), a.io("neighbour_list", neighbours.value());
    a.io("sphere_pairs", pairs.value());
    a.io("plane_walls", planes), a.io("mesh_walls", meshes), a.io("integrator", integrator), a.io("energy", energy);
    a.io("initial_energy", initialEnergy), a.io("rotation", rotation);
  }
};

void Simulation::archive(common::StateArchive& a) {
  a.shape(shape());
  archiveState(a);
}

void Simulation::archiveState(common::StateArchive& a) {
  auto scope = a.scope("simulation");
  if (!a.reading()) {
    Checkpoint c = *saveCheckpoint();
    c.archive(a);
    return;
  }
  // Read over the live state: what is built from the scene and not archived (the neighbour list's and the
  // integrator's prepared parts: each body's reach, the lone-sphere path) stays the scene's.
  Checkpoint c = *saveCheckpoint();
  c.archive(a);
  if (c.bodies.size() != bodies_.size() || c.meshes.walls().size() != meshWalls_->walls().size() ||
      c.planes.walls().size() != planeWalls_->walls().size())
    throw common::ConfigError(fmt::format("{}: the checkpoint holds {} bodies, {} plane and {} mesh walls; this scene has "
                                          "{}, {} and {}: not a checkpoint of this scene",
                                          a.path().string(), c.bodies.size(), c.planes.walls().size(),
                                          c.meshes.walls().size(), bodies_.size(), planeWalls_->walls().size(),
                                          meshWalls_->walls().size()));
  restoreCheckpoint(c);
  bonds_.relink([&](std::uint32_t s, std::uint32_t t) { return bondingLaw(s, t); });
}

std::shared_ptr<const Simulation::Checkpoint> Simulation::saveCheckpoint(Keep keep) const {
  if (keep == Keep::kMotion)
    return std::make_shared<const Checkpoint>(Checkpoint{bodies_, std::nullopt, std::nullopt, std::nullopt, *planeWalls_,
                                                         *meshWalls_, *integrator_, energy_, initialEnergy_, rotation_});
  return std::make_shared<const Checkpoint>(Checkpoint{bodies_, bonds_, *neighbours_, *pairs_, *planeWalls_,
                                                       *meshWalls_, *integrator_, energy_, initialEnergy_, rotation_});
}

void Simulation::restoreCheckpoint(const Checkpoint& c) {
  bodies_ = c.bodies;
  *planeWalls_ = c.planes;
  *meshWalls_ = c.meshes;
  *integrator_ = c.integrator;
  energy_ = c.energy;
  initialEnergy_ = c.initialEnergy;
  rotation_ = c.rotation;
  positionsStale_ = true;  // the centres are still those of the later state
  if (!c.bonds) return;  // a move's: the contacts and their force sums are still the step's
  bonds_ = *c.bonds;
  *neighbours_ = *c.neighbours;
  *pairs_ = *c.pairs;
  refsStale_ = true;
  // Spheres inactive here must not keep the sums of the later state (lone spheres: their sums are the
  // bodies' forces, restored above).
  // Sized by the spheres, which a run on several ranks restores with the bodies (its cuts replace both).
  sphereForce_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
  sphereTorque_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
}

std::string Simulation::shape() const {
  std::string meshes;
  for (const MeshWall& m : meshWalls_->walls()) meshes += fmt::format("{}{} ({} nodes, {} triangles)", meshes.empty() ? "" : ", ", m.name, m.nodes.size(), m.triangles.size());
  return fmt::format("{} bodies, {} spheres, {} plane walls, mesh walls [{}], {} materials, {} laws", bodies_.size(),
                     spheres_.size(), planeWalls_->walls().size(), meshes, interactions_.materials().size(), interactions_.laws().size());
}

void Simulation::replaceBodies(Bodies bodies, Spheres spheres, std::vector<int> owner, int rank,
                               const HistoryOf& pairHistory, const HistoryOf& planeHistory) {
  COSIM_ASSERT(!settings_.bridging, "Simulation::replaceBodies: a scene with a bridging zone");
  releaseBodies();
  bodies_ = std::move(bodies);
  spheres_ = std::move(spheres);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    double reach = 0.0;
    for (std::uint32_t i = 0; i < bodies_.sphereCount[b]; ++i)
      reach = std::max(reach, spheres_.local[bodies_.firstSphere[b] + i].norm());
    neighbours_->addBody(reach);
  }
  neighbours_->setOwners(std::move(owner), rank);
  if (integrator_->steps() == 0) {
    initialize();
    return;
  }
  neighbours_->prepare(true);
  integrator_->prepare(bodies_, loneSpheres_);
  sphereForce_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
  sphereTorque_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
  updateSpherePositions(true);
  rebuildContacts(true, true, true);
  ContactSet& pairs = pairs_->contacts();
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    pairs.history[k] = pairHistory(pairs.a[k], pairs.b[k]);
    pairs.overlap[k] = pairs.history[k].lastOverlap;  // as SpherePairs::assign sets a kept pair's
  }
  ContactSet& walls = planeWalls_->contacts();
  for (std::size_t k = 0; k < walls.size(); ++k) walls.history[k] = planeHistory(walls.a[k], walls.b[k]);
}

void Simulation::releaseBodies() {
  bodies_ = Bodies{}, spheres_ = Spheres{};
  const std::int64_t rebuilds = neighbours_->rebuilds();  // the run's count goes on
  *neighbours_ = NeighbourList{};
  neighbours_->addRebuilds(rebuilds);
  *pairs_ = SpherePairs{};
  planeWalls_->clearContacts();
  meshWalls_->clearContacts();
  sphereForce_ = {}, sphereTorque_ = {}, bodyRotation_ = {};
  refsStale_ = true;
}

std::vector<std::pair<std::string, std::size_t>> Simulation::memoryUse() const {
  using common::heapBytes;
  return {{"bodies", heapBytes(bodies_, *integrator_, bodyRotation_)},
          {"spheres", heapBytes(spheres_, sphereForce_, sphereTorque_)},
          {"sphere_contacts", heapBytes(*pairs_)},
          {"wall_contacts", heapBytes(*planeWalls_, *meshWalls_)},
          {"neighbour_list", heapBytes(*neighbours_)},
          {"bonds", heapBytes(bonds_)},
          {"other", heapBytes(interactions_, refStart_, refs_)}};
}

}  // namespace dem
