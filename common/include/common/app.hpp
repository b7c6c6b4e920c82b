#pragma once
// The command line and the run frame every executable shares:
//
//   NAME SCENE.yaml [--out DIR] [--set KEY.PATH=VALUE …] [--threads N] [--quiet] [--check]
//
// runApp parses that line with CLI11, loads the scene with its overrides, opens the run log
// (DIR/NAME.log), calls the solver's `run`, and always ends by writing DIR/summary.yaml with the
// status and exit code, also when `run` throws. Exit codes: 0 ok, 2 ConfigError (or a bad command
// line), 3 SimulationError (instability), 4 SimulationError with ExitCode::kCoupling, 1 a bug.

#include <filesystem>
#include <optional>
#include <functional>
#include <string>
#include <vector>

#include "common/config.hpp"
#include "common/summary.hpp"

namespace CLI {
class App;
}

namespace common {

struct RunOptions {
  std::filesystem::path scenePath;
  std::filesystem::path outDir;  ///< default: results/<scene stem>
  std::vector<std::string> overrides;
  int threads = 0;  ///< 0: OpenMP's default
  bool quiet = false;
  bool check = false;  ///< validate the scene and exit without running or writing results
  /// --restart [FILE]: continue from an on-disk checkpoint written by the same scene's earlier run,
  /// appending to the results folder's files (a solver: the checkpoint FILE; cosim: the last one in
  /// --out). Not set: start from the beginning.
  std::optional<std::filesystem::path> restart;
};

/// A run that cannot continue from a checkpoint (`what`: "a standalone run", …) refuses --restart with a
/// ConfigError (exit 2) instead of silently starting over.
void refuseRestart(const RunOptions& options, const std::string& what);
/// A solver's --restart [FILE]: the file (empty: no restart). --restart alone means `standalone`, the
/// file a standalone run's checkpoints go to (written when the scene sets `key`); without one (a coupled
/// run) it is a ConfigError.
std::filesystem::path restartFile(const RunOptions& options, const std::filesystem::path& standalone = {},
                                  const std::string& key = "output.checkpoint_interval");

/// What `run` gets: the parsed options, the loaded scene, and the summary to fill.
struct RunContext {
  RunOptions options;
  Config scene;
  Summary summary;
};

struct AppInfo {
  std::string name;         ///< executable name, also the run log's name
  std::string description;  ///< one line for --help
  std::string version;
  /// A folder inside --out for this process's log and summary, its console quiet: one rank of a run on
  /// several (rank_N); empty: --out itself.
  std::string ownFolder = {};
};

/// Runs one executable. `addOptions` may add options of its own to the CLI11 app before parsing;
/// `run` builds and runs the scene (in check mode: builds and returns). Returns the exit code.
int runApp(int argc, const char* const* argv, const AppInfo& info, const std::function<void(CLI::App&)>& addOptions,
           const std::function<void(RunContext&)>& run);

}  // namespace common
