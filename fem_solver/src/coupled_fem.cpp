#include "fem/coupled_fem.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "fem/static_cache.hpp"

namespace fem {

namespace {
const Mesh::Group& interfaceGroup(const Scene& scene) {
  static const Mesh::Group kNone;
  if (scene.interfaceGroup.empty() && scene.bridging) return kNone;
  if (scene.interfaceGroup.empty())
    throw common::ConfigError("a coupled fem_solver run needs `interface: {group: NAME, mode: dirichlet|neumann}` or "
                              "`bridging:` in its scene.");
  return *scene.mesh.group(scene.interfaceGroup);
}
}  // namespace

CoupledFem::CoupledFem(Scene& scene, common::H5Writer& h5)
    : scene_(scene),
      model_(scene.model),
      h5_(h5),
      group_(interfaceGroup(scene)),
      interface_(!scene.interfaceGroup.empty()),
      dirichlet_(scene.interfaceMode == "dirichlet"),
      explicit_(scene.analysis == "explicit"),
      out_(3 * group_.nodes.size()),
      series_(h5, scene) {
  addMeshes(h5_, scene_);
  if (scene_.bridging) bridge_ = bridgeCells(model_, *scene_.bridging);
  if (interface_ && dirichlet_)
    for (auto n : group_.nodes)
      for (int k = 0; k < 3; ++k) model_.fixed[3 * n + static_cast<unsigned>(k)] = 1;
  if (explicit_) {
    if (scene_.initialStatic) staticReused_ = solveStaticCached(model_, scene_.staticSettings).reused;
    model_.initializeExplicit(scene_.dt);
    initialEnergy_ = model_.energy().kinetic + model_.energy().strain;
    if (scene_.outputInterval > 0 && !h5_.resumed()) {  // the net before the impact (a resumed file has it)
      writeSnapshot(h5_, scene_, 0.0, !dirichlet_);
      nextSnapshot_ = scene_.outputInterval;
    }
    critical_ = model_.criticalTimeStep();  // a loop over all elements: once, not per iteration
  }
}

void CoupledFem::declare(cosim::InterfaceDeclaration& io) {
  if (bridge_) {
    std::vector<double> coords;
    for (auto n : bridge_->nodes) coords.insert(coords.end(), {model_.reference[n].x(), model_.reference[n].y(), model_.reference[n].z()});
    cosim::declareBridge(io, coords, bridge_->nodesPerCell, bridge_->cells);
  }
  if (!interface_) return;
  std::vector<double> coords;
  std::unordered_map<std::uint32_t, std::uint32_t> local;
  for (std::uint32_t i = 0; i < group_.nodes.size(); ++i) {
    local[group_.nodes[i]] = i;
    const Vec3& x = model_.reference[group_.nodes[i]];
    coords.insert(coords.end(), {x.x(), x.y(), x.z()});
  }
  std::vector<std::uint32_t> triangles;
  if (group_.dim == 2)
    for (auto n : group_.connectivity) triangles.push_back(local.at(n));
  io.addMesh("interface", coords, triangles);
  if (dirichlet_) {
    // The first window moves the interface from where the model has it (fixed since the start).
    io.addRead("interface", "displacement", 3, cosim::Interpolation::kLinear, gather(model_.displacement()));
    io.addWrite("interface", "force", 3, cosim::Reduction::kMean);
  } else {
    io.addRead("interface", "force", 3);
    io.addWrite("interface", "displacement", 3);
    io.addWrite("interface", "velocity", 3);
  }
}

void CoupledFem::save() {
  if (explicit_) checkpoint_ = model_.saveState();
}

void CoupledFem::restore() {
  if (explicit_) model_.restoreState(checkpoint_);
}

void CoupledFem::commit() {
  const double t = pending_.time;
  if (t < 0) return;
  if (common::snapshotDue(t, scene_.outputInterval, nextSnapshot_)) writeSnapshot(h5_, scene_, t, !dirichlet_);
  series_.write(pending_);
  if (++committed_ % 64 == 0) h5_.flush();
  pending_.time = -1.0;
}

const std::vector<double>& CoupledFem::gather(const std::vector<double>& field, double sign) {
  const auto& nodes = group_.nodes;
  for (std::size_t i = 0; i < nodes.size(); ++i)
    for (unsigned k = 0; k < 3; ++k) out_[3 * i + k] = sign * field[3 * nodes[i] + k];
  return out_;
}

void CoupledFem::beginWindow(const cosim::Window&, const cosim::Substeps& sub, cosim::WindowIo& io) {
  if (explicit_) model_.setTimeStep(sub.dt);
  if (bridge_) {
    const auto f = io.read("bridge", "force");
    for (std::size_t i = 0; i < bridge_->nodes.size(); ++i)
      for (unsigned k = 0; k < 3; ++k) model_.coupledForce[3 * bridge_->nodes[i] + k] = f[3 * i + k];
  }
  if (interface_ && !dirichlet_) {  // held over the window
    const auto& nodes = group_.nodes;
    const auto f = io.read("interface", "force");
    for (std::size_t i = 0; i < nodes.size(); ++i)
      for (unsigned k = 0; k < 3; ++k) model_.coupledForce[3 * nodes[i] + k] = f[3 * i + k];
  }
}

void CoupledFem::step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) {
  const auto& nodes = group_.nodes;
  if (interface_ && dirichlet_) {
    // The displacement at the substep's end: the central-difference step computes u there.
    const auto d = io.read("interface", "displacement", s.end);
    for (std::size_t i = 0; i < nodes.size(); ++i)
      for (unsigned k = 0; k < 3; ++k) model_.prescribed[3 * nodes[i] + k] = d[3 * i + k];
  }
  if (explicit_) {
    model_.stepExplicit();
  } else {
    StaticSettings settings = scene_.staticSettings;
    if (scene_.rampTime > 0) settings.loadFactor = std::min((w.time + w.dt) / scene_.rampTime, 1.0);
    model_.solveStatic(settings);
  }
  if (!interface_ || !dirichlet_) return;
  // What the structure exerts on the interface: minus the support force; explicit, the dynamic one
  // (inertia included), whose window mean hands the other side the impulse this side received.
  if (explicit_) {
    gather(model_.dynamicSupportForce(), -1.0);
  } else {
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const Vec3 f = -model_.supportForce(nodes[i]);
      for (unsigned k = 0; k < 3; ++k) out_[3 * i + k] = f[static_cast<int>(k)];
    }
  }
  io.write("interface", "force", out_);
}

