#pragma once
// Scene reading on yaml-cpp with located errors.
//
// A Config is a cheap, copyable view of one node of a loaded scene tree. Every node remembers the
// file, line and column it came from (also across `include:` and `--set`), and every map remembers
// which keys the program asked for. After a solver has read its scene it calls checkUnknownKeys():
// any key that is present but was never asked for is reported as unknown, with a "did you mean"
// suggestion taken from the keys that were asked for at the same place.
//
// Scene features:
//   include: other.yaml          (or a list) in any map: the included file's map is the base, the keys
//                                written beside `include:` override it (maps merge deeply). Paths are
//                                relative to the including file.
//   --set a.b[2].c=VALUE         override any key; VALUE is YAML (`1e-5`, `[0, 0, -9.81]`, `hertz`);
//                                `--set a.b=null` removes the key.
//
// Errors are common::ConfigError whose message has the shape
//   `dem.dt = "abc" (configs/dem/bounce.yaml:4:7): expected a number.`
// Thread safety: none; read scenes on one thread.

#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/errors.hpp"

namespace common {

/// Where a value was written. line and column are 1-based; line 0 means "no line" (e.g. --set).
struct Location {
  std::string file;
  int line = 0;
  int column = 0;
  std::string str() const;  ///< "file:line:column", or "file" when line is 0
};

/// An interval for range-checked getters. Factories say which ends are open.
struct Interval {
  double lo;
  double hi;
  bool loOpen;
  bool hiOpen;
  static Interval open(double lo, double hi) { return {lo, hi, true, true}; }
  static Interval closed(double lo, double hi) { return {lo, hi, false, false}; }
  static Interval positive() { return {0.0, kInf, true, true}; }
  static Interval nonNegative() { return {0.0, kInf, false, true}; }
  static Interval greaterThan(double lo) { return {lo, kInf, true, true}; }
  bool contains(double v) const;
  std::string str() const;  ///< "(0, inf)", "[-1, 0.5)"

  static constexpr double kInf = std::numeric_limits<double>::infinity();
};

/// The closest candidate to `word` by edit distance, if it is close enough to be a plausible typo.
std::optional<std::string> suggest(std::string_view word, const std::vector<std::string>& candidates);

class Config;
/// What requireWholeSteps counts: the step's name and key, the words for them, the count allowed.
struct WholeSteps {
  const char* dtKey = "dt";      ///< the key of the step, named in the fix
  const char* step = "step";     ///< one step, in counts ("3 steps")
  const char* what = "steps";    ///< in "is not a whole number of …"
  double limit = 1e12;           ///< requireStepCount's limit
};
/// A run ends at `endTime` exactly or not at all (a last step cut short would break a leapfrog): a
/// ConfigError at `owner.key` unless endTime is a whole number (at least one) of steps of dt, naming the
/// two nearest end times and the step that would divide it; first requireStepCount at `dtKey`.
void requireWholeSteps(const Config& owner, std::string_view key, double endTime, double dt, const WholeSteps& w = {});
/// A step count endTime / dt (of `step`s: "step", "window") above `limit` is a ConfigError at `key` of
/// `owner`: 10¹² steps overflow no counter, but no run finishes them (a dt of 1e-300 s used to wrap the
/// step count to a negative number and end "ok" after none).
void requireStepCount(const Config& owner, std::string_view key, double endTime, double dt, double limit = 1e12,
                      const char* step = "step");

namespace detail {
struct ConfigNode;
}

class Config {
 public:
  /// Reads `file` (resolving includes), then applies `overrides` ("key.path=value"). Throws
  /// ConfigError for unreadable files, YAML syntax errors, include cycles and malformed overrides.
  static Config load(const std::filesystem::path& file, const std::vector<std::string>& overrides = {});
  /// The same from text; `name` stands for the file name in messages, `baseDir` resolves includes.
  static Config parse(const std::string& text, const std::string& name = "<string>",
                      const std::filesystem::path& baseDir = ".",
                      const std::vector<std::string>& overrides = {});

