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
  if (single_) inverseSingle_[b] = inverse_[b].cast<float>();
}

void NodeBlocks::update(const Model& model) {
  start_ = &model.blockStart();
  const std::size_t blocks = start_->size() - 1;
  const auto& log = model.removalLog();
  if (inverse_.size() != blocks || model.heldNodes() != heldSeen_ || model.restores() != restoresSeen_) {
    inverse_.resize(blocks);
    if (single_) inverseSingle_.resize(blocks);
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

template <typename Scalar>
void NodeBlocks::apply(const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& r, Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& z) const {
  COSIM_ASSERT(start_ != nullptr, "NodeBlocks used before update()");
  if constexpr (std::is_same_v<Scalar, float>) COSIM_ASSERT(single_, "NodeBlocks used in single precision before keepSingle()");
  z.resize(r.size());
  const std::size_t n = blocks();
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < n; ++b) applyBlock(b, r, z);
}
template void NodeBlocks::apply(const Eigen::VectorXd&, Eigen::VectorXd&) const;
template void NodeBlocks::apply(const Eigen::VectorXf&, Eigen::VectorXf&) const;

}  // namespace lattice
