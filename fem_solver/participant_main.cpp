// The bridge between libfem and libcosim (DESIGN.md §2): runs a fem_solver scene as a participant of a
// coupled run. The interface is the scene's `interface.group`; mode dirichlet reads its displacement and
// writes the force the structure exerts on it, mode neumann reads the force on it and writes its
// displacement and velocity. Static scenes solve each window to equilibrium; explicit scenes advance
// the window with their own (sub)steps and checkpoint at window starts.
#include "participant_main.hpp"

#include <algorithm>
#include <chrono>
#include <unordered_map>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "cosim/participant.hpp"
#include "fem/static_cache.hpp"

namespace fem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary) {
  auto log = common::logger("fem.coupled");
  if (scene.interfaceGroup.empty())
    throw common::ConfigError("a coupled fem_solver run needs `interface: {group: NAME, mode: dirichlet|neumann}` in its scene.");
  const Mesh::Group& g = *scene.mesh.group(scene.interfaceGroup);
  Model& model = scene.model;
  std::vector<double> coords;
  std::unordered_map<std::uint32_t, std::uint32_t> local;
  for (std::uint32_t i = 0; i < g.nodes.size(); ++i) {
    local[g.nodes[i]] = i;
    const Vec3& x = model.reference[g.nodes[i]];
    coords.insert(coords.end(), {x.x(), x.y(), x.z()});
  }
  std::vector<std::uint32_t> triangles;
  if (g.dim == 2)
    for (auto n : g.connectivity) triangles.push_back(local.at(n));
  const bool dirichlet = scene.interfaceMode == "dirichlet";
  if (dirichlet)
    for (auto n : g.nodes)
      for (int k = 0; k < 3; ++k) model.fixed[3 * n + static_cast<unsigned>(k)] = 1;

  common::H5Writer h5(outDir / "fem.h5");
  addMeshes(h5, scene);
  // Field snapshots at the scene's output.interval, of final windows only (the model at the window's end).
  double nextSnapshot = 0.0;
  std::vector<std::string> reactionCols, probeCols;
  for (const auto& r : scene.reactionGroups)
    for (const char* c : {"_fx", "_fy", "_fz"}) reactionCols.push_back(r.name + c);
  for (const auto& pr : scene.probes)
    for (const char* c : {"_ux", "_uy", "_uz"}) probeCols.push_back(pr.name + c);
  if (!reactionCols.empty()) h5.addSeries("reactions", reactionCols);
  if (!probeCols.empty()) h5.addSeries("probes", probeCols);
  h5.addSeries("energy", {"kinetic", "strain", "external_work", "damping", "coupled_work"});
  // A window's record is kept once the window is final (the next one starts, or the run ends).
  std::vector<double> pendingReactions, pendingProbes, pendingEnergy;
  double pendingTime = -1.0;
  auto commit = [&] {
    if (pendingTime < 0) return;
    if (scene.outputInterval > 0 && pendingTime + 1e-9 * scene.outputInterval >= nextSnapshot) {
      writeSnapshot(h5, scene, pendingTime, !dirichlet);
      while (nextSnapshot <= pendingTime + 1e-9 * scene.outputInterval) nextSnapshot += scene.outputInterval;
    }
    if (!reactionCols.empty()) h5.append("reactions", pendingTime, pendingReactions);
    if (!probeCols.empty()) h5.append("probes", pendingTime, pendingProbes);
    h5.append("energy", pendingTime, pendingEnergy);
    pendingTime = -1.0;
  };

