#include "lattice/coupled_lattice_run.hpp"

#include <fmt/format.h>

#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"

namespace lattice {

CoupledLatticeRun::CoupledLatticeRun(const Scene& scene, common::H5Writer& h5)
    : scene_(scene),
      h5_(h5),
      model_(buildModel(scene, true)),
      solver_(scene.solver.build()),
      lattice_(model_, *solver_, scene.loading.removal, scene.loading.maxRounds, scene.coupledRemoval, scene.settleTolerance),
      out_(h5, scene.specimen),
      axis_(scene.supports.axis) {
  const Specimen& sp = scene.specimen;
  for (std::size_t i = 0; i < lattice_.faces(); ++i) {
    const Face& f = lattice_.face(i).face;
    if (f.axis == axis_) (f.side == 0 ? nominal_.lo : nominal_.hi) = static_cast<int>(i);
    meshes_.push_back(faceName(f));
  }
  nominal_.height = sp.box.size[axis_];
  nominal_.area = sp.box.volume() / nominal_.height;
  std::vector<std::string> cols;
  for (const auto& mesh : meshes_)
    for (const char* c : {"_fx", "_fy", "_fz", "_ux", "_uy", "_uz"}) cols.push_back(mesh + c);
  for (const char* c : {"strain", "stress", "removed", "removed_total", "rounds", "iterations", "coupling_iterations"})
    cols.push_back(c);
  out_.h5().addSeries("windows", cols);
}

void CoupledLatticeRun::declare(cosim::InterfaceDeclaration& io) {
  auto log = common::logger("lattice.coupled");
  const Specimen& sp = scene_.specimen;
  for (std::size_t i = 0; i < lattice_.faces(); ++i) {
    const Face& f = lattice_.face(i).face;
    std::vector<double> coords;
    std::vector<Eigen::Vector2d> inPlane;
    for (auto n : model_.faceNodes(i)) {
      const Vec3& x = sp.nodes[n];
      coords.insert(coords.end(), {x.x(), x.y(), x.z()});
      inPlane.emplace_back(x[(f.axis + 1) % 3], x[(f.axis + 2) % 3]);
    }
    std::vector<std::uint32_t> triangles;
    if (inPlane.size() >= 3)
      for (const auto& t : delaunayTriangles(inPlane)) triangles.insert(triangles.end(), t.begin(), t.end());
    io.addMesh(meshes_[i], coords, triangles);
    const bool dirichlet = lattice_.face(i).mode == FaceMode::kDirichlet;
    io.addRead(meshes_[i], dirichlet ? "displacement" : "force", 3);
    io.addWrite(meshes_[i], dirichlet ? "force" : "displacement", 3);
    log->info("interface {} ({}): {} nodes, {} triangles", meshes_[i], dirichlet ? "dirichlet" : "neumann",
              model_.faceNodes(i).size(), triangles.size() / 3);
  }
}

// A window is one load state, so one substep (maxSubstep() 0).
void CoupledLatticeRun::step(const cosim::Window& w, const cosim::Substep&, cosim::WindowIo& io) {
  for (std::size_t i = 0; i < lattice_.faces(); ++i)
    lattice_.setInput(i, io.read(meshes_[i], lattice_.face(i).mode == FaceMode::kDirichlet ? "displacement" : "force"));
  const auto rep = lattice_.advance(fmt::format("window {} iteration {}", w.index, w.iteration),
                                    !w.saveCheckpoint && !w.restoreCheckpoint);
  for (std::size_t i = 0; i < lattice_.faces(); ++i)
    io.write(meshes_[i], lattice_.face(i).mode == FaceMode::kDirichlet ? "force" : "displacement", lattice_.output(i));

  pending_.any = true;
  pending_.window = w.index;
  results_.time = w.time + w.dt;
  pending_.row.clear();
  for (std::size_t i = 0; i < lattice_.faces(); ++i) {
    const Eigen::Vector3d f = lattice_.resultant(i), u = lattice_.meanDisplacement(i);
    pending_.row.insert(pending_.row.end(), {f.x(), f.y(), f.z(), u.x(), u.y(), u.z()});
  }
  results_.strain = results_.stress = 0.0;
  if (nominal_.valid()) {
    const auto lo = static_cast<std::size_t>(nominal_.lo), hi = static_cast<std::size_t>(nominal_.hi);
    results_.strain = (lattice_.meanDisplacement(hi)[axis_] - lattice_.meanDisplacement(lo)[axis_]) / nominal_.height;
    results_.stress = (lattice_.resultant(lo)[axis_] - lattice_.resultant(hi)[axis_]) / (2 * nominal_.area);
  }
  // removed and removed_total are set at the commit.
  pending_.row.insert(pending_.row.end(), {results_.strain, results_.stress, 0.0, 0.0, static_cast<double>(rep.rounds),
                                           static_cast<double>(rep.iterations), static_cast<double>(w.iteration + 1)});
  if (rep.removed.size() > 0)
    common::logger("lattice.coupled")
        ->debug("window {} iteration {}: ε = {:.4g}, σ = {:.4g} Pa, {} rods removed in {} rounds", w.index, w.iteration,
                results_.strain, results_.stress, rep.removed.size(), rep.rounds - 1);
}

void CoupledLatticeRun::commit() {
  if (!pending_.any) return;
  ++committed_;
  results_.windows = committed_;
  if (const std::size_t late = lattice_.commit(static_cast<int>(pending_.window), results_.strain); late > 0) {
    results_.lateRemovals += static_cast<std::int64_t>(late);
    common::logger("lattice.coupled")
        ->info("window {}: {} rods over their limit in the committed state removed at its end", pending_.window, late);
  }
  // Rods removed in this window: in any of its settled iterates, or late.
  const std::size_t removedNow = model_.removedCount() - removedBefore_;
  removedBefore_ = model_.removedCount();
  const std::size_t at = 6 * lattice_.faces();
  pending_.row[at + 2] = static_cast<double>(removedNow);
  pending_.row[at + 3] = static_cast<double>(model_.removedCount());
  out_.h5().append("windows", results_.time, pending_.row);
  if (committed_ == 1 && removedNow == 0 && results_.strain != 0.0) results_.youngsModulus = results_.stress / results_.strain;
  if (results_.stress > results_.peakStress) {
    results_.peakWindow = static_cast<int>(pending_.window);
    results_.peakStress = results_.stress;
    results_.strainAtPeak = results_.strain;
  }
  if (scene_.snapshotEvery > 0 && committed_ % scene_.snapshotEvery == 0)
    out_.snapshot(model_, lattice_.displacement(), lattice_.removedAt(), results_.time);
  else if (committed_ % 16 == 0)
    out_.h5().flush();
  pending_.any = false;
}

std::string CoupledLatticeRun::shape(const Scene& scene) {
  std::string faces;
  for (const auto& f : scene.supports.coupled)
    faces += fmt::format(" {} {}", faceName(f.face), f.mode == FaceMode::kDirichlet ? "dirichlet" : "neumann");
  return fmt::format("{} nodes, {} rods, {} operator, faces{}", scene.specimen.nodes.size(), scene.specimen.rods.size(),
                     scene.op == Operator::kAssembled ? "assembled" : "matrix-free", faces);
}

void CoupledLatticeRun::archive(common::StateArchive& a) {
  if (!a.reading()) common::archiveExtent(a, h5_);  // read first, by common::openResults
  a.shape(shape(scene_));
  model_.archive(a);
  a.io("lattice", lattice_);
  if (a.reading()) solver_->update(model_);  // the solver's history is read into what update() rebuilt
  {
    auto scope = a.scope("solver");
    solver_->archive(a);
  }
  a.io("results", results_), a.io("committed", committed_), a.io("removed_before", removedBefore_);
}

void CoupledLatticeRun::report(common::Summary& summary) {
  auto log = common::logger("lattice.coupled");
  const Specimen& sp = scene_.specimen;
  const Results& r = results_;
  out_.snapshot(model_, lattice_.displacement(), lattice_.removedAt(), r.time);
  std::vector<LatticeOutput::Crack> cracks;
  std::vector<std::uint32_t> removed;
  for (const auto& rm : lattice_.removals()) {
    cracks.push_back({rm.rod, rm.window, rm.nominalStrain, rm.rodStrain});
    removed.push_back(rm.rod);
  }
  out_.cracks(cracks, r.time);
  h5_.flush();

  const auto& eq = lattice_.equilibrium();
  summary.setSteps(r.windows);
  summary.set("coupling_windows", r.windows);
  summary.set("peak_stress", r.peakStress);
  summary.set("strain_at_peak", r.strainAtPeak);
  summary.set("youngs_modulus", r.youngsModulus);
  summary.set("final_strain", r.strain);
  summary.set("final_stress", r.stress);
  reportSpecimen(scene_, model_, removed, axis_, summary);
  // The macro-crack: the rods removed after the peak window, without the diffuse pre-peak microcracking.
  std::vector<std::uint32_t> postPeak;
  for (const auto& rm : lattice_.removals())
    if (rm.window > r.peakWindow) postPeak.push_back(rm.rod);
  const CrackBand band = crackBand(model_, postPeak, axis_, 2 * sp.meanRodLength());
  summary.set("rods_removed_post_peak", static_cast<std::int64_t>(postPeak.size()));
  summary.set("crack_plane_post_peak", band.plane);
  summary.set("crack_band_fraction_post_peak", band.fraction);
  summary.set("solves", static_cast<std::int64_t>(eq.solves()));
  summary.set("solver_iterations", static_cast<std::int64_t>(eq.iterations()));
  summary.set("solve_time_s", eq.solveSeconds());
  summary.set("removal_time_s", eq.removalSeconds());
  summary.set("late_removals", r.lateRemovals);
  for (std::size_t i = 0; i < lattice_.faces(); ++i) {
    const Eigen::Vector3d f = lattice_.resultant(i);
    summary.set("force_" + meshes_[i], std::vector<double>{f.x(), f.y(), f.z()});
  }
  log->info("{} windows; peak stress {:.4g} MPa at strain {:.4g}; E = {:.4g} GPa; {} of {} rods removed; {} solves, {} "
            "iterations",
            r.windows, r.peakStress / 1e6, r.strainAtPeak, r.youngsModulus / 1e9, removed.size(), sp.rods.size(), eq.solves(),
            eq.iterations());
}

}  // namespace lattice
