// common::runLoop on a harmonic oscillator x'' = −ω² x integrated by leapfrog (kick-drift-kick): the
// schedule's rows against their times, the rows against the exact solution cos ωt, a restart against the
// uninterrupted run, and a failed energy check.
#include "common/run_loop.hpp"

#include <cmath>
#include <filesystem>
#include <variant>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "common/errors.hpp"

namespace fs = std::filesystem;

namespace {

struct Row {
  std::int64_t step;
  double t, x;
  bool last;
};

class Oscillator final : public common::SteppedRun {
 public:
  Oscillator(double omega, double dt, double end, double energyTolerance = 1.0)
      : omega_(omega), dt_(dt), total_(std::llround(end / dt)), tolerance_(energyTolerance) {}

  /// From then on a step fails before it counts (a solve that did not converge); `writable`: whether the
  /// failed state may be written (a run on ranks that failed on one rank alone may not).
  void failAt(std::int64_t step, bool writable) { failAt_ = step, writable_ = writable; }
  bool canWriteFailedState() const override { return writable_; }

  double clock() const override { return t_; }
  double clockStep() const override { return dt_; }
  std::int64_t steps() const override { return steps_; }
  bool finished() const override { return steps_ >= total_; }
  void step() override {
    if (steps_ == failAt_) throw common::SimulationError("the step did not converge");
    v_ -= 0.5 * dt_ * omega_ * omega_ * x_;
    x_ += dt_ * v_;
    v_ -= 0.5 * dt_ * omega_ * omega_ * x_;
    t_ += dt_;  // accumulated, as the solvers' clocks are: 10 steps of 0.01 fall short of 0.1
    ++steps_;
    if (std::abs(energy() - 0.5 * omega_ * omega_) > tolerance_ * 0.5 * omega_ * omega_)
      throw common::InstabilityError({"energy growth", "the oscillator", t_, fmt::format("E = {}", energy()), "a smaller dt"});
  }
  void writeSeries(common::SeriesRow row) override { rows.push_back({steps_, t_, x_, row != common::SeriesRow::kScheduled}); }
  void writeSnapshot(bool) override { snapshots.push_back(steps_); }
  void archive(common::StateArchive& a) override {
    a.io("x", x_), a.io("v", v_), a.io("t", t_), a.io("steps", steps_);
  }
  void report(common::Summary& summary, double, bool failed) override {
    summary.set("x_final", x_);
    summary.set("failed", static_cast<std::int64_t>(failed));
  }

  double energy() const { return 0.5 * v_ * v_ + 0.5 * omega_ * omega_ * x_ * x_; }
  double x() const { return x_; }
  double v() const { return v_; }

  std::vector<Row> rows;
  std::vector<std::int64_t> snapshots;

