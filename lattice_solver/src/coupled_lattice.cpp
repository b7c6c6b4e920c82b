#include "lattice/coupled_lattice.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"

namespace lattice {

CoupledLattice::CoupledLattice(const Scene& scene, common::H5Writer& h5)
    : scene_(scene),
      h5_(h5),
      model_(buildModel(scene, true)),
      solver_(scene.solver.build()),
      brittle_(model_, *solver_, scene.loading.removal, scene.loading.maxRounds),
      out_(h5, scene.specimen),
      axis_(scene.supports.axis) {
  x_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model_.freeDofs()));
  prescribed_.assign(6 * model_.nodes(), 0.0);
  force_.assign(6 * model_.nodes(), 0.0);
  model_.fullDisplacement(x_, prescribed_, u_);
  removedAt_.assign(model_.rods(), -1);
  solver_->update(model_);
  save();
  const Specimen& sp = scene.specimen;
  for (std::size_t i = 0; i < faces(); ++i) {
    const Face& f = face(i).face;
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

void CoupledLattice::declare(cosim::InterfaceDeclaration& io) {
  auto log = common::logger("lattice.coupled");
  const Specimen& sp = scene_.specimen;
  for (std::size_t i = 0; i < faces(); ++i) {
    const Face& f = face(i).face;
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
    io.addRead(meshes_[i], dirichlet(i) ? "displacement" : "force", 3);
    io.addWrite(meshes_[i], dirichlet(i) ? "force" : "displacement", 3);
    log->info("interface {} ({}): {} nodes, {} triangles", meshes_[i], dirichlet(i) ? "dirichlet" : "neumann",
              model_.faceNodes(i).size(), triangles.size() / 3);
  }
}

void CoupledLattice::save() {
  if (scene_.coupledRemoval == CoupledRemoval::kIterate) saved_ = model_.checkpoint();
}

void CoupledLattice::restore() {
  if (scene_.coupledRemoval != CoupledRemoval::kIterate) return;  // settled mode removes only what it keeps
  const std::size_t before = model_.restores();
  model_.restore(saved_);
  if (model_.restores() != before) solver_->update(model_);
  removedInWindow_.clear();
}

// A window is one load state, so one substep (maxSubstep() 0).
void CoupledLattice::step(const cosim::Window& w, const cosim::Substep&, cosim::WindowIo& io) {
  for (std::size_t i = 0; i < faces(); ++i) setInput(i, io.read(meshes_[i], dirichlet(i) ? "displacement" : "force"));
  const auto rep = advance(fmt::format("window {} iteration {}", w.index, w.iteration),
                           !w.saveCheckpoint && !w.restoreCheckpoint);
  for (std::size_t i = 0; i < faces(); ++i) io.write(meshes_[i], dirichlet(i) ? "force" : "displacement", output(i));

  pending_.any = true;
  pending_.window = w.index;
  results_.time = w.time + w.dt;
  pending_.faces.clear();
  for (std::size_t i = 0; i < faces(); ++i) {
    const Eigen::Vector3d f = resultant(i), u = meanDisplacement(i);
    pending_.faces.insert(pending_.faces.end(), {f.x(), f.y(), f.z(), u.x(), u.y(), u.z()});
  }
  results_.strain = results_.stress = 0.0;
  if (nominal_.valid()) {
    const auto lo = static_cast<std::size_t>(nominal_.lo), hi = static_cast<std::size_t>(nominal_.hi);
    results_.strain = (meanDisplacement(hi)[axis_] - meanDisplacement(lo)[axis_]) / nominal_.height;
    results_.stress = (resultant(lo)[axis_] - resultant(hi)[axis_]) / (2 * nominal_.area);
  }
  pending_.rounds = rep.rounds;
  pending_.iterations = static_cast<double>(rep.iterations);
  pending_.couplingIterations = w.iteration + 1;
  if (rep.removed.size() > 0)
    common::logger("lattice.coupled")
        ->debug("window {} iteration {}: ε = {:.4g}, σ = {:.4g} Pa, {} rods removed in {} rounds", w.index, w.iteration,
                results_.strain, results_.stress, rep.removed.size(), rep.rounds - 1);
}

void CoupledLattice::commit() {
  if (!pending_.any) return;
  ++committed_;
  results_.windows = committed_;
  const int window = static_cast<int>(pending_.window);
  if (const std::size_t late = removeLate(); late > 0) {
    results_.lateRemovals += static_cast<std::int64_t>(late);
    common::logger("lattice.coupled")->info("window {}: {} rods over their limit in the committed state removed at its end",
                                            window, late);
  }
  for (const auto& p : removedInWindow_) {
    removals_.push_back({p.rod, window, results_.strain, p.strain});
    removedAt_[p.rod] = window;
  }
  removedInWindow_.clear();
  windowStart_ = lastInput_;
  lastInput_.clear();
  // Rods removed in this window: in any of its settled iterates, or late.
  const std::size_t removedNow = model_.removedCount() - removedBefore_;
  removedBefore_ = model_.removedCount();
  std::vector<double> row = pending_.faces;
  row.insert(row.end(), {results_.strain, results_.stress, static_cast<double>(removedNow),
                         static_cast<double>(model_.removedCount()), pending_.rounds, pending_.iterations,
                         pending_.couplingIterations});
  out_.h5().append("windows", results_.time, row);
  if (committed_ == 1 && removedNow == 0 && results_.strain != 0.0) results_.youngsModulus = results_.stress / results_.strain;
  if (results_.stress > results_.peakStress) {
    results_.peakWindow = window;
    results_.peakStress = results_.stress;
    results_.strainAtPeak = results_.strain;
  }
  if (scene_.snapshotEvery > 0 && committed_ % scene_.snapshotEvery == 0)
    out_.snapshot(model_, u_, removedAt_, results_.time);
  else if (committed_ % 16 == 0)
    out_.h5().flush();
  pending_.any = false;
}

std::size_t CoupledLattice::removeLate() {
  if (scene_.coupledRemoval != CoupledRemoval::kSettled) return 0;
  std::vector<std::uint32_t> over;
  std::vector<double> ratio;
  brittle_.overLimit(u_, over, ratio);
  if (!over.empty() && scene_.loading.removal == RemovalStrategy::kOne) {
    const auto it = std::max_element(ratio.begin(), ratio.end());
    over.assign(1, over[static_cast<std::size_t>(it - ratio.begin())]);
  }
  for (auto r : over) removedInWindow_.push_back({r, model_.rodStrain(r, u_)});
  if (!over.empty()) {
    model_.removeRods(over, x_);
    solver_->update(model_);
  }
  return over.size();
}

void CoupledLattice::setInput(std::size_t face, std::span<const double> values) {
  const auto& nodes = model_.faceNodes(face);
  if (values.size() != 3 * nodes.size())
    throw std::invalid_argument(fmt::format("face {}: {} values for {} nodes (3 per node expected)", face, values.size(), nodes.size()));
  auto& target = dirichlet(face) ? prescribed_ : force_;
  for (std::size_t i = 0; i < nodes.size(); ++i)
    for (std::size_t k = 0; k < 3; ++k) {
      if (!std::isfinite(values[3 * i + k]))
        throw std::invalid_argument(fmt::format("face {}: value {} of node {} is not finite", face, k, nodes[i]));
      target[6 * nodes[i] + k] = values[3 * i + k];
    }
}

BrittleEquilibrium::Report CoupledLattice::advance(const std::string& where, bool final) {
  std::vector<double> input(prescribed_);
  input.insert(input.end(), force_.begin(), force_.end());
  if (windowStart_.empty()) windowStart_ = input;  // the first window starts from rest
  bool remove = final || scene_.coupledRemoval == CoupledRemoval::kIterate;
  if (!remove && !lastInput_.empty()) {
    // Settled: the last step of the input is small against its change over the window.
    double step = 0.0, change = 0.0;
    for (std::size_t i = 0; i < input.size(); ++i) {
      step += (input[i] - lastInput_[i]) * (input[i] - lastInput_[i]);
      change += (input[i] - windowStart_[i]) * (input[i] - windowStart_[i]);
    }
    remove = std::sqrt(step) <= scene_.settleTolerance * std::sqrt(change);
  }
  lastInput_ = std::move(input);
  auto rep = brittle_.run([&] { return model_.rhs(prescribed_, force_); },
                          [&](const Eigen::VectorXd& x, std::vector<double>& u) { model_.fullDisplacement(x, prescribed_, u); },
                          x_, u_, where, {}, remove);
  removedInWindow_.insert(removedInWindow_.end(), rep.removed.begin(), rep.removed.end());
  return rep;
}

std::vector<double> CoupledLattice::output(std::size_t face) const {
  std::vector<double> out;
  for (auto n : model_.faceNodes(face)) {
    if (dirichlet(face)) {
      const Model::Vec6 f = -model_.nodeForce(n, u_);
      out.insert(out.end(), {f[0], f[1], f[2]});
    } else {
      out.insert(out.end(), {u_[6 * n], u_[6 * n + 1], u_[6 * n + 2]});
    }
  }
  return out;
}

Eigen::Vector3d CoupledLattice::resultant(std::size_t face) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  if (!dirichlet(face)) {
    for (auto n : model_.faceNodes(face)) sum += Eigen::Vector3d(force_[6 * n], force_[6 * n + 1], force_[6 * n + 2]);
    return -sum;  // what the lattice exerts on the other side: minus what it receives
  }
  for (auto n : model_.faceNodes(face)) sum -= model_.nodeForce(n, u_).head<3>();
  return sum;
}

