#pragma once
// Logging on spdlog: one console sink (stderr) and, for a run, a log file in its results folder.
// Every part asks for a named logger ("dem", "fem.static", "cosim.mapping"); all share the sinks, so
// the run log interleaves them with their names. Libraries log through these, never std::cout.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace common {

/// (Re)configures the shared sinks: console at info (warn when `quiet`), plus `runLog` at debug when
/// non-empty (its folder is created). Loggers created before stay valid and pick up the new sinks.
/// `append`: a restarted run adds to the log of the run it continues.
void setupLogging(const std::filesystem::path& runLog, bool quiet, bool append = false);

/// The logger named `name`, created on first use with the shared sinks.
std::shared_ptr<spdlog::logger> logger(const std::string& name);

/// Progress of a long run in simulated time. On a terminal it redraws one status line on stderr at
/// most 5 times a second; otherwise it logs a line every `logEvery` of wall time. update() is cheap
/// enough to call every step (it reads the clock only every 64 calls).
class Progress {
 public:
  Progress(std::string label, double endTime, bool enabled = true,
           std::chrono::duration<double> logEvery = std::chrono::seconds(10));
  ~Progress();
  void update(double time, std::int64_t steps);
  /// Ends the status line and logs the totals.
  void finish(double time, std::int64_t steps);

  /// "t = 0.15 / 0.3 s (50.0 %), 2000 steps, 1.00e+03 steps/s, ETA 2 s": the text of one update.
  static std::string format(double time, double endTime, std::int64_t steps, double elapsedSeconds);

 private:
  std::string label_;
  double endTime_;
  bool enabled_;
  bool terminal_;
  bool lineOpen_ = false;
  std::chrono::duration<double> logEvery_;
  std::chrono::steady_clock::time_point start_, lastPrint_;
  std::uint32_t calls_ = 0;
};

}  // namespace common
