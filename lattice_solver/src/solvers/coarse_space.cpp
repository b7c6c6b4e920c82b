#include "coarse_space.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace lattice {

void CoarseSpace::build(const Model& model, double cellSize) {
  const Box& box = model.box();
  std::array<long, 3> dims{};
  for (int k = 0; k < 3; ++k) dims[k] = std::max(1L, static_cast<long>(std::ceil(box.size[k] / cellSize - 1e-9)));
  const auto& nodes = model.blockNodes();
  const auto& X = model.referenceNodes();
  std::vector<long> cell(nodes.size());
  for (std::size_t b = 0; b < nodes.size(); ++b) {
    long c = 0;
    for (int k = 2; k >= 0; --k) {
      const long i = std::clamp(static_cast<long>((X[nodes[b]][k] - box.origin[k]) / cellSize), 0L, dims[k] - 1);
      c = c * dims[k] + i;
    }
    cell[b] = c;
  }
  // Only cells that hold nodes; rotations about each cell's centroid keep P well scaled.
  std::vector<long> id(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]), -1);
  std::vector<Vec3> centroid;
  std::vector<int> count;
  for (std::size_t b = 0; b < nodes.size(); ++b) {
    long& c = id[static_cast<std::size_t>(cell[b])];
    if (c < 0) {
      c = static_cast<long>(centroid.size());
      centroid.push_back(Vec3::Zero());
      count.push_back(0);
    }
    centroid[static_cast<std::size_t>(c)] += X[nodes[b]];
    ++count[static_cast<std::size_t>(c)];
  }
  for (std::size_t c = 0; c < centroid.size(); ++c) centroid[c] /= count[c];
  std::vector<Eigen::Triplet<double>> t;
  const auto& dof = model.dofMap();
  for (std::size_t b = 0; b < nodes.size(); ++b) {
    const std::uint32_t n = nodes[b];
    const long c = id[static_cast<std::size_t>(cell[b])];
    const Vec3 d = X[n] - centroid[static_cast<std::size_t>(c)];
    for (int k = 0; k < 6; ++k) {
      const std::int32_t i = dof[6 * n + static_cast<std::size_t>(k)];
      if (i < 0) continue;
      if (k < 3) {
        t.emplace_back(i, 6 * c + k, 1.0);
        for (int m = 0; m < 3; ++m) {
          const double v = Vec3::Unit(m).cross(d)[k];  // u = ω × d
          if (v != 0.0) t.emplace_back(i, 6 * c + 3 + m, v);
        }
      } else {
        t.emplace_back(i, 6 * c + k, 1.0);  // θ = ω
      }
    }
  }
  rows_.resize(nodes.size());
  for (std::size_t b = 0; b < nodes.size(); ++b) {
    const std::uint32_t n = nodes[b];
    const Vec3 d = X[n] - centroid[static_cast<std::size_t>(id[static_cast<std::size_t>(cell[b])])];
    BlockRows& row = rows_[b];
    row.cell = static_cast<std::int32_t>(id[static_cast<std::size_t>(cell[b])]);
    for (int k = 0; k < 3; ++k) row.d[k] = static_cast<float>(d[k]);
    row.first = model.paddedBase(n);
    row.mask = 0;
    for (int k = 0; k < 6; ++k)
      if (dof[6 * n + static_cast<std::size_t>(k)] >= 0) row.mask = static_cast<std::uint8_t>(row.mask | (1u << k));
  }
  P_.resize(static_cast<Eigen::Index>(model.freeDofs()), static_cast<Eigen::Index>(6 * centroid.size()));
  P_.setFromTriplets(t.begin(), t.end());
  assemble(model);
}

