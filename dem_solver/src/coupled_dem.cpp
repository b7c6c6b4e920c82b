#include "dem/coupled_dem.hpp"

#include <algorithm>
#include <stdexcept>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "dem/time_steps.hpp"

namespace dem {

std::vector<std::uint32_t> CoupledDem::recordedBodies(const Scene& scene) {
  std::vector<std::uint32_t> bodies = scene.output.track;
  if (std::find(bodies.begin(), bodies.end(), scene.probe.body) == bodies.end()) bodies.push_back(scene.probe.body);
  return bodies;
}

namespace {
std::uint32_t interfaceWall(const Scene& scene, std::uint32_t none) {
  if (scene.interfaceWall.empty() && scene.sim->settings().bridging) return none;
  if (scene.interfaceWall.empty())
    throw common::ConfigError("a coupled dem_solver run needs `interface: {wall: NAME}` naming a mesh wall with motion: "
                              "external, or `bridging:`.");
  std::uint32_t i = 0;
  while (scene.sim->meshWalls().walls()[i].name != scene.interfaceWall) ++i;
  return i;
}
}  // namespace

CoupledDem::CoupledDem(Scene& scene, common::H5Writer& h5)
    : scene_(scene),
      sim_(*scene.sim),
      h5_(h5),
      wall_(interfaceWall(scene, kNoWall)),
      reference_(wall_ == kNoWall ? MeshWall{} : sim_.meshWalls().walls()[wall_]),
      dt_(sim_.settings().dt),
      critical_(criticalTimeStep(sim_)),  // a loop over every sphere: once, not per iteration
      monitor_(sim_, scene.energyTolerance),
      series_(h5, sim_, recordedBodies(scene)),
      nextSnapshot_(scene.output.interval) {
  addMeshWalls(h5_, sim_);
  const std::size_t nn = reference_.nodes.size();
  positions_.resize(nn), velocity_.resize(nn);
  if (const auto& zone = sim_.settings().bridging)
    for (std::uint32_t b = 0; b < sim_.bodies().size(); ++b)
      if (zone->overlaps(sim_.bodies().position[b])) {
        bridge_.push_back(b);
        weights_.push_back(zone->weight(sim_.bodies().position[b]));
        const Vec3& x = sim_.bodies().position[b];
        centres_.insert(centres_.end(), {x.x(), x.y(), x.z()});
      }
  // The overlap's spheres rotate (bonds or friction turn them): the coupler may constrain their spin.
  const auto physics = sim_.physics();
  spins_ = sim_.settings().bridging &&
           std::any_of(physics.begin(), physics.end(), [](const auto& p) { return p.first == "rotation" && p.second; });
}

void CoupledDem::declare(cosim::InterfaceDeclaration& io) {
  if (sim_.settings().bridging) cosim::declareBridge(io, centres_, 0, {}, spins_);
  if (wall_ != kNoWall) declareInterface(io, reference_);
}

void CoupledDem::declareInterface(cosim::InterfaceDeclaration& io, const MeshWall& wall) {
  std::vector<double> coords;
  std::vector<std::uint32_t> triangles;
  for (const auto& x : wall.nodes) coords.insert(coords.end(), {x.x(), x.y(), x.z()});
  for (const auto& t : wall.triangles) triangles.insert(triangles.end(), {t[0], t[1], t[2]});
  io.addMesh("interface", coords, triangles);
  io.addRead("interface", "displacement", 3, cosim::Interpolation::kLinear);
  io.addWrite("interface", "force", 3, cosim::Reduction::kMean);
}

// A bridging domain's second iteration repeats the step with the same forces (they follow from the
// positions at the window's start, not from the multipliers): the state is kept after the trial step's
// forces, and the repeat restores it and only moves.
bool CoupledDem::reusesForces() const { return sim_.settings().bridging && wall_ == kNoWall; }

void CoupledDem::save() {
  if (reusesForces()) saveAfterForces_ = true;
  else checkpoint_ = sim_.saveCheckpoint();
}

void CoupledDem::restore() {
  if (reusesForces()) restoreAfterForces_ = true;
  else if (checkpoint_) sim_.restoreCheckpoint(*checkpoint_);
}

void CoupledDem::commit() {
  const double t = pending_.time;
  if (t < 0) return;
  if (common::snapshotDue(t, scene_.output.interval, nextSnapshot_)) writeParticleSnapshot(h5_, sim_, t);
  ++committed_;
  monitor_.check(sim_);
  if (committed_ % 16 == 0) monitor_.observe(sim_);
  series_.write(pending_);
  if (committed_ % 64 == 0) h5_.flush();
  pending_.time = -1.0;
}

void CoupledDem::beginWindow(const cosim::Window&, const cosim::Substeps& sub, cosim::WindowIo& io) {
  sim_.settings().dt = sub.dt;
  if (sim_.settings().bridging) {
    monitor_.setScaleFloor(io.read("bridge_energy", "scale")[0]);
    applyMultipliers(io);
  }
  if (wall_ == kNoWall) return;
  const auto v = io.rate("interface", "displacement");
  for (std::size_t i = 0; i < velocity_.size(); ++i) velocity_[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
}

// The wall's nodes at the substep's start, moving at the window's constant velocity: a velocity-Verlet
// step evaluates the contact forces at the start of the step.
void CoupledDem::applyMultipliers(cosim::WindowIo& io) {
  const auto f = io.read("bridge", "force");
  for (std::size_t i = 0; i < bridge_.size(); ++i) sim_.setExternalForce(bridge_[i], Vec3(f[3 * i], f[3 * i + 1], f[3 * i + 2]));
}

// The multiplier torques on top of the contacts' of the step under way: only on the corrected step (the
// trial step's are zero).
void CoupledDem::applyTorques(cosim::WindowIo& io) {
  if (!spins_) return;
  const auto t = io.read("bridge", "torque");
  for (std::size_t i = 0; i < bridge_.size(); ++i)
    if (const Vec3 torque(t[3 * i], t[3 * i + 1], t[3 * i + 2]); torque != Vec3::Zero()) sim_.addStepTorque(bridge_[i], torque);
}

void CoupledDem::step(const cosim::Window&, const cosim::Substep& s, cosim::WindowIo& io) {
  if (reusesForces()) {
    if (restoreAfterForces_) {
      if (!checkpoint_) throw std::logic_error("dem_solver: a bridging window repeated before its first step");
      sim_.restoreCheckpoint(*checkpoint_);
      applyMultipliers(io);  // the restored state holds the trial step's (none)
      applyTorques(io);
    } else {
      sim_.prepareStep();
      if (saveAfterForces_) checkpoint_ = sim_.saveCheckpoint(Simulation::Keep::kMotion);
    }
    saveAfterForces_ = restoreAfterForces_ = false;
    sim_.finishStep();
    return;
  }
  if (wall_ == kNoWall) {
    sim_.step();
    return;
  }
  placeWall(io, s.begin);
  sim_.prepareStep();
  if (sim_.settings().bridging) applyTorques(io);
  sim_.finishStep();
  // Node-major x, y, z: the layout of a vector of Vec3, read in place.
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  const auto& nf = sim_.meshWalls().walls()[wall_].nodeForce;
  io.write("interface", "force", std::span<const double>(nf.front().data(), 3 * nf.size()));
}

void CoupledDem::writeBridge(cosim::WindowIo& io) {
  const Bodies& bodies = sim_.bodies();
  bridgeOut_.resize(3 * bridge_.size());
  for (std::size_t i = 0; i < bridge_.size(); ++i)
    for (int k = 0; k < 3; ++k) bridgeOut_[3 * i + static_cast<std::size_t>(k)] = bodies.velocity[bridge_[i]][k];
  io.write("bridge", "velocity", bridgeOut_);
  bridgeOut_.resize(bridge_.size());
  for (std::size_t i = 0; i < bridge_.size(); ++i) bridgeOut_[i] = bodies.mass[bridge_[i]];
  io.write("bridge", "mass", bridgeOut_);
  // β at the start position, as the masses were weighted (a particle keeps its share as it moves).
  for (std::size_t i = 0; i < bridge_.size(); ++i) bridgeOut_[i] = weights_[i];
  io.write("bridge", "weight", bridgeOut_);
  if (spins_) {
    for (std::size_t i = 0; i < bridge_.size(); ++i) bridgeOut_[i] = bodies.inertia[bridge_[i]].x();  // β I, a sphere's
    io.write("bridge", "inertia", bridgeOut_);
    bridgeOut_.resize(3 * bridge_.size());
    for (std::size_t i = 0; i < bridge_.size(); ++i)
      for (int k = 0; k < 3; ++k) bridgeOut_[3 * i + static_cast<std::size_t>(k)] = bodies.angularVelocity[bridge_[i]][k];
    io.write("bridge", "spin", bridgeOut_);
  }
  const EnergyLedger& e = sim_.energy();
  // The external work is left out as the multipliers' (a body given a force of its own elsewhere in the
  // scene would count as a drift of the coupled balance).
  const double energy[2] = {e.kinetic + e.potential + e.elastic,
                            e.damping + e.friction + e.cundall + e.bondFracture - e.wallWork};
  io.write("bridge_energy", "energy", energy);
}

void CoupledDem::endWindow(const cosim::Window& w, cosim::WindowIo& io) {
  if (sim_.settings().bridging) writeBridge(io);
  if (wall_ != kNoWall) placeWall(io, 1.0);
  sim_.settings().dt = dt_;
  pending_ = series_.sample();
  pending_.time = w.time + w.dt;
}

void CoupledDem::placeWall(cosim::WindowIo& io, double at) {
  const auto d = io.read("interface", "displacement", at);
  for (std::size_t i = 0; i < positions_.size(); ++i)
    positions_[i] = reference_.nodes[i] + Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
  sim_.meshWalls().setState(wall_, positions_, velocity_);
}

void CoupledDem::archive(common::StateArchive& a) {
  if (!a.reading()) common::archiveExtent(a, h5_);  // read first, by common::openResults
  sim_.archive(a);
  a.io("monitor", monitor_);
  a.io("next_snapshot", nextSnapshot_);
  a.io("committed", committed_);
}

void CoupledDem::report(common::Summary& summary) const {
  const std::int64_t windows = committed_;  // a restarted run's too
  summary.setSteps(sim_.steps());
  summary.set("coupling_windows", windows);
  const Simulation::Profile ph = sim_.profile();
  reportCost(sim_, summary, ph.neighbour + ph.sphereContacts + ph.wallContacts + ph.integrate + ph.other);
  summary.set("spheres", static_cast<std::int64_t>(sim_.spheres().size()));
  summary.set("mesh_skin", sim_.settings().meshSkin);
  summary.set("neighbor_rebuilds", ph.neighbourRebuilds);
  reportSheets(sim_, summary);
  reportBonds(sim_, summary);
}

}  // namespace dem
