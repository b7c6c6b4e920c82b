#include "cg.hpp"

#include <array>

#include <fmt/format.h>

#include "common/errors.hpp"

namespace lattice {

void Cg::update(const Model& model) {
  K_.attach(model);
  if (settings_.mixed) {
    if (model.op() != Operator::kMatrixFree)
      throw common::SimulationError("mixed-precision cg needs the matrix-free operator (solver.operator: matrix_free)");
    blocks_.keepSingle();
  }
  blocks_.update(model);
  if (settings_.coarseCells != 0) {
    // A restored model has rods back and nodes released: rebuild the coarse space (P included, it
    // dropped the rows of held nodes).
    if (model.restores() != restoresSeen_) coarseBuilt_ = false;
    restoresSeen_ = model.restores();
    if (!coarseBuilt_) {
      // Auto: cells of 4 mean rod lengths, at most 8 along the longest side (the factorisation of A_c
      // is redone after every removal round, so it must stay small).
      const double longest = model.box().size.maxCoeff();
      double mean = 0.0;
      for (std::size_t r = 0; r < model.rods(); ++r) mean += model.rodLength(r);
      mean /= static_cast<double>(std::max<std::size_t>(1, model.rods()));
      const double cell = settings_.coarseCells > 0 ? longest / settings_.coarseCells : std::max(4 * mean, longest / 8);
      coarse_.build(model, cell);
      coarseBuilt_ = true;
    } else {
      coarse_.update(model);
    }
  }
  cg_.preconditioner().bind(&blocks_, settings_.coarseCells != 0 ? &coarse_ : nullptr);
  cg_.compute(K_);
  cg_.setTolerance(settings_.tolerance);
  cg_.setMaxIterations(settings_.maxIterations > 0 ? settings_.maxIterations : static_cast<int>(10 * K_.rows()));
  ready_ = true;
}

SolveReport Cg::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  COSIM_ASSERT(ready_, "Cg::solve before update()");
  SolveReport rep;
  if (settings_.mixed) {
    rep = solveMixed(b, x);
  } else {
    x = cg_.solveWithGuess(b, x);
    rep = SolveReport{static_cast<int>(cg_.iterations()), cg_.error()};
  }
  if (!(rep.residual <= settings_.tolerance))
    throw common::SimulationError(fmt::format("cg did not reach the relative residual {:.3g} in {} iterations (it is {:.3g}); "
                                              "raise solver.max_iterations or the tolerance",
                                              settings_.tolerance, rep.iterations, rep.residual));
  return rep;
}

namespace {

// Sums over fixed chunks of [0, n), each chunk's sum in double, added in chunk order: the same bits
// for any thread count.
constexpr int kChunks = 64;
template <class Term>
double orderedSum(Eigen::Index n, const Term& term) {
  std::array<double, kChunks> part{};
#pragma omp parallel for schedule(static)
  for (int c = 0; c < kChunks; ++c) {
    double s = 0.0;
    const Eigen::Index begin = n * c / kChunks, end = n * (c + 1) / kChunks;
    for (Eigen::Index i = begin; i < end; ++i) s += term(i);
    part[static_cast<std::size_t>(c)] = s;
  }
  double s = 0.0;
  for (double v : part) s += v;
  return s;
}

}  // namespace

SolveReport Cg::solveMixed(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const Model& model = K_.model();
  const double bNorm = b.norm();
  if (bNorm == 0.0) {
    x.setZero();
    return {0, 0.0};
  }
  const double goal = settings_.tolerance * bNorm;
  const int maxIterations = cg_.maxIterations();
  // Each inner solve asks for the reduction the outer test needs (a second, short pass follows when
  // the double residual ends just above it), but not below what single precision reliably reaches:
  // on the 5 cm cube, asking for 3× more cost 17 % more iterations, a floor of 1e-5 instead of 1e-4 20 %.
  constexpr double kInnerFloor = 1e-4;
  model.apply(x, residual_);
  residual_ = b - residual_;
  double rNorm = residual_.norm();
  int total = 0, passes = 0;
  while (rNorm > goal && total < maxIterations) {
    const double reduction = std::max(goal / rNorm, kInnerFloor);
    rhsF_ = (residual_ / rNorm).cast<float>();
    total += pcgSingle(rhsF_, dF_, reduction, maxIterations - total);
    x += rNorm * dF_.cast<double>();
    model.apply(x, residual_);
    residual_ = b - residual_;
    const double previous = rNorm;
    rNorm = residual_.norm();
    // A pass reduces the residual by the floor's 1e-4 or reaches the goal: a handful of passes or one
    // that gains nothing means K̃ is too far from K for single precision.
    if (!(rNorm < previous) || ++passes > 10)
      throw common::SimulationError(fmt::format("mixed-precision cg stalled at the relative residual {:.3g} after {} passes (the "
                                                "single-precision solves no longer reduce the double residual); use "
                                                "solver.precision: double",
                                                rNorm / bNorm, passes));
  }
  return {total, rNorm / bNorm};
}

int Cg::pcgSingle(const Eigen::VectorXf& rhs, Eigen::VectorXf& d, double reduction, int maxIterations) {
  const Model& model = K_.model();
  const Eigen::Index n = rhs.size();
  const double stop = reduction * reduction * orderedSum(n, [&](Eigen::Index i) { return double(rhs[i]) * rhs[i]; });
  d.setZero(n);
  rF_ = rhs;
  // z = D⁻¹ r + P A_c⁻¹ Pᵀ r, the serial coarse solve on one thread while the others start on the
  // node blocks (dynamic shares: whoever is free takes the next).
  auto precondition = [&] {
    if (settings_.coarseCells == 0) {
      blocks_.apply(rF_, zF_);
      return;
    }
    coarse_.coarseResidual(rF_, rc_);
    zF_.resize(n);
    const auto blocks = static_cast<std::ptrdiff_t>(blocks_.blocks());
#pragma omp parallel
    {
#pragma omp single nowait
      coarse_.solve(rc_);
#pragma omp for schedule(dynamic, 2048)
      for (std::ptrdiff_t b = 0; b < blocks; ++b) blocks_.applyBlock(static_cast<std::size_t>(b), rF_, zF_);
    }
    coarse_.prolongAdd(rc_, zF_);
  };
  precondition();
  pF_ = zF_;
  double rz = orderedSum(n, [&](Eigen::Index i) { return double(rF_[i]) * zF_[i]; });
  int it = 0;
  while (it < maxIterations) {
    model.applySingle(pF_, qF_);
    ++it;
    const double pq = orderedSum(n, [&](Eigen::Index i) { return double(pF_[i]) * qF_[i]; });
    const auto alpha = static_cast<float>(rz / pq);
    const double rr = orderedSum(n, [&](Eigen::Index i) {
      d[i] += alpha * pF_[i];
      rF_[i] -= alpha * qF_[i];
      return double(rF_[i]) * rF_[i];
    });
    if (rr <= stop) break;
    precondition();
    const double rzNew = orderedSum(n, [&](Eigen::Index i) { return double(rF_[i]) * zF_[i]; });
    const auto beta = static_cast<float>(rzNew / rz);
    rz = rzNew;
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < n; ++i) pF_[i] = zF_[i] + beta * pF_[i];
  }
  return it;
}

}  // namespace lattice
