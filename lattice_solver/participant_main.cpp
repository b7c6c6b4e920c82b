// The bridge between liblattice and libcosim (DESIGN.md §2): runs a lattice_solver scene as a participant
// of a quasi-static coupled run. Every face of the scene's `interface` is one interface mesh named after
// the face (x_min … z_max): its nodes, and the 2-D Delaunay triangles of their in-plane coordinates (so
// either side may use nearest_projection). A dirichlet face reads `displacement` and writes `force` (what
// the lattice exerts on it); a neumann face reads `force` and writes `displacement`.
//
// Each ADVANCE is one load state: the coupler's time is only a load parameter. Checkpoints: the lattice
// state (K, removed rods, held fragments) is saved at a window start and restored when the coupler
// repeats the window, so rods that broke in a rejected iterate come back; a window is committed (its
// removals recorded, its row written) when the next window starts or the run ends.
#include "participant_main.hpp"

#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "cosim/participant.hpp"

namespace lattice {

namespace {

// The nominal strain and stress of the lattice zone along `axis`, when both of its faces normal to it
// are coupled: ε = (ū_max − ū_min)/H, σ = (F_min − F_max)/(2A) with F the axial force the lattice exerts
// on each face (positive in tension). Otherwise 0, 0.
struct Nominal {
  int lo = -1, hi = -1;
  double height = 0.0, area = 0.0;
  bool valid() const { return lo >= 0 && hi >= 0; }
};

}  // namespace

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name, const std::filesystem::path& outDir,
                    common::Summary& summary) {
  auto log = common::logger("lattice.coupled");
  if (scene.supports.coupled.empty())
    throw common::ConfigError("a coupled lattice_solver run needs `interface: [{face: z_min, mode: dirichlet}, …]` in its "
                              "scene: the specimen faces the coupler drives.");
  const Specimen& sp = scene.specimen;
  logSpecimen(scene);
  Model model = buildModel(scene, true);
  auto solver = makeSolver(scene.solver, scene.solverSettings);
  CoupledLattice lattice(model, *solver, scene.loading.removal, scene.loading.maxRounds, scene.coupledRemoval,
                         scene.settleTolerance);
  const int axis = scene.supports.axis;

  Nominal nominal;
  for (std::size_t i = 0; i < lattice.faces(); ++i) {
    const Face& f = lattice.face(i).face;
    if (f.axis == axis) (f.side == 0 ? nominal.lo : nominal.hi) = static_cast<int>(i);
  }
  nominal.height = sp.box.size[axis];
  nominal.area = sp.box.volume() / nominal.height;

  cosim::Participant p(name, endpoint);
  std::vector<std::string> meshes, cols;
  for (std::size_t i = 0; i < lattice.faces(); ++i) {
    const Face& f = lattice.face(i).face;
    const std::string mesh = faceName(f);
    meshes.push_back(mesh);
    std::vector<double> coords;
    std::vector<Eigen::Vector2d> inPlane;
    for (auto n : model.faceNodes(i)) {
      const Vec3& x = sp.nodes[n];
      coords.insert(coords.end(), {x.x(), x.y(), x.z()});
      inPlane.emplace_back(x[(f.axis + 1) % 3], x[(f.axis + 2) % 3]);
    }
    std::vector<std::uint32_t> triangles;
    if (inPlane.size() >= 3)
      for (const auto& t : delaunayTriangles(inPlane)) triangles.insert(triangles.end(), t.begin(), t.end());
    p.addMesh(mesh, coords, triangles);
    const bool dirichlet = lattice.face(i).mode == FaceMode::kDirichlet;
    p.addRead(mesh, dirichlet ? "displacement" : "force", 3);
    p.addWrite(mesh, dirichlet ? "force" : "displacement", 3);
    for (const char* c : {"_fx", "_fy", "_fz", "_ux", "_uy", "_uz"}) cols.push_back(mesh + c);
    log->info("interface {} ({}): {} nodes, {} triangles", mesh, dirichlet ? "dirichlet" : "neumann", model.faceNodes(i).size(),
              triangles.size() / 3);
  }
  for (const char* c : {"strain", "stress", "removed", "removed_total", "rounds", "iterations", "coupling_iterations"})
    cols.push_back(c);

  LatticeOutput out(outDir / "lattice.h5", sp);
  common::H5Writer& h5 = out.h5();
  h5.addSeries("windows", cols);

  // The last iterate of the current window, written when the window is committed.
  struct Pending {
    bool any = false;
    std::uint64_t window = 0;
    double time = 0.0, strain = 0.0, stress = 0.0;
    std::vector<double> row;
  } pending;
  double peakStress = 0.0, strainAtPeak = 0.0, youngsModulus = 0.0;
  int peakWindow = -1;
  std::int64_t windows = 0, lateRemovals = 0;
  std::size_t removedBefore = 0;
  auto commit = [&] {
    if (!pending.any) return;
    if (const std::size_t late = lattice.commit(static_cast<int>(pending.window), pending.strain); late > 0) {
      lateRemovals += static_cast<std::int64_t>(late);
      log->info("window {}: {} rods over their limit in the committed state removed at its end", pending.window, late);
    }
    // Rods removed in this window: in any of its settled iterates, or late.
    const std::size_t removedNow = model.removedCount() - removedBefore;
    removedBefore = model.removedCount();
    pending.row[6 * lattice.faces() + 2] = static_cast<double>(removedNow);
    pending.row[6 * lattice.faces() + 3] = static_cast<double>(model.removedCount());
    h5.append("windows", pending.time, pending.row);
    if (windows == 1 && removedNow == 0 && pending.strain != 0.0) youngsModulus = pending.stress / pending.strain;
    if (pending.stress > peakStress) {
      peakWindow = static_cast<int>(pending.window);
      peakStress = pending.stress;
      strainAtPeak = pending.strain;
    }
    if (scene.snapshotEvery > 0 && windows % scene.snapshotEvery == 0)
      out.snapshot(model, lattice.displacement(), lattice.removedAt(), pending.time);
    else if (windows % 16 == 0)
      h5.flush();
    pending.any = false;
  };

  try {
    p.initialize();
    cosim::Window w;
    while (p.nextWindow(w)) {
      const auto start = std::chrono::steady_clock::now();
      if (!pending.any || w.index != pending.window) {  // a new window: the previous one is final
        commit();
        ++windows;
      }
      if (w.restoreCheckpoint) lattice.restore();
      if (w.saveCheckpoint) lattice.save();
      for (std::size_t i = 0; i < lattice.faces(); ++i)
        lattice.setInput(i, p.read(meshes[i], lattice.face(i).mode == FaceMode::kDirichlet ? "displacement" : "force"));
      const auto rep = lattice.advance(fmt::format("window {} iteration {}", w.index, w.iteration),
                                       !w.saveCheckpoint && !w.restoreCheckpoint);
      for (std::size_t i = 0; i < lattice.faces(); ++i)
        p.write(meshes[i], lattice.face(i).mode == FaceMode::kDirichlet ? "force" : "displacement", lattice.output(i));

      pending.any = true;
      pending.window = w.index;
      pending.time = w.time + w.dt;
      pending.row.clear();
      for (std::size_t i = 0; i < lattice.faces(); ++i) {
        const Eigen::Vector3d f = lattice.resultant(i), u = lattice.meanDisplacement(i);
        pending.row.insert(pending.row.end(), {f.x(), f.y(), f.z(), u.x(), u.y(), u.z()});
      }
      pending.strain = pending.stress = 0.0;
      if (nominal.valid()) {
        const auto lo = static_cast<std::size_t>(nominal.lo), hi = static_cast<std::size_t>(nominal.hi);
        pending.strain = (lattice.meanDisplacement(hi)[axis] - lattice.meanDisplacement(lo)[axis]) / nominal.height;
        pending.stress = (lattice.resultant(lo)[axis] - lattice.resultant(hi)[axis]) / (2 * nominal.area);
      }
      // removed and removed_total are set at the commit.
      pending.row.insert(pending.row.end(), {pending.strain, pending.stress, 0.0, 0.0, static_cast<double>(rep.rounds),
                                             static_cast<double>(rep.iterations), static_cast<double>(w.iteration + 1)});
      if (rep.removed.size() > 0)
        log->debug("window {} iteration {}: ε = {:.4g}, σ = {:.4g} Pa, {} rods removed in {} rounds", w.index, w.iteration,
                   pending.strain, pending.stress, rep.removed.size(), rep.rounds - 1);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      p.complete(seconds, 0.0);
    }
    commit();
  } catch (const cosim::CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  } catch (const std::exception& e) {
    p.fail(fmt::format("lattice_solver {}: {}", name, e.what()), dynamic_cast<const common::InstabilityError*>(&e) != nullptr);
    throw;
  }
  out.snapshot(model, lattice.displacement(), lattice.removedAt(), pending.time);
  std::vector<LatticeOutput::Crack> cracks;
  std::vector<std::uint32_t> removed;
  for (const auto& r : lattice.removals()) {
    cracks.push_back({r.rod, r.window, r.nominalStrain, r.rodStrain});
    removed.push_back(r.rod);
  }
  out.cracks(cracks, pending.time);
  h5.flush();

  const auto& eq = lattice.equilibrium();
  summary.setSteps(windows);
  summary.set("coupling_windows", windows);
  summary.set("peak_stress", peakStress);
  summary.set("strain_at_peak", strainAtPeak);
  summary.set("youngs_modulus", youngsModulus);
  summary.set("final_strain", pending.strain);
  summary.set("final_stress", pending.stress);
  reportSpecimen(scene, model, removed, axis, summary);
  // The macro-crack: the rods removed after the peak window, without the diffuse pre-peak microcracking.
  std::vector<std::uint32_t> postPeak;
  for (const auto& r : lattice.removals())
    if (r.window > peakWindow) postPeak.push_back(r.rod);
  const CrackBand band = crackBand(model, postPeak, axis, 2 * sp.meanRodLength());
  summary.set("rods_removed_post_peak", static_cast<std::int64_t>(postPeak.size()));
  summary.set("crack_plane_post_peak", band.plane);
  summary.set("crack_band_fraction_post_peak", band.fraction);
  summary.set("solves", static_cast<std::int64_t>(eq.solves()));
  summary.set("solver_iterations", static_cast<std::int64_t>(eq.iterations()));
  summary.set("solve_time_s", eq.solveSeconds());
  summary.set("removal_time_s", eq.removalSeconds());
  summary.set("late_removals", lateRemovals);
  for (std::size_t i = 0; i < lattice.faces(); ++i) {
    const Eigen::Vector3d f = lattice.resultant(i);
    summary.set("force_" + meshes[i], std::vector<double>{f.x(), f.y(), f.z()});
  }
  log->info("{} windows; peak stress {:.4g} MPa at strain {:.4g}; E = {:.4g} GPa; {} of {} rods removed; {} solves, {} "
            "iterations",
            windows, peakStress / 1e6, strainAtPeak, youngsModulus / 1e9, removed.size(), sp.rods.size(), eq.solves(),
            eq.iterations());
}

}  // namespace lattice