void CoupledFem::writeBridge(cosim::WindowIo& io) {
  const auto& nodes = bridge_->nodes;
  bridgeOut_.resize(3 * nodes.size());
  const auto& v = model_.velocity();
  for (std::size_t i = 0; i < nodes.size(); ++i)
    for (unsigned k = 0; k < 3; ++k) bridgeOut_[3 * i + k] = v[3 * nodes[i] + k];
  io.write("bridge", "velocity", bridgeOut_);
  bridgeOut_.resize(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) bridgeOut_[i] = model_.nodeMass()[nodes[i]];
  io.write("bridge", "mass", bridgeOut_);
  // Unclamped: the coupler interpolates it at the particles, exactly, and clamps it there.
  for (std::size_t i = 0; i < nodes.size(); ++i) bridgeOut_[i] = scene_.bridging->linear(model_.reference[nodes[i]]);
  io.write("bridge", "weight", bridgeOut_);
  const EnergyState& e = model_.energy();
  const double energy[2] = {e.kinetic + e.strain, e.damping - (e.externalWork - e.coupledWork)};
  io.write("bridge_energy", "energy", energy);
  const double shape[1] = {static_cast<double>(scene_.bridging->shape)};
  io.write("bridge_energy", "shape", shape);
}

void CoupledFem::endWindow(const cosim::Window& w, cosim::WindowIo& io) {
  if (bridge_) writeBridge(io);
  if (interface_ && !dirichlet_) {
    io.write("interface", "displacement", gather(model_.displacement()));
    io.write("interface", "velocity", gather(model_.velocity()));
  }
  pending_ = series_.sample(w.time + w.dt, initialEnergy_);
}

void CoupledFem::archive(common::StateArchive& a) {
  a.shape(model_.shape());
  if (!a.reading()) common::archiveExtent(a, h5_);  // read first, by common::openResults
  Model::State state = model_.saveState();
  a.io("model", state);
  if (a.reading()) model_.restoreState(state);
  // The summary states whether the static start came from the cache: as in the run that wrote this.
  int reused = staticReused_ ? static_cast<int>(*staticReused_) : -1;
  a.io("static_reused", reused);
  if (a.reading()) staticReused_ = reused < 0 ? std::nullopt : std::optional<bool>(reused == 1);
  a.io("initial_energy", initialEnergy_);
  a.io("next_snapshot", nextSnapshot_);
  a.io("committed", committed_);
}

void CoupledFem::report(common::Summary& summary) const {
  const std::int64_t windows = committed_;  // a restarted run's too
  if (staticReused_) summary.set("static_reused", static_cast<std::int64_t>(*staticReused_));
  summary.setSteps(windows);
  summary.set("coupling_windows", windows);
  reportProbesAndReactions(scene_, summary, "");
}

}  // namespace fem