  cosim::Participant p(name, endpoint);
  p.addMesh("interface", coords, triangles);
  if (dirichlet) {
    p.addRead("interface", "displacement", 3);
    p.addWrite("interface", "force", 3);
  } else {
    p.addRead("interface", "force", 3);
    p.addWrite("interface", "displacement", 3);
    p.addWrite("interface", "velocity", 3);
  }
  try {
    // The initial static state is solver work: done before HELLO, so the coupler's first wait is not
    // charged with it.
    const bool explicitRun = scene.analysis == "explicit";
    if (explicitRun) {
      if (scene.initialStatic) summary.set("static_reused", static_cast<std::int64_t>(solveStaticCached(model, scene.staticSettings).reused));
      model.initializeExplicit(scene.dt);
      if (scene.outputInterval > 0) {  // the net before the impact
        writeSnapshot(h5, scene, 0.0, !dirichlet);
        nextSnapshot = scene.outputInterval;
      }
    }
    p.initialize();
    // Reported to the coupler with every result; a loop over all elements, so once, not per iteration.
    const double critical = explicitRun ? model.criticalTimeStep() : 0.0;
    Model::State checkpoint;
    std::vector<double> impulse;  // Dirichlet, explicit: window-mean support force per interface dof
    cosim::Window w;
    std::int64_t windows = 0;
    std::uint64_t currentWindow = 0;
    while (p.nextWindow(w)) {
      const auto start = std::chrono::steady_clock::now();
      if (w.restoreCheckpoint && explicitRun) model.restoreState(checkpoint);
      if (w.saveCheckpoint && explicitRun) checkpoint = model.saveState();
      if (w.index != currentWindow || windows == 0) {  // a new window: the previous one is final
        commit();
        currentWindow = w.index;
        ++windows;
        if (windows % 64 == 0) h5.flush();
      }
      std::vector<double> target;  // Dirichlet: the interface displacement at the window end, per interface dof
      if (dirichlet) {
        const auto d = p.read("interface", "displacement");
        target.assign(d.begin(), d.end());
        if (!explicitRun)
          for (std::size_t i = 0; i < g.nodes.size(); ++i)
            for (unsigned k = 0; k < 3; ++k) model.prescribed[3 * g.nodes[i] + k] = d[3 * i + k];
      } else {
        const auto f = p.read("interface", "force");
        for (std::size_t i = 0; i < g.nodes.size(); ++i)
          for (int k = 0; k < 3; ++k) model.coupledForce[3 * g.nodes[i] + static_cast<unsigned>(k)] = f[3 * i + static_cast<unsigned>(k)];
      }
      if (explicitRun) {
        const auto steps = static_cast<std::int64_t>(std::ceil(w.dt / scene.dt - 1e-9));
        model.setTimeStep(w.dt / static_cast<double>(steps));
        if (dirichlet) {
          // The interface moves linearly over the window's substeps; the force written back is the
          // window mean of the dynamic support force (inertia included), so the impulse handed to the
          // other side is the one this side received.
          const auto& u = model.displacement();
          std::vector<double> start(target.size());
          for (std::size_t i = 0; i < g.nodes.size(); ++i)
            for (unsigned k = 0; k < 3; ++k) start[3 * i + k] = u[3 * g.nodes[i] + k];
          impulse.assign(target.size(), 0.0);
          for (std::int64_t s = 0; s < steps; ++s) {
            const double f = static_cast<double>(s + 1) / static_cast<double>(steps);
            for (std::size_t i = 0; i < g.nodes.size(); ++i)
              for (unsigned k = 0; k < 3; ++k)
                model.prescribed[3 * g.nodes[i] + k] = start[3 * i + k] + f * (target[3 * i + k] - start[3 * i + k]);
            model.stepExplicit();
            const auto& r = model.dynamicSupportForce();
            for (std::size_t i = 0; i < g.nodes.size(); ++i)
              for (unsigned k = 0; k < 3; ++k) impulse[3 * i + k] += r[3 * g.nodes[i] + k] / static_cast<double>(steps);
          }
        } else {
          for (std::int64_t s = 0; s < steps; ++s) model.stepExplicit();
        }
      } else {
        StaticSettings settings = scene.staticSettings;
        if (scene.rampTime > 0) settings.loadFactor = std::min((w.time + w.dt) / scene.rampTime, 1.0);
        model.solveStatic(settings);
      }
      std::vector<double> out;
      const auto& u = model.displacement();
      const auto& v = model.velocity();
      if (dirichlet) {
        // What the structure exerts on the interface: minus the support force.
        if (explicitRun) {
          for (double r : impulse) out.push_back(-r);
        } else {
          for (auto n : g.nodes) {
            const Vec3 f = -model.supportForce(n);
            out.insert(out.end(), {f.x(), f.y(), f.z()});
          }
        }
        p.write("interface", "force", out);
      } else {
        for (auto n : g.nodes) out.insert(out.end(), {u[3 * n], u[3 * n + 1], u[3 * n + 2]});
        p.write("interface", "displacement", out);
        out.clear();
        for (auto n : g.nodes) out.insert(out.end(), {v[3 * n], v[3 * n + 1], v[3 * n + 2]});
        p.write("interface", "velocity", out);
      }
      pendingReactions.clear();
      for (const auto& r : groupReactions(scene)) pendingReactions.insert(pendingReactions.end(), {r.x(), r.y(), r.z()});
      pendingProbes.clear();
      for (const auto& pr : scene.probes)
        pendingProbes.insert(pendingProbes.end(), {u[3 * pr.node], u[3 * pr.node + 1], u[3 * pr.node + 2]});
      const EnergyState& e = model.energy();
      pendingEnergy = {e.kinetic, e.strain, e.externalWork, e.damping, e.coupledWork};
      pendingTime = w.time + w.dt;
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      p.complete(seconds, critical);
    }
    commit();
    h5.flush();
    summary.setSteps(windows);
    summary.set("coupling_windows", windows);
    reportProbesAndReactions(scene, summary, "");
  } catch (const cosim::CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  } catch (const std::exception& e) {
    p.fail(fmt::format("fem_solver {}: {}", name, e.what()), dynamic_cast<const common::InstabilityError*>(&e) != nullptr);
    throw;
  }
}

}  // namespace fem