 private:
  double omega_, dt_;
  std::int64_t total_;
  double tolerance_;
  double x_ = 1.0, v_ = 0.0, t_ = 0.0;
  std::int64_t steps_ = 0, failAt_ = -1;
  bool writable_ = true;
};

common::RunLoopSettings settings(double series, double snapshots, double end) {
  common::RunLoopSettings s;
  s.label = "oscillator";
  s.kind = "run loop test";
  s.end = end;
  s.series = common::Cadence::every(series);
  s.snapshots = common::Cadence::every(snapshots);
  s.progress = false;
  return s;
}

double result(const common::Summary& summary, const std::string& key) {
  return std::get<double>(summary.results().at(key));
}

fs::path freshFolder(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("cosim_run_loop_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

}  // namespace

TEST(RunLoop, RowsFallOnTheNearestStepAndFollowTheExactSolution) {
  Oscillator run(1.0, 0.01, 1.0);
  common::Summary summary;
  std::optional<common::StateArchive> none;
  common::runLoop(run, settings(0.1, 0.25, 1.0), nullptr, none, {}, summary);
  // t accumulated in steps of 0.01 is 0.09999999999999999 after 10: the row is due half a step early.
  ASSERT_EQ(run.rows.size(), 11u);
  for (std::size_t k = 0; k < run.rows.size(); ++k) {
    EXPECT_EQ(run.rows[k].step, static_cast<std::int64_t>(10 * k));
    EXPECT_NEAR(run.rows[k].t, 0.1 * static_cast<double>(k), 1e-12);
    // Leapfrog's phase error: ω³ dt² t / 24 ≤ 4.2e-6 at t = 1.
    EXPECT_NEAR(run.rows[k].x, std::cos(run.rows[k].t), 5e-6);
  }
  EXPECT_TRUE(run.rows.back().last);  // the end fell due: written once, as the last state
  EXPECT_EQ(run.snapshots, (std::vector<std::int64_t>{0, 25, 50, 75, 100}));
  EXPECT_EQ(result(summary, "x_final"), run.x());
}

TEST(RunLoop, TheLastStateIsWrittenOnceWhereTheSettingsAskForIt) {
  auto run = [](bool atEnd) {
    Oscillator osc(1.0, 0.01, 1.0);
    auto s = settings(0.3, 0.0, 1.0);
    s.seriesAtEnd = s.snapshotAtEnd = atEnd;
    common::Summary summary;
    std::optional<common::StateArchive> none;
    common::runLoop(osc, s, nullptr, none, {}, summary);
    std::vector<std::int64_t> steps;
    for (const Row& r : osc.rows) steps.push_back(r.step);
    return std::make_pair(steps, osc.snapshots);
  };
  EXPECT_EQ(run(false).first, (std::vector<std::int64_t>{0, 30, 60, 90}));
  EXPECT_TRUE(run(false).second.empty());
  EXPECT_EQ(run(true).first, (std::vector<std::int64_t>{0, 30, 60, 90, 100}));
  EXPECT_EQ(run(true).second, (std::vector<std::int64_t>{100}));  // no cadence, but the last state
}

TEST(RunLoop, ARestartFromTheLastCheckpointEndsWhereTheUninterruptedRunEnds) {
  const fs::path dir = freshFolder("restart");
  auto s = settings(0.1, 0.0, 1.0);
  s.checkpoints = common::Cadence::after(0.3);
  s.checkpointFile = dir / "checkpoint.h5";
  Oscillator whole(2.0, 0.01, 1.0);
  common::Summary first;
  std::optional<common::StateArchive> none;
  const auto report = common::runLoop(whole, s, nullptr, none, {}, first);
  EXPECT_EQ(report.checkpoints, 3);  // 0.3, 0.6, 0.9; none at the end
  EXPECT_EQ(std::get<std::int64_t>(first.cost().at("checkpoints_written")), 3);

  Oscillator resumed(2.0, 0.01, 1.0);  // its state is the checkpoint's, not x = 1 at rest
  std::optional<common::StateArchive> from = common::StateArchive::open(s.checkpointFile, s.kind);
  common::Summary second;
  const auto again = common::runLoop(resumed, s, nullptr, from, s.checkpointFile, second);
  EXPECT_EQ(again.restartedAt, 90);
  EXPECT_EQ(std::get<std::int64_t>(second.cost().at("restarted_at_step")), 90);
  EXPECT_EQ(resumed.x(), whole.x());  // bit for bit
  EXPECT_EQ(resumed.v(), whole.v());
  // The schedule continued too: the rows after the checkpoint and no other.
  ASSERT_EQ(resumed.rows.size(), 1u);
  EXPECT_EQ(resumed.rows[0].step, 100);
  EXPECT_EQ(resumed.rows[0].x, whole.rows.back().x);
  fs::remove_all(dir);
}

TEST(RunLoop, AFailedCheckKeepsTheFailedStateAndReportsBeforeTheErrorGoesOn) {
  // ω dt = 2.1 > 2: leapfrog is unstable and the energy grows about threefold a step.
  Oscillator run(210.0, 0.01, 1.0, 10.0);
  common::Summary summary;
  std::optional<common::StateArchive> none;
  EXPECT_THROW(common::runLoop(run, settings(0.1, 0.0, 1.0), nullptr, none, {}, summary), common::InstabilityError);
  ASSERT_EQ(run.rows.size(), 2u);  // t = 0, and the state that failed
  EXPECT_EQ(run.rows[1].step, run.steps());
  EXPECT_GT(run.energy(), 10.0 * 0.5 * 210.0 * 210.0);
  EXPECT_EQ(std::get<std::int64_t>(summary.results().at("failed")), 1);
  EXPECT_EQ(result(summary, "x_final"), run.x());
}

TEST(RunLoop, AStepThatFailsBeforeItCountsLeavesNoRowAndNeitherDoesARankThatFailedAlone) {
  // The first row one interval in (as the lattice's curve): a first step that fails left no state.
  Oscillator first(1.0, 0.01, 1.0);
  first.failAt(0, true);
  auto s = settings(0.1, 0.0, 1.0);
  s.series = common::Cadence::after(0.1);
  common::Summary summary;
  std::optional<common::StateArchive> none;
  EXPECT_THROW(common::runLoop(first, s, nullptr, none, {}, summary), common::SimulationError);
  EXPECT_TRUE(first.rows.empty());
  EXPECT_EQ(std::get<std::int64_t>(summary.results().at("failed")), 1);
  // A failed state that may not be written is not, though it is new.
  Oscillator alone(210.0, 0.01, 1.0, 10.0);
  alone.failAt(-1, false);
  EXPECT_THROW(common::runLoop(alone, settings(0.1, 0.0, 1.0), nullptr, none, {}, summary), common::InstabilityError);
  ASSERT_EQ(alone.rows.size(), 1u);  // t = 0 only
}

TEST(RunLoop, AnOutputSwitchedOnForARestartStartsAtTheClock) {
  const fs::path dir = freshFolder("switched_on");
  auto s = settings(0.1, 0.0, 1.0);  // no snapshots
  s.checkpoints = common::Cadence::after(0.3);
  s.checkpointFile = dir / "checkpoint.h5";
  Oscillator whole(1.0, 0.01, 1.0);
  common::Summary summary;
  std::optional<common::StateArchive> none;
  common::runLoop(whole, s, nullptr, none, {}, summary);
  // Restarted at 0.9 with snapshots every 0.05: the one owed at the clock, then on the interval's grid;
  // not one every step to catch up from 0.
  s.snapshots = common::Cadence::every(0.05);
  Oscillator resumed(1.0, 0.01, 1.0);
  std::optional<common::StateArchive> from = common::StateArchive::open(s.checkpointFile, s.kind);
  common::runLoop(resumed, s, nullptr, from, s.checkpointFile, summary);
  EXPECT_EQ(resumed.snapshots, (std::vector<std::int64_t>{91, 95, 100}));
  fs::remove_all(dir);
}
