#include "averaging.hpp"

#include <fmt/format.h>

#include "common/config.hpp"
#include "common/errors.hpp"

namespace lattice {

SolverMake readAveraging(const common::Config& solver, bool) {
  AveragingKeys k;
  k.relaxation = solver.get("relaxation", k.relaxation, common::Interval::open(0, 2));
  return [k](const SolverSettings& s) { return std::make_unique<Averaging>(s, k); };
}

void Averaging::update(const Model& model) {
  model_ = &model;
  blocks_.update(model);
}

// Node j's rods ask for positions p_r with K_jj^r p_r = −K_ji^r x_i (the position where rod r pulls no
// more, the other end held); the stiffness-weighted average (Σ_r K_jj^r)⁻¹ Σ_r K_jj^r p_r is the
// Gauss–Seidel update x_j = D_j⁻¹(b_j − Σ_{i≠j} K_ji x_i), written as x_j += D_j⁻¹ r_j.
void Averaging::sweep(const Eigen::VectorXd& b, Eigen::VectorXd& x, bool forward) const {
  const auto& start = model_->blockStart();
  const auto& order = model_->sweepOrder();
  const double omega = keys_.relaxation;
  Eigen::Matrix<double, 6, 1> r;
  const std::size_t n = order.size();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t blk = order[forward ? k : n - 1 - k];
    const int first = static_cast<int>(start[blk]);
    const int m = static_cast<int>(start[blk + 1]) - first;
    r.head(m) = b.segment(first, m) - model_->blockProduct(blk, x).head(m);
    const auto& inv = blocks_.inverse(blk);
    if (m == 6) {
      x.segment<6>(first) += omega * (inv * r);
    } else {
      x.segment(first, m) += omega * (inv.topLeftCorner(m, m) * r.head(m));
    }
  }
}

SolveReport Averaging::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  COSIM_ASSERT(model_ != nullptr, "Averaging::solve before update()");
  const double bNorm = b.norm();
  SolveReport rep;
  if (bNorm == 0.0) {
    x.setZero();
    return rep;
  }
  const int maxSweeps = settings_.maxIterations > 0 ? settings_.maxIterations : static_cast<int>(20 * b.size());
  Eigen::VectorXd res(b.size());
  auto residual = [&] {
    model_->apply(x, res);
    return (b - res).norm() / bNorm;
  };
  rep.residual = residual();
  while (rep.residual > settings_.tolerance) {
    if (rep.iterations >= maxSweeps)
      throw common::SimulationError(fmt::format("averaging did not reach the relative residual {:.3g} in {} sweeps (it is "
                                                "{:.3g}); raise solver.max_iterations or use solver.type: cg",
                                                settings_.tolerance, rep.iterations, rep.residual));
    for (int s = 0; s < keys_.checkEvery; ++s, ++rep.iterations) sweep(b, x, rep.iterations % 2 == 0);
    rep.residual = residual();
  }
  return rep;
}

}  // namespace lattice
