#pragma once
// The three error tiers, and the process exit codes.
//
//   ConfigError      bad user input; carries the file:line:column and key path in its message. Exit 2.
//   SimulationError  a failure found while running (instability, I/O, coupling). Exit 3 or 4.
//   COSIM_ASSERT     a bug in this code: expression and values; compiled in for Debug and CI builds.

#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace common {

/// Process exit codes shared by every executable.
enum class ExitCode : int {
  kOk = 0,
  kBadInput = 2,     ///< scene or command-line error
  kInstability = 3,  ///< numerical instability or other runtime failure of the physics
  kCoupling = 4,     ///< participant died, timeout, protocol error
};

/// User-input error. The message is complete: what, where (file:line:column, key path), observed vs
/// allowed, how to fix. Thrown by the scene reader and by solvers validating their scene.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Runtime failure. `code` selects the exit code (kInstability or kCoupling).
class SimulationError : public std::runtime_error {
 public:
  explicit SimulationError(const std::string& what, ExitCode code = ExitCode::kInstability)
      : std::runtime_error(what), code_(code) {}
  ExitCode code() const { return code_; }

 private:
  ExitCode code_;
};

/// A run that went numerically wrong: what diverged, where, when, the evidence, and a fix
/// the user can apply (a computed dt or window, not generic advice). Exit 3. The executable writes the
/// fields under `failure:` in summary.yaml, so drivers read the cause without parsing log text.
struct Instability {
  std::string cause;     ///< what diverged: "energy growth", "non-finite state", …
  std::string where;     ///< body / element / interface node, e.g. "body 0"
  double time = 0.0;     ///< simulated time at detection [s]
  std::string evidence;  ///< the numbers that show it, observed vs allowed
  std::string fix;       ///< what to change, with a computed value
};

class InstabilityError : public SimulationError {
 public:
  explicit InstabilityError(Instability i)
      : SimulationError(fmt::format("numerical instability: {} at {}, t = {:.6g} s: {}. Fix: {}", i.cause, i.where,
                                    i.time, i.evidence, i.fix)),
        info_(std::move(i)) {}
  const Instability& info() const { return info_; }

 private:
  Instability info_;
};

/// Thrown by COSIM_ASSERT: a bug, not a user error.
class AssertionError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

}  // namespace common

#if defined(COSIM_ENABLE_ASSERTS)
#define COSIM_ASSERT(cond, ...)                                                                  \
  do {                                                                                           \
    if (!(cond))                                                                                 \
      throw ::common::AssertionError(::fmt::format("{}:{}: assertion `{}` failed: {}", __FILE__, \
                                                   __LINE__, #cond, ::fmt::format(__VA_ARGS__))); \
  } while (false)
#else
#define COSIM_ASSERT(cond, ...) \
  do {                          \
  } while (false)
#endif
