#include <Eigen/Cholesky>

#include "common/errors.hpp"
#include "lattice/solver.hpp"

namespace lattice {

void NodeBlocks::compute(const Model::SparseMatrix& K, const std::vector<std::uint32_t>& blockStart) {
  start_ = &blockStart;
  const std::size_t blocks = blockStart.size() - 1;
  inverse_.resize(blocks);
  const int* outer = K.outerIndexPtr();
  const int* inner = K.innerIndexPtr();
  const double* value = K.valuePtr();
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < blocks; ++b) {
    const int first = static_cast<int>(blockStart[b]);
    const int m = static_cast<int>(blockStart[b + 1]) - first;
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(m, m);
    for (int i = 0; i < m; ++i)
      for (int p = outer[first + i]; p < outer[first + i + 1]; ++p)
        if (inner[p] >= first && inner[p] < first + m) D(i, inner[p] - first) = value[p];
    inverse_[b].setZero();
    // A node block is symmetric positive definite while the node has rods; LDLT also copes with the
    // semi-definite blocks round-off can leave.
    inverse_[b].topLeftCorner(m, m) = D.ldlt().solve(Eigen::MatrixXd::Identity(m, m));
  }
}

void NodeBlocks::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  COSIM_ASSERT(start_ != nullptr, "NodeBlocks used before compute()");
  const auto& s = *start_;
  z.resize(r.size());
  const std::size_t blocks = s.size() - 1;
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < blocks; ++b) {
    const int first = static_cast<int>(s[b]);
    const int m = static_cast<int>(s[b + 1]) - first;
    if (m == 6) {
      z.segment<6>(first) = inverse_[b] * r.segment<6>(first);
    } else {
      z.segment(first, m) = inverse_[b].topLeftCorner(m, m) * r.segment(first, m);
    }
  }
}

}  // namespace lattice