Eigen::Vector3d CoupledLattice::meanDisplacement(std::size_t face) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const auto& nodes = model_.faceNodes(face);
  for (auto n : nodes) sum += Eigen::Vector3d(u_[6 * n], u_[6 * n + 1], u_[6 * n + 2]);
  return sum / static_cast<double>(nodes.size());
}

std::string CoupledLattice::shape(const Scene& scene) {
  std::string faces;
  for (const auto& f : scene.supports.coupled)
    faces += fmt::format(" {} {}", faceName(f.face), f.mode == FaceMode::kDirichlet ? "dirichlet" : "neumann");
  return fmt::format("{} nodes, {} rods, {} operator, faces{}", scene.specimen.nodes.size(), scene.specimen.rods.size(),
                     scene.op == Operator::kAssembled ? "assembled" : "matrix-free", faces);
}

void CoupledLattice::archiveRemovals(common::StateArchive& a) {
  a.io("equilibrium", brittle_), a.io("state", x_), a.io("prescribed", prescribed_), a.io("force", force_), a.io("u", u_);
  a.io("window_start", windowStart_), a.io("last_input", lastInput_), a.io("pending", removedInWindow_);
  a.io("removals", removals_), a.io("removed_at", removedAt_);
  const std::size_t dofs = 6 * model_.nodes();
  if (a.reading() && (static_cast<std::size_t>(x_.size()) != model_.freeDofs() || prescribed_.size() != dofs ||
                      force_.size() != dofs || u_.size() != dofs || removedAt_.size() != model_.rods()))
    throw common::ConfigError(fmt::format("{}: the coupled lattice's state does not fit this model ({})", a.path().string(),
                                          model_.shape()));
}

