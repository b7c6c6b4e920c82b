#include "cg.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <span>

#include <fmt/format.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace lattice {

SolverMake readCg(const common::Config& solver, bool matrixFree) {
  CgKeys k;
  k.coarseCells = static_cast<int>(solver.get("coarse_cells", -1.0, common::Interval::closed(-1, 22)));
  // Single-precision inner solves halve the memory traffic of an iteration (docs/performance.md): the
  // default where they apply.
  k.mixed = solver.choice("precision", {"double", "mixed"}, matrixFree ? "mixed" : "double") == "mixed";
  if (k.mixed && !matrixFree) solver.failAt("precision", "`mixed` needs solver.type cg with solver.operator matrix_free");
  return [k](const SolverSettings& s) { return std::make_unique<Cg>(s, k); };
}

void Cg::update(const Model& model) {
  K_.attach(model);
  if (keys_.mixed) {
    if (model.op() != Operator::kMatrixFree)
      throw common::SimulationError("mixed-precision cg needs the matrix-free operator (solver.operator: matrix_free)");
    blocks_.keepSingle();
  }
  blocks_.update(model);
  if (keys_.coarseCells != 0) {
    // A restored model has rods back and nodes released: rebuild the coarse space (P included, it
    // dropped the rows of held nodes).
    if (model.restores() != restoresSeen_) coarseBuilt_ = false;
    restoresSeen_ = model.restores();
    if (!coarseBuilt_) {
      // Auto: cells of 4 mean rod lengths, at most 8 along the longest side up to 800,000 free dofs and
      // 8 (n / 800,000)^(1/5) beyond (12 for the 8M-rod cube). The coarse solve runs every iteration and
      // A_c is refactorised every 0.1 % of the rods, so the level grows much slower than the model: on
      // the 1M cube 10 or 12 cells save iterations but not time, on the 8M cube 12 save 19 %
      // (docs/performance.md).
      const double longest = model.box().size.maxCoeff();
      double mean = 0.0;
      for (std::size_t r = 0; r < model.rods(); ++r) mean += model.rodLength(r);
      mean /= static_cast<double>(std::max<std::size_t>(1, model.rods()));
      const double most = std::max(8.0, std::round(8.0 * std::pow(static_cast<double>(model.freeDofs()) / 8e5, 0.2)));
      const double cell = keys_.coarseCells > 0 ? longest / keys_.coarseCells : std::max(4 * mean, longest / most);
      coarse_.build(model, cell);
      coarseBuilt_ = true;
    } else {
      coarse_.update(model);
    }
  }
  cg_.preconditioner().bind(&blocks_, keys_.coarseCells != 0 ? &coarse_ : nullptr);
  cg_.compute(K_);
  cg_.setTolerance(settings_.tolerance);
  cg_.setMaxIterations(settings_.maxIterations > 0 ? settings_.maxIterations : static_cast<int>(10 * K_.rows()));
  ready_ = true;
}

void Cg::archive(common::StateArchive& a) {
  COSIM_ASSERT(ready_, "Cg::archive before update()");
  if (keys_.coarseCells != 0) a.io("coarse", coarse_);
  if (!keys_.mixed) return;
  // The last mixed solve, from which the next one's residual is updated when x has not moved (a
  // coupled window starts from the last one's solution): only while it is of this model as it is now.
  const Model& model = K_.model();
  bool current = haveLast_ && lastModel_ == &model && lastRestores_ == model.restores();
  a.io("last_current", current), a.io("residual", residual_), a.io("last_x", lastX_), a.io("last_b", lastB_);
  a.io("last_removals", lastRemovals_), a.io("last_held", lastHeld_);
  if (!a.reading()) return;
  haveLast_ = current;
  lastModel_ = &model;
  lastRestores_ = model.restores();
}