void CoarseSpace::assemble(const Model& model) {
  // Held nodes leave the coarse space, so the correction never moves them (their rows of K are
  // diagonal and decoupled: block Jacobi alone keeps them exactly where they are held).
  if (model.heldNodes() > 0) {
    std::vector<std::uint8_t> heldRow(static_cast<std::size_t>(P_.rows()), 0);
    const auto& dof = model.dofMap();
    for (std::size_t n = 0; n < model.nodes(); ++n)
      if (model.held(n))
        for (int k = 0; k < 6; ++k)
          if (dof[6 * n + static_cast<std::size_t>(k)] >= 0) heldRow[static_cast<std::size_t>(dof[6 * n + static_cast<std::size_t>(k)])] = 1;
    P_.prune([&](Eigen::Index row, Eigen::Index, double) { return !heldRow[static_cast<std::size_t>(row)]; });
    const auto& nodes = model.blockNodes();
    for (std::size_t b = 0; b < nodes.size(); ++b)
      if (model.held(nodes[b])) rows_[b].cell = -1;
  }
  // A_c = Σ_rods P_rᵀ K_rod P_r over the active rods (held nodes have no rows in P any more), summed
  // per pair of cells; no assembled K needed.
  std::unordered_map<std::uint64_t, Eigen::Matrix<double, 6, 6>> pairs;
  const auto nc = static_cast<std::uint64_t>(P_.cols() / 6);
  for (std::size_t r = 0; r < model.rods(); ++r) {
    if (!model.active(r)) continue;
    std::vector<Eigen::Index> cols;
    const Eigen::MatrixXd dA = rodCoarse(model, r, cols);
    for (std::size_t a = 0; a < cols.size(); a += 6)
      for (std::size_t b = 0; b < cols.size(); b += 6) {
        const auto key = static_cast<std::uint64_t>(cols[a] / 6) * nc + static_cast<std::uint64_t>(cols[b] / 6);
        auto [it, fresh] = pairs.try_emplace(key, Eigen::Matrix<double, 6, 6>::Zero());
        it->second += dA.block<6, 6>(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      }
  }
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(36 * pairs.size());
  for (const auto& [key, m] : pairs)
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        t.emplace_back(static_cast<Eigen::Index>(key / nc) * 6 + i, static_cast<Eigen::Index>(key % nc) * 6 + j, m(i, j));
  Ac_.resize(P_.cols(), P_.cols());
  Ac_.setFromTriplets(t.begin(), t.end());
  // A cell can hold too few nodes to resist all six motions (a truss cell with one node cannot
  // rotate anything): a shift of 1e-10 of the mean diagonal keeps A_c definite at no visible cost.
  const double shift = 1e-10 * Ac_.diagonal().cwiseAbs().mean();
  for (Eigen::Index i = 0; i < Ac_.rows(); ++i) Ac_.coeffRef(i, i) += shift;
  Ac_.makeCompressed();
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(nc));
  for (const auto& entry : pairs)
    if (entry.first / nc != entry.first % nc) neighbours[entry.first / nc].push_back(static_cast<int>(entry.first % nc));
  factor_.analyze(neighbours);
  if (!factor_.factorize(Ac_))
    throw common::SimulationError(fmt::format("the coarse stiffness ({} dofs) could not be factorised", Ac_.rows()));
  removalsSeen_ = model.removalLog().size();
  heldSeen_ = model.heldNodes();
  pending_ = 0;
}

void CoarseSpace::update(const Model& model) {
  const auto& log = model.removalLog();
  if (model.heldNodes() != heldSeen_) {
    assemble(model);
    return;
  }
  if (log.size() == removalsSeen_) return;
  for (std::size_t i = removalsSeen_; i < log.size(); ++i) {
    const std::uint32_t r = log[i];
    std::vector<Eigen::Index> cols;
    const Eigen::MatrixXd dA = rodCoarse(model, r, cols);
    for (Eigen::Index a = 0; a < dA.rows(); ++a)
      for (Eigen::Index b = 0; b < dA.cols(); ++b) Ac_.coeffRef(cols[static_cast<std::size_t>(a)], cols[static_cast<std::size_t>(b)]) -= dA(a, b);
  }
  pending_ += log.size() - removalsSeen_;
  removalsSeen_ = log.size();
  // A_c is kept exact, but refactorised only every so many removals: a slightly stale A_c is still
  // symmetric positive definite, so it remains a valid preconditioner, and the factorisation is the
  // expensive part (it dominated the `one` strategy, one rod per round).
  if (pending_ < std::max<std::size_t>(20, model.rods() / 1000)) return;
  pending_ = 0;
  if (!factor_.factorize(Ac_))
    throw common::SimulationError(fmt::format("the coarse stiffness ({} dofs) could not be refactorised", Ac_.rows()));
}

