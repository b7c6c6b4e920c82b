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
  if (scene.interfaceGroup.empty())
    throw common::ConfigError("a coupled fem_solver run needs `interface: {group: NAME, mode: dirichlet|neumann}` in its scene.");
  return *scene.mesh.group(scene.interfaceGroup);
}
}  // namespace

CoupledFem::CoupledFem(Scene& scene, common::H5Writer& h5)
    : scene_(scene),
      model_(scene.model),
      h5_(h5),
      group_(interfaceGroup(scene)),
      dirichlet_(scene.interfaceMode == "dirichlet"),
      explicit_(scene.analysis == "explicit"),
      series_(h5, scene) {
  addMeshes(h5_, scene_);
  if (dirichlet_)
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

void CoupledFem::declare(cosim::InterfaceIo& io) {
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
    io.addRead("interface", "displacement", 3);
    io.addWrite("interface", "force", 3);
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
  const double interval = scene_.outputInterval;
  if (interval > 0 && t + 1e-9 * interval >= nextSnapshot_) {
    writeSnapshot(h5_, scene_, t, !dirichlet_);
    while (nextSnapshot_ <= t + 1e-9 * interval) nextSnapshot_ += interval;
  }
  series_.write(pending_);
  if (++committed_ % 64 == 0) h5_.flush();
  pending_.time = -1.0;
}

void CoupledFem::advance(const cosim::Window& w, cosim::InterfaceIo& io) {
  const auto& nodes = group_.nodes;
  std::vector<double> target;  // Dirichlet: the interface displacement at the window end, per interface dof
  if (dirichlet_) {
    const auto d = io.read("interface", "displacement");
    target.assign(d.begin(), d.end());
    if (!explicit_)
      for (std::size_t i = 0; i < nodes.size(); ++i)
        for (unsigned k = 0; k < 3; ++k) model_.prescribed[3 * nodes[i] + k] = d[3 * i + k];
  } else {
    const auto f = io.read("interface", "force");
    for (std::size_t i = 0; i < nodes.size(); ++i)
      for (unsigned k = 0; k < 3; ++k) model_.coupledForce[3 * nodes[i] + k] = f[3 * i + k];
  }
  if (explicit_) {
    const cosim::Substeps sub(w.dt, scene_.dt);
    model_.setTimeStep(sub.dt);
    if (dirichlet_) {
      // The interface moves linearly over the window's substeps; the force written back is the window
      // mean of the dynamic support force (inertia included), so the impulse handed to the other side
      // is the one this side received.
      const auto& u = model_.displacement();
      std::vector<double> start(target.size());
      for (std::size_t i = 0; i < nodes.size(); ++i)
        for (unsigned k = 0; k < 3; ++k) start[3 * i + k] = u[3 * nodes[i] + k];
      impulse_.assign(target.size(), 0.0);
      for (std::int64_t s = 0; s < sub.count; ++s) {
        const double f = sub.end(s);
        for (std::size_t i = 0; i < nodes.size(); ++i)
          for (unsigned k = 0; k < 3; ++k)
            model_.prescribed[3 * nodes[i] + k] = start[3 * i + k] + f * (target[3 * i + k] - start[3 * i + k]);
        model_.stepExplicit();
        const auto& r = model_.dynamicSupportForce();
        for (std::size_t i = 0; i < nodes.size(); ++i)
          for (unsigned k = 0; k < 3; ++k) impulse_[3 * i + k] += r[3 * nodes[i] + k] / static_cast<double>(sub.count);
      }
    } else {
      for (std::int64_t s = 0; s < sub.count; ++s) model_.stepExplicit();
    }
  } else {
    StaticSettings settings = scene_.staticSettings;
    if (scene_.rampTime > 0) settings.loadFactor = std::min((w.time + w.dt) / scene_.rampTime, 1.0);
    model_.solveStatic(settings);
  }
  std::vector<double> out;
  const auto& u = model_.displacement();
  const auto& v = model_.velocity();
  if (dirichlet_) {
    // What the structure exerts on the interface: minus the support force.
    if (explicit_) {
      for (double r : impulse_) out.push_back(-r);
    } else {
      for (auto n : nodes) {
        const Vec3 f = -model_.supportForce(n);
        out.insert(out.end(), {f.x(), f.y(), f.z()});
      }
    }
    io.write("interface", "force", out);
  } else {
    for (auto n : nodes) out.insert(out.end(), {u[3 * n], u[3 * n + 1], u[3 * n + 2]});
    io.write("interface", "displacement", out);
    out.clear();
    for (auto n : nodes) out.insert(out.end(), {v[3 * n], v[3 * n + 1], v[3 * n + 2]});
    io.write("interface", "velocity", out);
  }
  pending_ = series_.sample(w.time + w.dt, initialEnergy_);
}

void CoupledFem::writeCheckpoint(const std::string& path) {
  common::StateArchive::write(path, kKind, [&](common::StateArchive& a) { archive(a); });
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
