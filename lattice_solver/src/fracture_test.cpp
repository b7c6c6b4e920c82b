#include "lattice/fracture_test.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "common/log.hpp"

namespace lattice {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
}  // namespace

FractureTest::FractureTest(Model& model, EquilibriumSolver& solver, const LoadingSettings& settings)
    : model_(model), solver_(solver), settings_(settings) {
  x_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.freeDofs()));
  removedAt_.assign(model.rods(), -1);
  solver_.update(model_);
}

std::vector<double> FractureTest::displacement() const {
  std::vector<double> u;
  model_.fullDisplacement(x_, strain_, u);
  return u;
}

void FractureTest::overLimit(const std::vector<double>& u, std::vector<std::uint32_t>& rods,
                             std::vector<double>& ratio) const {
  rods.clear();
  ratio.clear();
  const auto n = static_cast<std::int64_t>(model_.rods());
#pragma omp parallel
  {
    std::vector<std::uint32_t> myRods;
    std::vector<double> myRatio;
#pragma omp for schedule(static) nowait
    for (std::int64_t r = 0; r < n; ++r) {
      const auto rod = static_cast<std::size_t>(r);
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

void FractureTest::solve(IncrementResult& row) {
  const auto t = Clock::now();
  const SolveReport rep = solver_.solve(model_.rhs(strain_), x_);
  solveSeconds_ += since(t);
  ++solves_;
  iterations_ += rep.iterations;
  row.iterations += rep.iterations;
  ++row.rounds;
}

bool FractureTest::step() {
  if (finished_) return false;
  const auto start = Clock::now();
  ++increment_;
  const double previous = strain_;
  strain_ = settings_.direction * std::min(increment_ * settings_.strainIncrement, settings_.maxStrain);
  if (previous != 0.0) {
    const Eigen::VectorXd held = model_.heldValues();
    x_ = held + (strain_ / previous) * (x_ - held);
  }
  IncrementResult row;
  row.increment = increment_;
  row.strain = strain_;
  solve(row);

  std::vector<double> u;
  model_.fullDisplacement(x_, strain_, u);
  std::vector<std::uint32_t> over;
  std::vector<double> ratio;
  if (increment_ == 1) {
    youngsModulus_ = model_.reaction(u) / model_.loadedArea() / strain_;
    // Linear until the first removal: the rod at the largest ratio reaches its limit at ε / ratio.
    double worst = 0.0;
    for (std::size_t r = 0; r < model_.rods(); ++r) {
      const double e = model_.rodStrain(r, u);
      const auto& p = model_.phaseProperties(model_.phase(r));
      worst = std::max(worst, e >= 0 ? e / p.tensileStrain : -e / p.compressiveStrain);
    }
    firstCritical_ = worst > 0 ? strain_ / worst : std::numeric_limits<double>::infinity();
  }
  for (int round = 0;; ++round) {
    const auto checkStart = Clock::now();
    overLimit(u, over, ratio);
    checkSeconds_ += since(checkStart);
    if (over.empty()) break;
    if (round >= settings_.maxRounds) {
      common::logger("lattice")->warn("increment {}: {} rods still over their limit after {} removal rounds; moving on",
                                      increment_, over.size(), round);
      break;
    }
    if (settings_.removal == RemovalStrategy::kOne) {
      const auto it = std::max_element(ratio.begin(), ratio.end());  // first of equal maxima: lowest rod
      const std::uint32_t r = over[static_cast<std::size_t>(it - ratio.begin())];
      over.assign(1, r);
    }
    for (auto r : over) {
      removals_.push_back({r, increment_, strain_, model_.rodStrain(r, u)});
      removedAt_[r] = increment_;
    }
    row.removedNow += over.size();
    auto t = Clock::now();
    model_.removeRods(over, x_);
    removalSeconds_ += since(t);
    t = Clock::now();
    solver_.update(model_);
    updateSeconds_ += since(t);
    solve(row);
    model_.fullDisplacement(x_, strain_, u);
  }
  row.removedTotal = model_.removedCount();
  row.stress = model_.reaction(u) / model_.loadedArea();
  row.seconds = since(start);
  curve_.push_back(row);
  if (peak_ < 0 || settings_.direction * row.stress > settings_.direction * curve_[static_cast<std::size_t>(peak_)].stress)
    peak_ = static_cast<int>(curve_.size()) - 1;
  const double peakStress = settings_.direction * curve_[static_cast<std::size_t>(peak_)].stress;
  if (std::abs(strain_) >= settings_.maxStrain * (1 - 1e-12)) finished_ = true;
  if (settings_.stopFraction > 0 && peak_ < static_cast<int>(curve_.size()) - 1 &&
      settings_.direction * row.stress < settings_.stopFraction * peakStress)
    finished_ = true;
  return true;
}

}  // namespace lattice
