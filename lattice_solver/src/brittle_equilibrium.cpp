#include "lattice/brittle_equilibrium.hpp"

#include <algorithm>
#include <chrono>

#include "common/log.hpp"
#include "common/state_archive.hpp"

namespace lattice {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
}  // namespace

BrittleEquilibrium::BrittleEquilibrium(Model& model, EquilibriumSolver& solver, RemovalStrategy removal, int maxRounds)
    : model_(model), solver_(solver), removal_(removal), maxRounds_(maxRounds) {}

namespace {
constexpr std::int64_t kAhead = 16;
}  // namespace

void BrittleEquilibrium::overLimit(const std::vector<double>& u, std::vector<std::uint32_t>& rods,
                                   std::vector<double>& ratio) const {
  rods.clear();
  ratio.clear();
  const auto n = static_cast<std::int64_t>(model_.rods());
#pragma omp parallel
  {
    std::vector<std::uint32_t> myRods;
    std::vector<double> myRatio;
    const auto& X = model_.referenceNodes();
#pragma omp for schedule(static) nowait
    for (std::int64_t r = 0; r < n; ++r) {
      const auto rod = static_cast<std::size_t>(r);
      // Rods run by their first end, so the second ends are scattered over u and the nodes: fetch them
      // a few rods ahead (the check waited on those loads).
      if (r + kAhead < n) {
        const std::uint32_t b = model_.rod(rod + kAhead)[1];
        __builtin_prefetch(u.data() + 6 * static_cast<std::size_t>(b));
        __builtin_prefetch(X.data() + b);
      }
      if (!model_.active(rod)) continue;
      const double e = model_.rodStrain(rod, u);
      const auto& p = model_.phaseProperties(model_.phase(rod));
      const double q = e >= 0 ? e / p.tensileStrain : -e / p.compressiveStrain;
      if (q > 1.0) {
        myRods.push_back(static_cast<std::uint32_t>(rod));
        myRatio.push_back(q);
      }
    }
#pragma omp critical
    {
      rods.insert(rods.end(), myRods.begin(), myRods.end());
      ratio.insert(ratio.end(), myRatio.begin(), myRatio.end());
    }
  }
  // Threads finish in any order: sort by rod so every run removes the same rods in the same order.
  std::vector<std::size_t> idx(rods.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::sort(idx.begin(), idx.end(), [&](auto a, auto b) { return rods[a] < rods[b]; });
  std::vector<std::uint32_t> r2(rods.size());
  std::vector<double> q2(rods.size());
  for (std::size_t i = 0; i < idx.size(); ++i) {
    r2[i] = rods[idx[i]];
    q2[i] = ratio[idx[i]];
  }
  rods.swap(r2);
  ratio.swap(q2);
}

double BrittleEquilibrium::worstRatio(const std::vector<double>& u) const {
  double worst = 0.0;
  for (std::size_t r = 0; r < model_.rods(); ++r) {
    const double e = model_.rodStrain(r, u);
    const auto& p = model_.phaseProperties(model_.phase(r));
    worst = std::max(worst, e >= 0 ? e / p.tensileStrain : -e / p.compressiveStrain);
  }
  return worst;
}

BrittleEquilibrium::Report BrittleEquilibrium::run(const Rhs& rhs, const Full& full, Eigen::VectorXd& x,
                                                   std::vector<double>& u, const std::string& where,
                                                   const Inspect& elastic, bool remove) {
  Report rep;
  auto solve = [&] {
    const auto t = Clock::now();
    const SolveReport s = solver_.solve(rhs(), x);
    solveSeconds_ += since(t);
    ++solves_;
    iterations_ += s.iterations;
    rep.iterations += s.iterations;
    ++rep.rounds;
    full(x, u);
  };
  solve();
  if (elastic) elastic(u);
  if (!remove) return rep;
  std::vector<std::uint32_t> over;
  std::vector<double> ratio;
  for (int round = 0;; ++round) {
    const auto checkStart = Clock::now();
    overLimit(u, over, ratio);
    checkSeconds_ += since(checkStart);
    if (over.empty()) break;
    if (round >= maxRounds_) {
      common::logger("lattice")->warn("{}: {} rods still over their limit after {} removal rounds; moving on", where,
                                      over.size(), round);
      break;
    }
    if (removal_ == RemovalStrategy::kOne) {
      const auto it = std::max_element(ratio.begin(), ratio.end());  // first of equal maxima: lowest rod
      const std::uint32_t r = over[static_cast<std::size_t>(it - ratio.begin())];
      over.assign(1, r);
    }
    for (auto r : over) rep.removed.push_back({r, model_.rodStrain(r, u)});
    auto t = Clock::now();
    model_.removeRods(over, x);
    removalSeconds_ += since(t);
    t = Clock::now();
    solver_.update(model_);
    updateSeconds_ += since(t);
    solve();
  }
  return rep;
}

void BrittleEquilibrium::archive(common::StateArchive& a) {
  a.io("iterations", iterations_), a.io("solves", solves_), a.io("solve_seconds", solveSeconds_);
  a.io("removal_seconds", removalSeconds_), a.io("update_seconds", updateSeconds_), a.io("check_seconds", checkSeconds_);
}

}  // namespace lattice
