#pragma once
// summary.yaml of a run: scene, status, exit_code, wall_time_s, steps, results.
// Tests, studies and benchmarks read results from here, never from log text.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/errors.hpp"

namespace common {

class StateArchive;

/// `text` with every byte that is not part of well-formed UTF-8 written as `\xNN`: what a peer or a file
/// sent may be quoted in a summary (which must stay valid YAML) or an ERROR message (shown as text).
std::string cleanUtf8(std::string_view text);

class Summary {
 public:
  using Value = std::variant<double, std::int64_t, std::string, std::vector<double>>;

  void setScene(std::string scene) { scene_ = std::move(scene); }
  void setSteps(std::int64_t steps) { steps_ = steps; }
  /// A key result, under `results:`; the names are those the scene documents in its header comment.
  void set(const std::string& key, Value value) { results_[key] = std::move(value); }
  bool has(const std::string& key) const { return results_.count(key) != 0; }
  const std::map<std::string, Value>& results() const { return results_; }

  /// What the run cost and which physics it paid for, under `cost:` (processes, threads, peak memory,
  /// output bytes, time per step and phase, the physics enabled and left out): what a scene pays for,
  /// shown per run.
  void setCost(const std::string& key, Value value) { cost_[key] = std::move(value); }
  const std::map<std::string, Value>& cost() const { return cost_; }
  /// What a run reported so far, written into a checkpoint or read back (a restart keeps what the run
  /// measured before it, such as its static start).
  void archive(StateArchive& a);

  /// A failed run's diagnosis, written as the `failure:` map (cause, where, time, evidence, fix).
  void setFailure(const Instability& failure) { failure_ = failure; hasFailure_ = true; }
  bool hasFailure() const { return hasFailure_; }

  /// Writes the file atomically (temporary file + rename). `status` is "ok" or the error text. A result
  /// that is not finite is left out and named under `nonfinite_results` (a summary never holds a NaN).
  void write(const std::filesystem::path& file, ExitCode code, const std::string& status, double wallTimeS) const;

 private:
  std::string scene_;
  std::int64_t steps_ = 0;
  std::map<std::string, Value> results_;
  std::map<std::string, Value> cost_;
  Instability failure_;
  bool hasFailure_ = false;
};

}  // namespace common
