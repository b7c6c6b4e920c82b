// The bridge between libdem and libcosim (DESIGN.md §2): runs a dem_solver scene as a participant. The
// interface is the mesh wall named by `interface.wall` (motion: external). Each window it reads the
// wall's node displacement (from the wall's reference nodes) at the window end and moves the nodes
// linearly from their window-start positions over its substeps (velocity = their displacement over the
// window, consistent with that motion), and writes the nodal contact
// force averaged over the window (the impulse divided by the window: momentum is passed on exactly).
#include "participant_main.hpp"

#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "cosim/participant.hpp"
#include "dem/stability_monitor.hpp"

namespace dem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary) {
  auto log = common::logger("dem.coupled");
  if (scene.interfaceWall.empty())
    throw common::ConfigError("a coupled dem_solver run needs `interface: {wall: NAME}` naming a mesh wall with motion: external.");
  Simulation& sim = *scene.sim;
  std::uint32_t wallIndex = 0;
  while (sim.meshes()[wallIndex].name != scene.interfaceWall) ++wallIndex;
  const MeshWall reference = sim.meshes()[wallIndex];
  const std::size_t nn = reference.nodes.size();
  std::vector<double> coords;
  std::vector<std::uint32_t> triangles;
  for (const auto& x : reference.nodes) coords.insert(coords.end(), {x.x(), x.y(), x.z()});
  for (const auto& t : reference.triangles) triangles.insert(triangles.end(), {t[0], t[1], t[2]});

  common::H5Writer h5(outDir / "dem.h5");
  addMeshWalls(h5, sim);
  const std::uint32_t body = scene.probe.body;
  h5.addSeries("body_0", {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz", "contacts"});
  h5.addSeries("energy", {"kinetic", "potential", "elastic", "damping", "friction", "cundall", "wall_work", "residual"});

  cosim::Participant p(name, endpoint);
  p.addMesh("interface", coords, triangles);
  p.addRead("interface", "displacement", 3);
  p.addWrite("interface", "force", 3);
  try {
    p.initialize();
    const double dt = sim.settings().dt;
    const double critical = sim.criticalTimeStep();  // a loop over every sphere: once, not per iteration
    std::shared_ptr<const Simulation::Checkpoint> checkpoint;
    std::vector<double> pendingBody, pendingEnergy;
    double pendingTime = -1.0;
    // The run's own energy ledger, checked on final windows only (a repeated window's iterations are
    // discarded with their ledger).
    StabilityMonitor monitor(sim, scene.energyTolerance);
    std::int64_t windows = 0;
    // Snapshots at the scene's output.interval, of final windows only (the state at the window's end).
    // None at t = 0: the interface wall is not yet where the structure put it (the net's static sag
    // arrives with the first window).
    double nextSnapshot = scene.output.interval;
    auto commit = [&] {  // the previous window is final: record it
      if (pendingTime < 0) return;
      if (scene.output.interval > 0 && pendingTime + 1e-9 * scene.output.interval >= nextSnapshot) {
        writeParticleSnapshot(h5, sim, pendingTime);
        while (nextSnapshot <= pendingTime + 1e-9 * scene.output.interval) nextSnapshot += scene.output.interval;
      }
      monitor.check(sim);
      if (windows % 16 == 0) monitor.observe(sim);
      h5.append("body_0", pendingTime, pendingBody);
      h5.append("energy", pendingTime, pendingEnergy);
      pendingTime = -1.0;
    };
    std::uint64_t currentWindow = 0;
    cosim::Window w;
    std::vector<Vec3> start(nn), end(nn), positions(nn), velocity(nn);
    std::vector<double> force(3 * nn);
    while (p.nextWindow(w)) {
      const auto t0 = std::chrono::steady_clock::now();
      if (w.index != currentWindow || windows == 0) {  // a new window: the previous one is final
        commit();
        currentWindow = w.index;
        ++windows;
        if (windows % 64 == 0) h5.flush();
      }
      if (w.saveCheckpoint) checkpoint = sim.saveCheckpoint();
      if (w.restoreCheckpoint && checkpoint) sim.restoreCheckpoint(*checkpoint);
      const auto d = p.read("interface", "displacement");
      for (std::size_t i = 0; i < nn; ++i) {
        start[i] = sim.meshes()[wallIndex].nodes[i];
        end[i] = reference.nodes[i] + Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
        velocity[i] = (end[i] - start[i]) / w.dt;
      }
      const auto substeps = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(w.dt / dt - 1e-9)));
      sim.settings().dt = w.dt / static_cast<double>(substeps);
      std::fill(force.begin(), force.end(), 0.0);
      for (std::int64_t s = 0; s < substeps; ++s) {
        const double a = static_cast<double>(s) / static_cast<double>(substeps);
        for (std::size_t i = 0; i < nn; ++i) positions[i] = start[i] + a * (end[i] - start[i]);
        sim.setMeshState(wallIndex, positions, velocity);
        sim.step();
        const auto& nf = sim.meshes()[wallIndex].nodeForce;
        for (std::size_t i = 0; i < nn; ++i)
          for (int k = 0; k < 3; ++k) force[3 * i + static_cast<unsigned>(k)] += nf[i][k] / static_cast<double>(substeps);
      }
      sim.setMeshState(wallIndex, end, velocity);
      sim.settings().dt = dt;
      p.write("interface", "force", force);
      // This iteration's record; kept only if the window turns out final.
      const auto& B = sim.bodies();
      const Vec3 v = sim.bodyVelocity(body);
      const BodyContacts c = sim.bodyContacts(body);
      pendingBody = {B.position[body].x(), B.position[body].y(), B.position[body].z(), v.x(), v.y(), v.z(),
                     B.angularVelocity[body].x(), B.angularVelocity[body].y(), B.angularVelocity[body].z(),
                     B.force[body].x(), B.force[body].y(), B.force[body].z(), static_cast<double>(c.count)};
      const EnergyLedger& e = sim.energy();
      pendingEnergy = {e.kinetic, e.potential, e.elastic, e.damping, e.friction, e.cundall, e.wallWork,
                       e.residual(sim.initialEnergy())};
      pendingTime = w.time + w.dt;
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      p.complete(seconds, critical);
    }
    commit();
    h5.flush();
    summary.setSteps(sim.steps());
    summary.set("coupling_windows", windows);
    const Simulation::PhaseSeconds& ph = sim.phaseSeconds();
    reportCost(sim, summary, ph.neighbour + ph.sphereContacts + ph.wallContacts + ph.integrate + ph.other);
    summary.set("spheres", static_cast<std::int64_t>(sim.spheres().size()));
    summary.set("mesh_skin", sim.settings().meshSkin);
    summary.set("neighbor_rebuilds", sim.neighbourRebuilds());
    reportSheets(sim, summary);
  } catch (const cosim::CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  } catch (const std::exception& e) {
    p.fail(fmt::format("dem_solver {}: {}", name, e.what()), dynamic_cast<const common::InstabilityError*>(&e) != nullptr);
    throw;
  }
}

}  // namespace dem
