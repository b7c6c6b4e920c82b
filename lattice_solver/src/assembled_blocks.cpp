#include <algorithm>
#include <numeric>

#include <omp.h>

#include "common/errors.hpp"
#include "stiffness.hpp"

namespace lattice {

Model::AssembledBlocks::AssembledBlocks(const Model& m) {
  // Block pattern: per node block i, the blocks j > i of its rod neighbours (upper triangle; K is
  // symmetric), and for the other direction references to the blocks (j, i), j < i.
  const std::size_t nb = m.blockNode_.size();
  upStart_.assign(nb + 1, 0);
  std::vector<std::vector<std::uint32_t>> up(nb);
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < nb; ++blk) {
    const std::uint32_t n = m.blockNode_[blk];
    for (auto i = m.nodeRodStart_[n]; i < m.nodeRodStart_[n + 1]; ++i) {
      const auto& rod = m.rods_[m.nodeRods_[i]];
      const std::int32_t j = m.blockOf_[rod[0] == n ? rod[1] : rod[0]];
      if (j > static_cast<std::int32_t>(blk)) up[blk].push_back(static_cast<std::uint32_t>(j));
    }
    std::sort(up[blk].begin(), up[blk].end());
    up[blk].erase(std::unique(up[blk].begin(), up[blk].end()), up[blk].end());
  }
  for (std::size_t blk = 0; blk < nb; ++blk) upStart_[blk + 1] = upStart_[blk] + static_cast<std::uint32_t>(up[blk].size());
  upCol_.resize(upStart_.back());
  for (std::size_t blk = 0; blk < nb; ++blk) std::copy(up[blk].begin(), up[blk].end(), upCol_.begin() + upStart_[blk]);
  up = {};
  upper_.assign(upCol_.size(), Block::Zero());
  diag_.assign(nb, Block::Zero());
  loStart_.assign(nb + 1, 0);
  for (auto j : upCol_) ++loStart_[j + 1];
  std::partial_sum(loStart_.begin(), loStart_.end(), loStart_.begin());
  loRef_.resize(upCol_.size());
  loRow_.resize(upCol_.size());
  {
    std::vector<std::uint32_t> fill(loStart_.begin(), loStart_.end() - 1);
    for (std::uint32_t blk = 0; blk < nb; ++blk)
      for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) {
        const auto q = fill[upCol_[p]]++;
        loRef_[q] = p;
        loRow_[q] = blk;
      }
  }

  // Values: each node adds its diagonal block and the upper blocks of its own row, so threads never
  // write the same block.
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t blk = 0; blk < nb; ++blk) {
    const std::uint32_t n = m.blockNode_[blk];
    for (auto i = m.nodeRodStart_[n]; i < m.nodeRodStart_[n + 1]; ++i) {
      const std::uint32_t r = m.nodeRods_[i];
      addRows(m, r, m.rods_[r][0] == n ? 0 : 1, m.rodStiffness(r), 1.0);
    }
  }
}

void Model::AssembledBlocks::addRows(const Model& m, std::size_t r, int side, const Mat12& k, double sign) {
  const std::uint32_t n = m.rods_[r][static_cast<std::size_t>(side)];
  const std::uint32_t o = m.rods_[r][static_cast<std::size_t>(1 - side)];
  if (m.blockOf_[n] < 0) return;  // a node without free dofs has no rows
  // Node n owns its diagonal block and the off-diagonal block when it is the smaller block index; rows
  // and columns of dofs that are not free are never read.
  const auto i = static_cast<std::uint32_t>(m.blockOf_[n]);
  diag_[i] += sign * k.block<6, 6>(6 * side, 6 * side);
  if (m.blockOf_[o] > m.blockOf_[n]) upper_[upperIndex(i, static_cast<std::uint32_t>(m.blockOf_[o]))] += sign * k.block<6, 6>(6 * side, 6 * (1 - side));
}

std::size_t Model::AssembledBlocks::upperIndex(std::uint32_t i, std::uint32_t j) const {
  const auto begin = upCol_.begin() + upStart_[i], end = upCol_.begin() + upStart_[i + 1];
  const auto it = std::lower_bound(begin, end, j);
  COSIM_ASSERT(it != end && *it == j, "K has no block ({}, {})", i, j);
  return static_cast<std::size_t>(it - upCol_.begin());
}