Eigen::MatrixXd CoarseSpace::rodCoarse(const Model& model, std::size_t r, std::vector<Eigen::Index>& cols) const {
  const auto& dof = model.dofMap();
  const Mat12 k = model.rodStiffness(r);
  // The rod's rows of P as a dense 12 × m block over the coarse columns they touch: whole cells, so
  // the result splits into 6 × 6 cell blocks.
  std::array<std::int32_t, 12> rows{};
  cols.clear();
  for (int q = 0; q < 2; ++q)
    for (int c = 0; c < 6; ++c) {
      const std::int32_t f = dof[6 * model.rod(r)[static_cast<std::size_t>(q)] + static_cast<std::size_t>(c)];
      rows[static_cast<std::size_t>(6 * q + c)] = f;
      if (f >= 0)
        for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(P_, f); it; ++it)
          for (Eigen::Index j = 0; j < 6; ++j) cols.push_back(it.col() / 6 * 6 + j);
    }
  std::sort(cols.begin(), cols.end());
  cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
  Eigen::MatrixXd Pr = Eigen::MatrixXd::Zero(12, static_cast<Eigen::Index>(cols.size()));
  for (int j = 0; j < 12; ++j) {
    if (rows[static_cast<std::size_t>(j)] < 0) continue;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(P_, rows[static_cast<std::size_t>(j)]); it; ++it)
      Pr(j, std::lower_bound(cols.begin(), cols.end(), it.col()) - cols.begin()) = it.value();
  }
  return Pr.transpose() * k * Pr;
}

void CoarseSpace::addCorrection(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  Eigen::VectorXd yc = P_.transpose() * r;
  factor_.solve(yc);
  z.noalias() += P_ * yc;
}

void CoarseSpace::solve(Eigen::VectorXd& rc) const {
  // On the factor rounded to float: it is read beside block Jacobi, both from memory, and A_c⁻¹ is only
  // a preconditioner here.
  factor_.solveSingle(rc);
}

void CoarseSpace::direction(const Eigen::VectorXd& yc, const Eigen::VectorXf& z, float beta, Eigen::VectorXf& p) const {
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < rows_.size(); ++b) {
    const BlockRows& row = rows_[b];
    float* pn = p.data() + row.first;
    const float* zn = z.data() + row.first;
    if (row.cell < 0) {
      for (int k = 0; k < 6; ++k) pn[k] = zn[k] + beta * pn[k];
      continue;
    }
    const double* c = yc.data() + 6 * row.cell;
    // u = t + ω × d, θ = ω, at the free dofs only (the others stay 0).
    float u[6] = {static_cast<float>(c[0] + (c[4] * row.d[2] - c[5] * row.d[1])),
                  static_cast<float>(c[1] + (c[5] * row.d[0] - c[3] * row.d[2])),
                  static_cast<float>(c[2] + (c[3] * row.d[1] - c[4] * row.d[0])),
                  static_cast<float>(c[3]),
                  static_cast<float>(c[4]),
                  static_cast<float>(c[5])};
    if (row.mask != 0x3f)
      for (int k = 0; k < 6; ++k)
        if (!(row.mask & (1u << k))) u[k] = 0.0f;
    for (int k = 0; k < 6; ++k) pn[k] = zn[k] + beta * pn[k] + u[k];
  }
}

void CoarseSpace::archive(common::StateArchive& a) {
  Ac_.makeCompressed();
  std::int64_t n = Ac_.rows();
  std::vector<int> outer(Ac_.outerIndexPtr(), Ac_.outerIndexPtr() + Ac_.outerSize() + 1);
  std::vector<int> inner(Ac_.innerIndexPtr(), Ac_.innerIndexPtr() + Ac_.nonZeros());
  std::vector<double> values(Ac_.valuePtr(), Ac_.valuePtr() + Ac_.nonZeros());
  a.io("size", n), a.io("outer", outer), a.io("inner", inner), a.io("values", values);
  a.io("factor", factor_), a.io("removals_seen", removalsSeen_), a.io("held_seen", heldSeen_), a.io("pending", pending_);
  if (!a.reading()) return;
  if (n != Ac_.rows() || outer.size() != static_cast<std::size_t>(n) + 1 || inner.size() != values.size() ||
      static_cast<std::size_t>(outer.back()) != values.size())
    throw common::ConfigError(fmt::format("{}: a coarse space of {} dofs where this model has {}", a.path().string(), n, Ac_.rows()));
  Ac_ = Eigen::Map<const Eigen::SparseMatrix<double>>(n, n, static_cast<Eigen::Index>(values.size()), outer.data(), inner.data(),
                                                      values.data());
}

}  // namespace lattice