void CoupledLattice::archive(common::StateArchive& a) {
  if (!a.reading()) common::archiveExtent(a, h5_);  // read first, by common::openResults
  a.shape(shape(scene_));
  model_.archive(a);
  {
    auto scope = a.scope("lattice");
    archiveRemovals(a);
  }
  if (a.reading()) solver_->update(model_);  // the solver's history is read into what update() rebuilt
  {
    auto scope = a.scope("solver");
    solver_->archive(a);
  }
  a.io("results", results_), a.io("committed", committed_), a.io("removed_before", removedBefore_);
}

void CoupledLattice::report(common::Summary& summary) {
  auto log = common::logger("lattice.coupled");
  const Specimen& sp = scene_.specimen;
  const Results& r = results_;
  out_.snapshot(model_, u_, removedAt_, r.time);
  std::vector<LatticeOutput::Crack> cracks;
  std::vector<std::uint32_t> removed;
  for (const auto& rm : removals_) {
    cracks.push_back({rm.rod, rm.window, rm.nominalStrain, rm.rodStrain});
    removed.push_back(rm.rod);
  }
  out_.cracks(cracks, r.time);
  h5_.flush();

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
  for (const auto& rm : removals_)
    if (rm.window > r.peakWindow) postPeak.push_back(rm.rod);
  const CrackBand band = crackBand(model_, postPeak, axis_, 2 * sp.meanRodLength());
  summary.set("rods_removed_post_peak", static_cast<std::int64_t>(postPeak.size()));
  summary.set("crack_plane_post_peak", band.plane);
  summary.set("crack_band_fraction_post_peak", band.fraction);
  summary.set("solves", static_cast<std::int64_t>(brittle_.solves()));
  summary.set("solver_iterations", static_cast<std::int64_t>(brittle_.iterations()));
  summary.set("solve_time_s", brittle_.solveSeconds());
  summary.set("removal_time_s", brittle_.removalSeconds());
  summary.set("late_removals", r.lateRemovals);
  for (std::size_t i = 0; i < faces(); ++i) {
    const Eigen::Vector3d f = resultant(i);
    summary.set("force_" + meshes_[i], std::vector<double>{f.x(), f.y(), f.z()});
  }
  log->info("{} windows; peak stress {:.4g} MPa at strain {:.4g}; E = {:.4g} GPa; {} of {} rods removed; {} solves, {} "
            "iterations",
            r.windows, r.peakStress / 1e6, r.strainAtPeak, r.youngsModulus / 1e9, removed.size(), sp.rods.size(),
            brittle_.solves(), brittle_.iterations());
}

}  // namespace lattice