void Model::AssembledBlocks::apply(const Model& m, const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  const std::size_t nb = m.blockNode_.size();
  xPad_.resize(static_cast<Eigen::Index>(6 * nb));
  yPad_.resize(static_cast<Eigen::Index>(6 * nb));
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < nb; ++i) xPad_.segment<6>(static_cast<Eigen::Index>(6 * i)) = m.gather(m.blockNode_[i], x);
  // One pass over the stored (upper) blocks, each used for (i, j) and (j, i): half the memory traffic
  // of a full matrix, and K x is memory bound. With threads, each scatters its rows' products into its
  // own vector (the transposed updates would collide), summed in thread order: deterministic for a
  // given thread count, and still one pass over the matrix (gathering the lower blocks per row instead
  // read it twice and made 2 threads slower than one).
  auto rows = [&](std::size_t begin, std::size_t end, Eigen::VectorXd& out) {
    out.setZero();
    for (std::size_t i = begin; i < end; ++i) {
      const auto xi = xPad_.segment<6>(static_cast<Eigen::Index>(6 * i));
      Vec6 yi = diag_[i] * xi;
      for (auto p = upStart_[i]; p < upStart_[i + 1]; ++p) {
        const auto j = static_cast<Eigen::Index>(6 * upCol_[p]);
        yi.noalias() += upper_[p] * xPad_.segment<6>(j);
        out.segment<6>(j).noalias() += upper_[p].transpose() * xi;
      }
      out.segment<6>(static_cast<Eigen::Index>(6 * i)) += yi;
    }
  };
  detail::sumOverThreads(yPad_, yThread_, [&](std::size_t t, std::size_t team, Eigen::VectorXd& out) {
    // Equal shares of stored blocks, not of rows: the upper rows of a block profile are longer.
    const std::size_t total = upStart_[nb];
    auto rowAt = [&](std::size_t share) {
      const auto last = upStart_.begin() + static_cast<std::ptrdiff_t>(nb);
      return static_cast<std::size_t>(std::lower_bound(upStart_.begin(), last, total * share / team) - upStart_.begin());
    };
    rows(rowAt(t), t + 1 == team ? nb : rowAt(t + 1), out);
  });
  y.resize(x.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < nb; ++i) {
    const std::uint32_t n = m.blockNode_[i];
    int k = static_cast<int>(m.blockStart_[i]);
    for (int c = 0; c < 6; ++c)
      if (m.freeMask_[n] & (1u << c)) y[k++] = yPad_[static_cast<Eigen::Index>(6 * i + static_cast<std::size_t>(c))];
  }
}

Model::Vec6 Model::AssembledBlocks::nodeProduct(const Model& m, std::size_t blk, const Eigen::VectorXd& x) const {
  Vec6 f = diag_[blk] * m.gather(m.blockNode_[blk], x);
  for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) f.noalias() += upper_[p] * m.gather(m.blockNode_[upCol_[p]], x);
  for (auto q = loStart_[blk]; q < loStart_[blk + 1]; ++q)
    f.noalias() += upper_[loRef_[q]].transpose() * m.gather(m.blockNode_[loRow_[q]], x);
  return f;
}

Model::Block Model::AssembledBlocks::nodeDiagonal(const Model&, std::size_t blk) const { return diag_[blk]; }

void Model::AssembledBlocks::remove(const Model& m, std::uint32_t r, const Mat12& k) {
  addRows(m, r, 0, k, -1.0);
  addRows(m, r, 1, k, -1.0);
}

void Model::AssembledBlocks::hold(const Model& m, std::size_t blk) {
  for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) upper_[p].setZero();
  for (auto q = loStart_[blk]; q < loStart_[blk + 1]; ++q) upper_[loRef_[q]].setZero();
  diag_[blk].setZero();
  const std::uint32_t n = m.blockNode_[blk];
  int i = 0;
  for (int k = 0; k < 6; ++k)
    if (m.freeMask_[n] & (1u << k)) {
      diag_[blk](k, k) = m.diagonal_[m.blockStart_[blk] + static_cast<std::uint32_t>(i)];
      ++i;
    }
}

Model::SparseMatrix Model::AssembledBlocks::matrix(const Model& m) const {
  std::vector<Eigen::Triplet<double>> t;
  auto add = [&](std::size_t bi, std::size_t bj, const Block& B) {
    const std::uint32_t ni = m.blockNode_[bi], nj = m.blockNode_[bj];
    for (int a = 0; a < 6; ++a)
      for (int c = 0; c < 6; ++c) {
        const std::int32_t row = m.dofMap_[6 * ni + static_cast<std::size_t>(a)], col = m.dofMap_[6 * nj + static_cast<std::size_t>(c)];
        if (row >= 0 && col >= 0 && B(a, c) != 0.0) t.emplace_back(row, col, B(a, c));
      }
  };
  for (std::size_t bi = 0; bi < m.blockNode_.size(); ++bi) {
    add(bi, bi, diag_[bi]);
    for (auto p = upStart_[bi]; p < upStart_[bi + 1]; ++p) {
      add(bi, upCol_[p], upper_[p]);
      add(upCol_[p], bi, upper_[p].transpose());
    }
  }
  SparseMatrix K(static_cast<Eigen::Index>(m.freeDofs()), static_cast<Eigen::Index>(m.freeDofs()));
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

std::vector<Model::Block> Model::AssembledBlocks::values() const {
  std::vector<Block> v;
  v.reserve(diag_.size() + upper_.size());
  v.insert(v.end(), diag_.begin(), diag_.end());
  v.insert(v.end(), upper_.begin(), upper_.end());
  return v;
}

void Model::AssembledBlocks::restore(const Model&, const std::vector<Block>& values, const std::vector<std::int32_t>&) {
  COSIM_ASSERT(values.size() == diag_.size() + upper_.size(), "{} stored blocks for {} + {}", values.size(), diag_.size(),
               upper_.size());
  const auto split = values.begin() + static_cast<std::ptrdiff_t>(diag_.size());
  std::copy(values.begin(), split, diag_.begin());
  std::copy(split, values.end(), upper_.begin());
}

}  // namespace lattice
