#include <array>

#include <Eigen/Cholesky>

#include "common/errors.hpp"
#include "lattice/solver.hpp"

namespace lattice {

void NodeBlocks::invert(const Model& model, std::size_t b) {
  const auto& start = model.blockStart();
  const int m = static_cast<int>(start[b + 1] - start[b]);
  const Model::Block D = model.diagonalBlock(b);
  inverse_[b].setZero();
  // A node block is symmetric positive definite while the node has rods; LDLT also copes with the
  // semi-definite blocks round-off can leave.
  inverse_[b].topLeftCorner(m, m) = D.topLeftCorner(m, m).ldlt().solve(Eigen::MatrixXd::Identity(m, m));
  if (!single_) return;
  const std::uint32_t n = model.blockNodes()[b];
  std::array<int, 6> dof{};  // the node's dof of each of the block's rows
  int i = 0;
  for (int k = 0; k < 6; ++k)
    if (model.dofMap()[6 * n + static_cast<std::size_t>(k)] >= 0) dof[static_cast<std::size_t>(i++)] = k;
  inverseSingle_[b].setZero();
  for (int r = 0; r < m; ++r)
    for (int c = 0; c < m; ++c)
      inverseSingle_[b](dof[static_cast<std::size_t>(r)], dof[static_cast<std::size_t>(c)]) = static_cast<float>(inverse_[b](r, c));
}

void NodeBlocks::update(const Model& model) {
  start_ = &model.blockStart();
  const std::size_t blocks = start_->size() - 1;
  const auto& log = model.removalLog();
  if (inverse_.size() != blocks || model.heldNodes() != heldSeen_ || model.restores() != restoresSeen_) {
    inverse_.resize(blocks);
    if (single_) {
      inverseSingle_.resize(blocks);
      base_.resize(blocks);
      for (std::size_t b = 0; b < blocks; ++b) base_[b] = model.paddedBase(model.blockNodes()[b]);
    }
#pragma omp parallel for schedule(static)
    for (std::size_t b = 0; b < blocks; ++b) invert(model, b);
  } else {
    for (std::size_t i = removalsSeen_; i < log.size(); ++i)
      for (auto n : model.rod(log[i]))
        if (model.blockOf(n) >= 0) invert(model, static_cast<std::size_t>(model.blockOf(n)));
  }
  removalsSeen_ = log.size();
  heldSeen_ = model.heldNodes();
  restoresSeen_ = model.restores();
}

void NodeBlocks::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  COSIM_ASSERT(start_ != nullptr, "NodeBlocks used before update()");
  z.resize(r.size());
  const std::size_t n = blocks();
  const auto& s = *start_;
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < n; ++b) {
    const int first = static_cast<int>(s[b]);
    const int m = static_cast<int>(s[b + 1]) - first;
    if (m == 6) z.segment<6>(first) = inverse_[b] * r.segment<6>(first);
    else z.segment(first, m) = inverse_[b].topLeftCorner(m, m) * r.segment(first, m);
  }
}

}  // namespace lattice
