#pragma once
// The standalone run loop: what every solver run on its own shares, as the window loop
// (cosim/window_loop.hpp) is what every coupled participant shares. A solver supplies an adapter, a
// SteppedRun; the loop owns the rest:
//
//   - stepping until the adapter says the run reached its end (whole steps: the adapter's clock);
//   - the output schedule, one rule for series, snapshots and checkpoints (Cadence): an output falls
//     due once the clock is within half a step of its time; the run's last state is written once more
//     where the settings ask (atEnd), never twice;
//   - on-disk checkpoints (the loop's schedule and the adapter's state, with the results file's extent)
//     and --restart from one;
//   - the progress display;
//   - a failed check (common::SimulationError, exit 3): the failed state joins the series if it is
//     new and finite, the adapter reports what it measured so far, the results are flushed, and the
//     error goes on to runApp;
//   - the summary's steps and the cost section's checkpoint and restart entries.
//
// A time-stepped run's clock is the time; a quasi-static one's is its load (the lattice's increments,
// the triaxial test's axial strain). One step of the loop is one call of SteppedRun::step().

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "common/h5_writer.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"

namespace common {

/// An output made at intervals of the run's clock, from `first` on (0 interval: never).
class Cadence {
 public:
  Cadence() = default;
  Cadence(double interval, double first) : interval_(interval), next_(first) {}
  /// Every `interval` from the start: the first at the run's start.
  static Cadence every(double interval) { return {interval, 0.0}; }
  /// Every `interval`, the first one interval in.
  static Cadence after(double interval) { return {interval, interval}; }

  bool on() const { return interval_ > 0; }
  /// After a restart: a next time left behind the clock (an interval changed since the checkpoint) moves
  /// to the first one past it.
  void skipPast(double clock, double halfStep) {
    if (on() && next_ < clock - halfStep) next_ += std::ceil((clock - halfStep - next_) / interval_) * interval_;
  }
  /// Due once `clock` is within `halfStep` (half the clock's step) of the next output's time.
  bool due(double clock, double halfStep) const { return on() && clock + halfStep >= next_; }
  void advance() { next_ += interval_; }
  double next() const { return next_; }
  void archive(StateArchive& a) { a.io("next", next_); }

 private:
  double interval_ = 0.0, next_ = 0.0;
};

/// Why a series row is written: its time fell due, the run's last state, or the state that failed a check.
enum class SeriesRow { kScheduled, kLast, kFailed };

/// A standalone run, as the loop drives it.
class SteppedRun {
 public:
  virtual ~SteppedRun() = default;
  /// The run's clock (time [s], or its load's measure) and by how much the next step advances it.
  virtual double clock() const = 0;
  virtual double clockStep() const = 0;
  virtual std::int64_t steps() const = 0;
  /// Whether the run reached its end (then it takes no further step).
  virtual bool finished() const = 0;
  /// One step, with the checks it makes: a failed one throws common::SimulationError.
  virtual void step() = 0;
  /// A row of the series, a snapshot of the fields: of the current state, the run's last when `last`.
  virtual void writeSeries(SeriesRow row) = 0;
  virtual void writeSnapshot(bool last) = 0;
  /// Whether the state that failed a check may be written (a run on several ranks: only where every rank
  /// failed together, as the row is gathered from all).
  virtual bool canWriteFailedState() const { return true; }
  /// Everything the adapter carries from step to step, written and read by one function.
  virtual void archive(StateArchive& a) = 0;
  /// A checkpoint, `fill` writing the loop's part and archive(): one file by default; a run on several
  /// ranks writes one per rank.
  virtual void writeCheckpoint(const std::filesystem::path& file, const std::string& kind,
                               const std::function<void(StateArchive&)>& fill) {
    StateArchive::write(file, kind, fill);
  }
  /// What the run measured: at its end, or so far at a failed check (`failed`); `loopSeconds`, the wall
  /// time of the stepping so far.
  virtual void report(Summary& summary, double loopSeconds, bool failed) = 0;
  /// A status line for the progress display, logged every 10 s of wall time; empty (from the start): the
  /// loop's own (clock, steps, rate, ETA, common::Progress), which reads the clock every 64 steps and so
  /// suits time steps, not increments of minutes each.
  virtual std::string status() const { return {}; }
};

/// The kind of a standalone run's checkpoint (StateArchive kind) by `program`: it names the loop's layout
/// too, so a checkpoint of another layout is refused when the results are opened, before anything of them
/// is cut back (common::openResults).
inline std::string standaloneKind(const std::string& program) { return program + " standalone (run loop 1)"; }

struct RunLoopSettings {
  std::string label;            ///< the progress display's and the log's name: dem, fem, lattice, …
  std::string kind;             ///< the checkpoint's writer (StateArchive kind)
  double end = 0.0;             ///< the clock at the end, for the progress display
  std::string stepName = "step";  ///< what a step is called in the cost section (restarted_at_<name>)
  Cadence series, snapshots, checkpoints;
  bool seriesAtEnd = false, snapshotAtEnd = false;  ///< the last state written whatever the cadence
  std::filesystem::path checkpointFile;
  bool progress = true;
};

struct RunLoopReport {
  double loopSeconds = 0.0;  ///< wall time of the stepping, outputs included
  std::int64_t checkpoints = 0;
  std::int64_t restartedAt = -1;  ///< the step a restart continued from; -1: a fresh run
};

/// Runs `run` to its end. `results` is the run's results file (its extent goes into every checkpoint;
/// nullptr on a rank that writes none);
/// `from`, when set, the checkpoint --restart named (`restart`, its path, for the log and the summary).
/// The adapter's report goes into `summary` at the end and at a failed check, which is rethrown.
RunLoopReport runLoop(SteppedRun& run, RunLoopSettings settings, H5Writer* results, std::optional<StateArchive>& from,
                      const std::filesystem::path& restart, Summary& summary);

}  // namespace common