SolveReport Cg::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  COSIM_ASSERT(ready_, "Cg::solve before update()");
  SolveReport rep;
  if (keys_.mixed) {
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
    // Four running sums: with one, every addition waits for the previous one.
    double s[4] = {0.0, 0.0, 0.0, 0.0};
    const Eigen::Index begin = n * c / kChunks, end = n * (c + 1) / kChunks;
    Eigen::Index i = begin;
    for (; i + 4 <= end; i += 4)
      for (int k = 0; k < 4; ++k) s[k] += term(i + k);
    for (; i < end; ++i) s[0] += term(i);
    part[static_cast<std::size_t>(c)] = (s[0] + s[1]) + (s[2] + s[3]);
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
  if (!residualFromLast(b, x)) {
    model.apply(x, residual_);
    residual_ = b - residual_;
  }
  haveLast_ = false;  // until this solve ends: an exception leaves x and residual_ apart
  double rNorm = residual_.norm();
  int total = 0, passes = 0;
  while (rNorm > goal && total < maxIterations) {
    const double reduction = std::max(goal / rNorm, kInnerFloor);
    model.toPadded(residual_, 1.0 / rNorm, rhsF_);
    total += pcgSingle(rhsF_, dF_, reduction, maxIterations - total);
    model.addFromPadded(dF_, rNorm, x);
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
  lastModel_ = &model;
  lastX_ = x;
  lastB_ = b;
  lastRemovals_ = model.removalLog().size();
  lastHeld_ = model.heldNodes();
  lastRestores_ = model.restores();
  haveLast_ = true;
  return {total, rNorm / bNorm};
}

bool Cg::residualFromLast(const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
  const Model& model = K_.model();
  const auto& log = model.removalLog();
  // Holding a fragment or restoring a checkpoint changes K by more than the removed rods.
  if (!haveLast_ || &model != lastModel_ || model.heldNodes() != lastHeld_ || model.restores() != lastRestores_ || log.size() < lastRemovals_ ||
      x.size() != lastX_.size() || b.size() != lastB_.size() || !(x.array() == lastX_.array()).all())
    return false;
  residual_ += b - lastB_;
  model.addRodProducts(std::span(log).subspan(lastRemovals_), x, residual_);
  return true;
}

int Cg::pcgSingle(const Eigen::VectorXf& rhs, Eigen::VectorXf& d, double reduction, int maxIterations) {
  const Model& model = K_.model();
  const Eigen::Index n = rhs.size();
  const double stop = reduction * reduction * orderedSum(n, [&](Eigen::Index i) { return double(rhs[i]) * rhs[i]; });
  const bool coarse = keys_.coarseCells != 0;
  d.setZero(n);
  rF_ = rhs;
  zF_.setZero(n);  // the entries of nodes without free dofs stay 0
  // The preconditioned residual is z = z_J + P y_c with z_J = D⁻¹ r and y_c = A_c⁻¹ Pᵀ r; z_J is kept
  // apart and P y_c goes straight into the new direction. Returns r·z = r·z_J + (Pᵀ r)·y_c, r·z_J summed
  // per fixed chunk of node blocks (deterministic), while one thread runs the serial coarse solve.
  constexpr std::size_t kChunk = 2048;
  const std::size_t blocks = blocks_.blocks();
  const auto chunks = static_cast<std::ptrdiff_t>((blocks + kChunk - 1) / kChunk);
  chunkDot_.resize(static_cast<std::size_t>(chunks));
  bool restricted = false;  // rc_ already holds Pᵀ r
  auto precondition = [&] {
    if (coarse) {
      if (!restricted) coarse_.coarseResidual(rF_, rc_, [](Eigen::Index, Eigen::Index) { return 0.0; });
      restricted = false;
      rcRhs_ = rc_;
    }
#pragma omp parallel
    {
      if (coarse) {
#pragma omp single nowait
        coarse_.solve(rc_);
      }
#pragma omp for schedule(dynamic, 1)
      for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        double sum = 0.0;
        const std::size_t end = std::min(blocks, kChunk * static_cast<std::size_t>(c + 1));
        for (std::size_t b = kChunk * static_cast<std::size_t>(c); b < end; ++b) sum += blocks_.applySingleBlock(b, rF_, zF_);
        chunkDot_[static_cast<std::size_t>(c)] = sum;
      }
    }
    double rz = 0.0;
    for (double v : chunkDot_) rz += v;
    return coarse ? rz + rcRhs_.dot(rc_) : rz;
  };
  double rz = precondition();
  if (coarse) {
    pF_.setZero(n);
    coarse_.direction(rc_, zF_, 0.0f, pF_);
  } else {
    pF_ = zF_;
  }
  int it = 0;
  while (it < maxIterations) {
    model.applySingle(pF_, qF_);
    ++it;
    const double pq = orderedSum(n, [&](Eigen::Index i) { return double(pF_[i]) * qF_[i]; });
    const auto alpha = static_cast<float>(rz / pq);
    auto update = [&](Eigen::Index begin, Eigen::Index end) {
      double sum = 0.0;
      for (Eigen::Index i = begin; i < end; ++i) {
        d[i] += alpha * pF_[i];
        rF_[i] -= alpha * qF_[i];
        sum += double(rF_[i]) * rF_[i];
      }
      return sum;
    };
    // With a coarse level, Pᵀ r is gathered in the same pass (precondition() then skips it).
    const double rr = coarse ? coarse_.coarseResidual(rF_, rc_, update) : orderedSum(n, [&](Eigen::Index i) { return update(i, i + 1); });
    restricted = coarse;
    if (rr <= stop) break;
    const double rzNew = precondition();
    const auto beta = static_cast<float>(rzNew / rz);
    rz = rzNew;
    if (coarse) {
      coarse_.direction(rc_, zF_, beta, pF_);
    } else {
#pragma omp parallel for schedule(static)
      for (Eigen::Index i = 0; i < n; ++i) pF_[i] = zF_[i] + beta * pF_[i];
    }
  }
  return it;
}

}  // namespace lattice
