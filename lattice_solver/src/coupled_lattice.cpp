#include "lattice/coupled_lattice.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace lattice {

CoupledLattice::CoupledLattice(Model& model, EquilibriumSolver& solver, RemovalStrategy removal, int maxRounds,
                               CoupledRemoval when, double settleTolerance)
    : model_(model), solver_(solver), brittle_(model, solver, removal, maxRounds), strategy_(removal), when_(when),
      settleTolerance_(settleTolerance) {
  x_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.freeDofs()));
  prescribed_.assign(6 * model.nodes(), 0.0);
  force_.assign(6 * model.nodes(), 0.0);
  model_.fullDisplacement(x_, prescribed_, u_);
  removedAt_.assign(model.rods(), -1);
  solver_.update(model_);
  save();
}

void CoupledLattice::setInput(std::size_t face, std::span<const double> values) {
  const auto& nodes = model_.faceNodes(face);
  if (values.size() != 3 * nodes.size())
    throw std::invalid_argument(fmt::format("face {}: {} values for {} nodes (3 per node expected)", face, values.size(), nodes.size()));
  auto& target = this->face(face).mode == FaceMode::kDirichlet ? prescribed_ : force_;
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
  bool remove = final || when_ == CoupledRemoval::kIterate;
  if (!remove && !lastInput_.empty()) {
    // Settled: the last step of the input is small against its change over the window.
    double step = 0.0, change = 0.0;
    for (std::size_t i = 0; i < input.size(); ++i) {
      step += (input[i] - lastInput_[i]) * (input[i] - lastInput_[i]);
      change += (input[i] - windowStart_[i]) * (input[i] - windowStart_[i]);
    }
    remove = std::sqrt(step) <= settleTolerance_ * std::sqrt(change);
  }
  lastInput_ = std::move(input);
  auto rep = brittle_.run([&] { return model_.rhs(prescribed_, force_); },
                          [&](const Eigen::VectorXd& x, std::vector<double>& u) { model_.fullDisplacement(x, prescribed_, u); },
                          x_, u_, where, {}, remove);
  pending_.insert(pending_.end(), rep.removed.begin(), rep.removed.end());
  return rep;
}

std::vector<double> CoupledLattice::output(std::size_t face) const {
  std::vector<double> out;
  const bool dirichlet = this->face(face).mode == FaceMode::kDirichlet;
  for (auto n : model_.faceNodes(face)) {
    if (dirichlet) {
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
  if (this->face(face).mode == FaceMode::kNeumann) {
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

void CoupledLattice::save() {
  if (when_ == CoupledRemoval::kIterate) saved_ = model_.checkpoint();
}

void CoupledLattice::restore() {
  if (when_ != CoupledRemoval::kIterate) return;  // settled mode removes only what it keeps
  const std::size_t before = model_.restores();
  model_.restore(saved_);
  if (model_.restores() != before) solver_.update(model_);
  pending_.clear();
}

std::size_t CoupledLattice::commit(int window, double nominalStrain) {
  std::size_t late = 0;
  if (when_ == CoupledRemoval::kSettled) {
    std::vector<std::uint32_t> over;
    std::vector<double> ratio;
    brittle_.overLimit(u_, over, ratio);
    if (!over.empty() && strategy_ == RemovalStrategy::kOne) {
      const auto it = std::max_element(ratio.begin(), ratio.end());
      over.assign(1, over[static_cast<std::size_t>(it - ratio.begin())]);
    }
    for (auto r : over) pending_.push_back({r, model_.rodStrain(r, u_)});
    if (!over.empty()) {
      model_.removeRods(over, x_);
      solver_.update(model_);
    }
    late = over.size();
  }
  for (const auto& p : pending_) {
    removals_.push_back({p.rod, window, nominalStrain, p.strain});
    removedAt_[p.rod] = window;
  }
  pending_.clear();
  windowStart_ = lastInput_;
  lastInput_.clear();
  return late;
}

void CoupledLattice::archive(common::StateArchive& a) {
  a.io("equilibrium", brittle_), a.io("state", x_), a.io("prescribed", prescribed_), a.io("force", force_), a.io("u", u_);
  a.io("window_start", windowStart_), a.io("last_input", lastInput_), a.io("pending", pending_), a.io("removals", removals_);
  a.io("removed_at", removedAt_);
  const std::size_t dofs = 6 * model_.nodes();
  if (a.reading() && (static_cast<std::size_t>(x_.size()) != model_.freeDofs() || prescribed_.size() != dofs ||
                      force_.size() != dofs || u_.size() != dofs || removedAt_.size() != model_.rods()))
    throw common::ConfigError(fmt::format("{}: the coupled lattice's state does not fit this model ({})", a.path().string(),
                                          model_.shape()));
}

CrackBand crackBand(const Model& model, std::span<const std::uint32_t> removed, int axis, double halfWidth) {
  CrackBand band;
  if (removed.empty()) return band;
  std::vector<double> pos;
  pos.reserve(removed.size());
  const auto& nodes = model.referenceNodes();
  for (auto r : removed) pos.push_back(0.5 * (nodes[model.rod(r)[0]][axis] + nodes[model.rod(r)[1]][axis]));
  std::sort(pos.begin(), pos.end());
  // Sliding window of width 2 halfWidth over the sorted midpoints: the densest one.
  std::size_t best = 0, lo = 0;
  for (std::size_t hi = 0; hi < pos.size(); ++hi) {
    while (pos[hi] - pos[lo] > 2 * halfWidth) ++lo;
    if (hi - lo + 1 > best) {
      best = hi - lo + 1;
      band.plane = 0.5 * (pos[lo] + pos[hi]);
    }
  }
  band.fraction = static_cast<double>(best) / static_cast<double>(pos.size());
  return band;
}

}  // namespace lattice
