#pragma once
// Starting and stopping the participant processes of a coupled run. Every process started here ends
// when the run ends, whatever it does: SIGTERM, then SIGKILL after a bounded grace (a process that
// ignores SIGTERM or was stopped with SIGSTOP is not waited for forever).

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace cosim {

struct LaunchRequest {
  std::vector<std::string> argv;       ///< program (searched on PATH unless it has a slash) and arguments
  std::filesystem::path workDir;       ///< where it starts
  std::filesystem::path console;       ///< stdout and stderr go here
  std::vector<std::string> extraEnv;   ///< NAME=VALUE added to (or replacing in) this process's environment
};

/// How a process ended.
struct ProcessEnd {
  bool exited = false;  ///< false: killed by `signal`
  int code = 0, signal = 0;
  std::string describe() const;  ///< "exited with code 3" / "was killed by signal 9 (Killed)"
};

/// Starts the process; throws std::runtime_error with the OS's reason when it cannot.
pid_t launch(const LaunchRequest& request);

/// The process's end if it has ended (it is then reaped), else nothing. Never blocks.
std::optional<ProcessEnd> pollExit(pid_t pid);

/// Waits up to `patience` for the process to end by itself; its end, or nothing if it still runs.
std::optional<ProcessEnd> waitExit(pid_t pid, std::chrono::milliseconds patience);

/// Ends the process: SIGTERM (with SIGCONT, so a stopped process can act on it), then SIGKILL if it is
/// still there after `grace`. Returns how it ended; always reaps it.
ProcessEnd stop(pid_t pid, std::chrono::milliseconds grace);

}  // namespace cosim
