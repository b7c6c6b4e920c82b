#include "common/run_loop.hpp"

#include <chrono>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"

namespace common {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// The progress display: common::Progress for time steps, the adapter's own status line every 10 s of
/// wall time for slow steps.
class Display {
 public:
  Display(const SteppedRun& run, const RunLoopSettings& s)
      : run_(run),
        label_(s.label),
        enabled_(s.progress),
        ownStatus_(!run.status().empty()),
        bar_(s.label, s.end, s.progress && !ownStatus_) {}
  void update() {
    if (!enabled_) return;
    if (!ownStatus_) return bar_.update(run_.clock(), run_.steps());
    if (since(last_) < 10.0) return;
    last_ = Clock::now();
    logger(label_)->info("{}", run_.status());
  }
  void finish() { bar_.finish(run_.clock(), run_.steps()); }

 private:
  const SteppedRun& run_;
  std::string label_;
  bool enabled_, ownStatus_;
  Progress bar_;
  Clock::time_point last_ = Clock::now();
};

}  // namespace

RunLoopReport runLoop(SteppedRun& run, RunLoopSettings s, H5Writer* results, std::optional<StateArchive>& from,
                      const std::filesystem::path& restart, Summary& summary) {
  RunLoopReport report;
  std::int64_t seriesStep = -1, snapshotStep = -1;  // the step each last wrote: a state is written once
  // Marked before writing: a check the writing makes may fail after the row is in.
  auto writeSeries = [&](SeriesRow row) {
    seriesStep = run.steps();
    run.writeSeries(row);
  };
  auto writeSnapshot = [&](bool last) {
    snapshotStep = run.steps();
    run.writeSnapshot(last);
  };
  // Everything a checkpoint holds: the results' extent, the loop's schedule, the adapter's state.
  const std::function<void(StateArchive&)> archive = [&](StateArchive& a) {
    if (!a.reading() && results) archiveExtent(a, *results);
    {
      auto scope = a.scope("loop");
      a.io("series", s.series), a.io("snapshots", s.snapshots), a.io("checkpoints", s.checkpoints);
      a.io("series_step", seriesStep), a.io("snapshot_step", snapshotStep);
    }
    run.archive(a);
  };
  // Half the step read anew for each: writing a row may change the step (the FEM's followed step).
  auto outputsDue = [&] {
    if (s.series.due(run.clock(), 0.5 * run.clockStep())) {
      writeSeries(SeriesRow::kScheduled);
      s.series.advance();
    }
    if (s.snapshots.due(run.clock(), 0.5 * run.clockStep())) {
      writeSnapshot(false);
      s.snapshots.advance();
    }
  };

  if (from) {
    archive(*from);
    // A checkpoint holds each schedule's next time, kept with the interval it was written with: an
    // interval changed for the restart (an output switched on) starts from the clock, not from the past.
    for (Cadence* c : {&s.series, &s.snapshots, &s.checkpoints}) c->skipPast(run.clock(), 0.5 * run.clockStep());
    report.restartedAt = run.steps();
    logger(s.label)->info("restarted from {} at {} {} (clock {:.6g})", restart.string(), s.stepName, run.steps(),
                          run.clock());
  }
  Display display(run, s);
  const auto start = Clock::now();
  const std::int64_t firstStep = run.steps();
  try {
    if (!from) outputsDue();
    while (!run.finished()) {
      run.step();
      display.update();
      if (run.finished()) break;
      outputsDue();
      if (s.checkpoints.due(run.clock(), 0.5 * run.clockStep())) {
        s.checkpoints.advance();
        run.writeCheckpoint(s.checkpointFile, s.kind, archive);
        ++report.checkpoints;
      }
    }
    // The last state: where its time falls due, or where the run always keeps it.
    const double half = 0.5 * run.clockStep();
    if (seriesStep != run.steps() && (s.series.due(run.clock(), half) || s.seriesAtEnd)) writeSeries(SeriesRow::kLast);
    if (snapshotStep != run.steps() && (s.snapshots.due(run.clock(), half) || s.snapshotAtEnd))
      writeSnapshot(true);
  } catch (const SimulationError&) {
    // The state that failed the check goes into the series too (what the summary's peaks saw), unless it
    // is not finite: then the writer refuses the row and the last finite one stays the last. Only a state
    // the run reached (a step that failed before it counted left none) and where the adapter can write.
    if (run.steps() > firstStep && seriesStep != run.steps() && run.canWriteFailedState()) try {
        writeSeries(SeriesRow::kFailed);
      } catch (const SimulationError&) {
      }
    if (results) results->flush();
    summary.setSteps(run.steps());
    run.report(summary, since(start), true);
    throw;
  }
  display.finish();
  report.loopSeconds = since(start);
  if (results) results->flush();
  summary.setSteps(run.steps());
  run.report(summary, report.loopSeconds, false);
  if (s.checkpoints.on()) summary.setCost("checkpoints_written", report.checkpoints);
  if (!restart.empty()) summary.setCost("restarted_from", restart.string());
  if (report.restartedAt >= 0) summary.setCost("restarted_at_" + s.stepName, report.restartedAt);
  return report;
}

}  // namespace common
