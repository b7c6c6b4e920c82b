#include "lattice/fracture_test.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/state_archive.hpp"

namespace lattice {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
}  // namespace

FractureTest::FractureTest(Model& model, EquilibriumSolver& solver, const LoadingSettings& settings)
    : model_(model), solver_(solver), settings_(settings), brittle_(model, solver, settings.removal, settings.maxRounds) {
  x_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.freeDofs()));
  removedAt_.assign(model.rods(), -1);
  solver_.update(model_);
}

std::vector<double> FractureTest::displacement() const {
  std::vector<double> u;
  model_.fullDisplacement(x_, strain_, u);
  return u;
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
  std::vector<double> u;
  const auto rep = brittle_.run([&] { return model_.rhs(strain_); },
                                [&](const Eigen::VectorXd& x, std::vector<double>& out) { model_.fullDisplacement(x, strain_, out); },
                                x_, u, fmt::format("increment {}", increment_), [&](const std::vector<double>& elastic) {
                                  if (increment_ != 1) return;
                                  youngsModulus_ = model_.reaction(elastic) / model_.loadedArea() / strain_;
                                  // Linear until the first removal: the rod at the largest ratio reaches its
                                  // limit at ε / ratio.
                                  const double worst = brittle_.worstRatio(elastic);
                                  firstCritical_ = worst > 0 ? strain_ / worst : std::numeric_limits<double>::infinity();
                                });
  for (const auto& rec : rep.removed) {
    removals_.push_back({rec.rod, increment_, strain_, rec.strain});
    removedAt_[rec.rod] = increment_;
  }
  row.removedNow = rep.removed.size();
  row.rounds = rep.rounds;
  row.iterations = rep.iterations;
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

void FractureTest::archive(common::StateArchive& a) {
  a.io("equilibrium", brittle_), a.io("state", x_), a.io("strain", strain_), a.io("increment", increment_);
  a.io("finished", finished_), a.io("peak", peak_), a.io("youngs_modulus", youngsModulus_);
  a.io("first_critical", firstCritical_), a.io("curve", curve_), a.io("removals", removals_), a.io("removed_at", removedAt_);
  if (a.reading() && (static_cast<std::size_t>(x_.size()) != model_.freeDofs() || removedAt_.size() != model_.rods()))
    throw common::ConfigError(fmt::format("{}: the fracture test's state does not fit this model ({})", a.path().string(), model_.shape()));
}

}  // namespace lattice