  Config() = default;
  bool valid() const { return node_ != nullptr; }
  explicit operator bool() const { return valid(); }
  bool isMap() const;
  bool isSequence() const;
  bool isScalar() const;
  bool isNull() const;

  /// Dotted key path of this node from the root ("dem.walls[2].type"; "" for the root).
  const std::string& path() const { return path_; }
  /// Where this node's value was written.
  Location location() const;
  /// The file the root was loaded from.
  const std::filesystem::path& sceneFile() const;

  /// True when `key` is present. Asking marks the key as known.
  bool has(std::string_view key) const;
  /// The sub-node `key`; ConfigError when missing.
  Config at(std::string_view key) const;
  /// The sub-node `key`, or an invalid Config when missing.
  Config child(std::string_view key) const;

  template <class T>
  T get(std::string_view key) const {
    return at(key).as<T>();
  }
  template <class T>
  T get(std::string_view key, const T& fallback) const {
    Config c = child(key);
    return c.valid() && !c.isNull() ? c.as<T>() : fallback;
  }
  template <class T>
  std::optional<T> find(std::string_view key) const {
    Config c = child(key);
    if (!c.valid() || c.isNull()) return std::nullopt;
    return c.as<T>();
  }
  /// Range-checked numbers: the message names the value, the location and the interval.
  double get(std::string_view key, const Interval& range) const;
  double get(std::string_view key, double fallback, const Interval& range) const;
  /// A name from a closed list ("type: hertz_mindlin"); unknown names get a "did you mean".
  std::string choice(std::string_view key, const std::vector<std::string>& allowed) const;
  std::string choice(std::string_view key, const std::vector<std::string>& allowed,
                     const std::string& fallback) const;
  /// A file path written under `key`, resolved relative to the file that wrote it.
  std::filesystem::path filePath(std::string_view key) const;

  /// This node's value. Supported: bool, int, long, std::size_t, double, std::string,
  /// std::vector<double|int|std::string>, Eigen::Vector3d.
  template <class T>
  T as() const;

  /// Elements of a sequence (ConfigError if this is not a sequence).
  std::vector<Config> elements() const;
  /// Entries of a map in file order; all its keys count as known (for user-named maps).
  std::vector<std::pair<std::string, Config>> entries() const;

  /// Throws ConfigError "path = value (loc): message".
  [[noreturn]] void fail(const std::string& message) const;
  /// Throws ConfigError located at `key` of this map (at this map when `key` is absent).
  [[noreturn]] void failAt(std::string_view key, const std::string& message) const;

  /// Throws one ConfigError listing every key below this node that was present but never asked for.
  void checkUnknownKeys() const;
  /// Every key path the program asked for, present in the scene or not, list indices as `[]`
  /// (`walls[].normal`): what a solver reads, for the test that every key is documented.
  std::vector<std::string> askedKeys() const;

 private:
  Config(std::shared_ptr<detail::ConfigNode> node, std::shared_ptr<const std::filesystem::path> scene,
         std::string path)
      : node_(std::move(node)), scene_(std::move(scene)), path_(std::move(path)) {}
  std::string describe() const;  // "path = value (loc)"
  std::string childPath(std::string_view key) const;

  std::shared_ptr<detail::ConfigNode> node_;
  std::shared_ptr<const std::filesystem::path> scene_;
  std::string path_;
};

template <>
bool Config::as<bool>() const;
template <>
int Config::as<int>() const;
template <>
long Config::as<long>() const;
template <>
std::size_t Config::as<std::size_t>() const;
template <>
double Config::as<double>() const;
template <>
std::string Config::as<std::string>() const;
template <>
std::vector<double> Config::as<std::vector<double>>() const;
template <>
std::vector<int> Config::as<std::vector<int>>() const;
template <>
std::vector<std::string> Config::as<std::vector<std::string>>() const;
template <>
Eigen::Vector3d Config::as<Eigen::Vector3d>() const;

}  // namespace common
