#pragma once
// The three error tiers, and the process exit codes.
//
//   ConfigError      bad user input; carries the file:line:column and key path in its message. Exit 2.
//   SimulationError  a failure found while running (instability, I/O, coupling). Exit 3 or 4.
//   COSIM_ASSERT     a bug in this code: expression and values; compiled in for Debug and CI builds.

#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

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
  std::string cause;     ///< what diverged, named by its sign: "energy growth", "energy loss", …
  std::string where;     ///< body / element / interface node, e.g. "body 0"
  double time = 0.0;     ///< simulated time at detection [s]
  std::string evidence;  ///< the numbers that show it, observed vs allowed
  std::string fix;       ///< what to change, with a computed value
  /// The fix's first alternative as scene settings (`KEY=VALUE`, as `--set` takes them), printed and
  /// written as `failure.fix_settings` exactly as the rerun needs them; empty when no setting is the fix
  /// (a finer mesh, another material law). Values are rounded towards safety (fixedDown).
  std::vector<std::string> settings = {};
};

/// `x` with `digits` significant digits, rounded towards zero: a step, window, tolerance or relaxation
/// printed as a fix must not exceed the value computed as safe.
inline double fixedDown(double x, int digits = 3) {
  if (!(x > 0) || !std::isfinite(x)) return x;
  const double scale = std::pow(10.0, std::floor(std::log10(x)) - (digits - 1));
  return std::floor(x / scale) * scale;
}

/// A fix's value as printed, in its text and in its settings alike: fixedDown to three digits
/// (fixValue(2.8056e-6) == "2.8e-06").
inline std::string fixValue(double x) { return fmt::format("{:.3g}", fixedDown(x)); }

/// A step for `span` seconds in whole steps, at most `safe` and at least 0.8 × it where possible,
/// printed with the fewest digits that keep the count whole (within 1e-7 steps): a fix that the scene's
/// end_time check accepts as printed (0.01618 s and a safe 3.46e-5 s give 3.236e-05, 500 steps).
/// `span` ≤ 0: fixedDown(safe) to three digits.
inline std::string wholeStepValue(double span, double safe) {
  if (!(span > 0) || !(safe > 0)) return fixValue(safe);
  for (int digits = 3; digits <= 6; ++digits) {
    const double scale = std::pow(10.0, std::floor(std::log10(safe)) - (digits - 1));
    for (double k = std::floor(safe / scale); k * scale >= 0.8 * safe; --k) {
      const std::string text = fmt::format("{:.{}g}", k * scale, digits);
      const double v = std::stod(text), steps = span / v;
      if (v <= safe && std::abs(steps - std::round(steps)) <= 1e-7) return text;
    }
  }
  const double n = std::ceil(span / safe);
  for (int digits = 7; digits <= 17; ++digits) {
    const std::string text = fmt::format("{:.{}g}", span / n, digits);
    const double v = std::stod(text);
    if (v <= safe && std::abs(span / v - n) <= 1e-7) return text;
  }
  return fmt::format("{:.17g}", span / n);
}

/// How an instability's message ends with its settings: kRerunWith A kSetSeparator B …
inline constexpr std::string_view kRerunWith = " — rerun with --set ", kSetSeparator = " --set ";

/// " — rerun with --set A --set B" for an instability's settings ("" when there are none).
inline std::string rerunWith(const std::vector<std::string>& settings) {
  std::string s;
  for (const auto& v : settings) s += std::string(s.empty() ? kRerunWith : kSetSeparator) + v;
  return s;
}

class InstabilityError : public SimulationError {
 public:
  explicit InstabilityError(Instability i)
      : SimulationError(fmt::format("numerical instability: {} at {}, t = {:.6g} s: {}. Fix: {}{}", i.cause, i.where,
                                    i.time, i.evidence, i.fix, rerunWith(i.settings))),
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
