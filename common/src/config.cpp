#include "common/config.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

namespace common {

namespace fs = std::filesystem;

namespace detail {

// Our own tree rather than YAML::Node: yaml-cpp nodes do not know their file, cannot be merged with
// provenance kept, and have no place to record which keys the program asked for.
struct ConfigNode {
  enum class Kind { kNull, kScalar, kMap, kSequence };
  Kind kind = Kind::kNull;
  std::string scalar;  // raw text of a scalar (converted on demand by yaml-cpp)
  std::vector<std::pair<std::string, std::shared_ptr<ConfigNode>>> map;  // file order
  std::vector<Location> keyLocations;                                     // parallel to map
  std::vector<std::shared_ptr<ConfigNode>> sequence;
  Location location;
  std::set<std::string, std::less<>> asked;  // keys the program asked about, present or not
  bool allKnown = false;                     // set by entries(): user-named keys

  std::shared_ptr<ConfigNode> find(std::string_view key) const {
    for (const auto& [k, v] : map)
      if (k == key) return v;
    return nullptr;
  }
  void set(const std::string& key, std::shared_ptr<ConfigNode> value, const Location& keyLoc) {
    for (std::size_t i = 0; i < map.size(); ++i)
      if (map[i].first == key) {
        map[i].second = std::move(value);
        keyLocations[i] = keyLoc;
        return;
      }
    map.emplace_back(key, std::move(value));
    keyLocations.push_back(keyLoc);
  }
  void erase(std::string_view key) {
    for (std::size_t i = 0; i < map.size(); ++i)
      if (map[i].first == key) {
        map.erase(map.begin() + static_cast<std::ptrdiff_t>(i));
        keyLocations.erase(keyLocations.begin() + static_cast<std::ptrdiff_t>(i));
        return;
      }
  }
};

}  // namespace detail

using detail::ConfigNode;
using NodePtr = std::shared_ptr<ConfigNode>;

namespace {

Location markLocation(const std::string& file, const YAML::Mark& mark) {
  return {file, mark.line + 1, mark.column + 1};
}

std::string quoteScalar(const std::string& s) {
  // Show numbers and names plainly, anything with spaces or empty quoted.
  if (s.empty() || s.find_first_of(" \t:#") != std::string::npos) return fmt::format("\"{}\"", s);
  return s;
}

std::string kindName(ConfigNode::Kind k) {
  switch (k) {
    case ConfigNode::Kind::kNull: return "nothing (null)";
    case ConfigNode::Kind::kScalar: return "a scalar";
    case ConfigNode::Kind::kMap: return "a map";
    case ConfigNode::Kind::kSequence: return "a list";
  }
  return "?";
}

// Deep merge: `over` wins; maps merge key by key. A key that `over` sets to null is removed from what
// it includes (as `--set key=null` removes it): a scene can drop an included key it does not want.
NodePtr merge(const NodePtr& base, const NodePtr& over) {
  if (base->kind != ConfigNode::Kind::kMap || over->kind != ConfigNode::Kind::kMap) return over;
  auto out = std::make_shared<ConfigNode>(*base);
  out->location = over->location;
  for (std::size_t i = 0; i < over->map.size(); ++i) {
    const auto& [key, value] = over->map[i];
    NodePtr existing = out->find(key);
    if (existing && value->kind == ConfigNode::Kind::kNull) {
      out->erase(key);
      continue;
    }
    out->set(key, existing ? merge(existing, value) : value, over->keyLocations[i]);
  }
  return out;
}

class TreeBuilder {
 public:
  NodePtr loadFile(const fs::path& file, const Location& from) {
    const std::string where = from.file.empty() ? std::string() : from.str() + ": ";
    // A name the file system refuses (too long, …) is an input error, not a filesystem_error that ends
    // the program (found by fuzz_cluster); a device or a folder is not a scene file (an include of
    // /dev/zero would read forever).
    std::error_code ec;
    fs::path canonical = fs::weakly_canonical(file, ec);
    if (ec)
      throw ConfigError(fmt::format("{}cannot open scene file \"{}\" ({}).", where, file.string(), ec.message()));
    if (std::find(stack_.begin(), stack_.end(), canonical) != stack_.end())
      throw ConfigError(fmt::format("{}: include cycle: {} includes itself (via {}).", from.str(),
                                    file.string(), chain()));
    if (fs::exists(file, ec) && !fs::is_regular_file(file, ec))
      throw ConfigError(fmt::format("{}\"{}\" is not a regular file.", where, file.string()));
    std::ifstream in(file);
    if (!in) {
      throw ConfigError(fmt::format("{}cannot open scene file \"{}\" ({}).", where, file.string(),
                                    std::error_code(errno, std::generic_category()).message()));
    }
    std::stringstream text;
    text << in.rdbuf();
    stack_.push_back(canonical);
    NodePtr root = parseText(text.str(), file.string(), file.parent_path());
    stack_.pop_back();
    return root;
  }

  NodePtr parseText(const std::string& text, const std::string& name, const fs::path& baseDir) {
    budget_ += 2 * text.size();
    YAML::Node doc;
    try {
      doc = YAML::Load(text);
    } catch (const YAML::ParserException& e) {
      throw ConfigError(fmt::format("{}: YAML syntax error: {}.", markLocation(name, e.mark).str(), e.msg));
    }
    if (!doc.IsDefined() || doc.IsNull()) {
      auto empty = std::make_shared<ConfigNode>();
      empty->kind = ConfigNode::Kind::kMap;
      empty->location = {name, 1, 1};
      return empty;
    }
    return build(doc, name, baseDir);
  }

 private:
  std::string chain() const {
    std::string s;
    for (const auto& p : stack_) s += (s.empty() ? "" : " -> ") + p.filename().string();
    return s;
  }

  NodePtr build(const YAML::Node& y, const std::string& file, const fs::path& baseDir) {
    // An *alias repeats its &anchor's whole tree, and nested aliases multiply: 1 KB of text can stand for
    // 10⁹ values ("billion laughs"). yaml-cpp shares the anchor; our tree would copy it, so the values
    // built are counted against a budget (50,000, plus two per character of the scene's text: the
    // largest shipped scene, a 22,000-sphere cluster, has 110,000) before anything large is allocated.
    if (++built_ > budget_)
      throw ConfigError(fmt::format("{}: the scene expands to more than {} values: *aliases repeat their &anchor's "
                                    "whole tree, and nested ones multiply. No scene needs this many; remove the "
                                    "aliases that repeat large parts.",
                                    markLocation(file, y.Mark()).str(), budget_));
    auto n = std::make_shared<ConfigNode>();
    n->location = markLocation(file, y.Mark());
    switch (y.Type()) {
      case YAML::NodeType::Null:
      case YAML::NodeType::Undefined: n->kind = ConfigNode::Kind::kNull; break;
      case YAML::NodeType::Scalar:
        n->kind = ConfigNode::Kind::kScalar;
        n->scalar = y.Scalar();
        break;
      case YAML::NodeType::Sequence:
        n->kind = ConfigNode::Kind::kSequence;
        for (const auto& e : y) n->sequence.push_back(build(e, file, baseDir));
        break;
      case YAML::NodeType::Map: {
        n->kind = ConfigNode::Kind::kMap;
        std::vector<NodePtr> includes;
        for (const auto& kv : y) {
          Location keyLoc = markLocation(file, kv.first.Mark());
          if (!kv.first.IsScalar())
            throw ConfigError(fmt::format("{}: map keys must be plain names.", keyLoc.str()));
          const std::string key = kv.first.Scalar();
          if (key == "include") {
            std::vector<YAML::Node> files;
            if (kv.second.IsSequence())
              for (const auto& f : kv.second) files.push_back(f);
            else
              files.push_back(kv.second);
            for (const auto& f : files) {
              Location at = markLocation(file, f.Mark());
              if (!f.IsScalar())
                throw ConfigError(fmt::format("{}: include expects a file name or a list of file names.",
                                              at.str()));
              fs::path p = f.Scalar();
              includes.push_back(loadFile(p.is_absolute() ? p : baseDir / p, at));
            }
            continue;
          }
          if (n->find(key))
            throw ConfigError(fmt::format("{}: key \"{}\" appears twice in the same map.", keyLoc.str(), key));
          n->set(key, build(kv.second, file, baseDir), keyLoc);
        }
        if (!includes.empty()) {
          NodePtr base = includes.front();
          for (std::size_t i = 1; i < includes.size(); ++i) base = merge(base, includes[i]);
          for (const auto& inc : includes)
            if (inc->kind != ConfigNode::Kind::kMap)
              throw ConfigError(fmt::format("{}: an included file must hold a map, found {}.",
                                            inc->location.str(), kindName(inc->kind)));
          NodePtr merged = merge(base, n);
          merged->location = n->location;
          return merged;
        }
        break;
      }
    }
    return n;
  }

  std::vector<fs::path> stack_;
  std::size_t built_ = 0, budget_ = 50'000;
};

struct PathStep {
  std::string key;       // map key, or empty for a sequence index
  std::ptrdiff_t index;  // sequence index when key is empty
};

std::vector<PathStep> splitPath(const std::string& path, const std::string& origin) {
  std::vector<PathStep> steps;
  std::size_t i = 0;
  while (i < path.size()) {
    std::size_t end = path.find_first_of(".[", i);
    std::string name = path.substr(i, end == std::string::npos ? std::string::npos : end - i);
    if (!name.empty()) steps.push_back({name, 0});
    if (end == std::string::npos) break;
    if (path[end] == '[') {
      std::size_t close = path.find(']', end);
      if (close == std::string::npos)
        throw ConfigError(fmt::format("{}: unclosed '[' in key path \"{}\".", origin, path));
      try {
        steps.push_back({"", std::stol(path.substr(end + 1, close - end - 1))});
      } catch (const std::exception&) {
        throw ConfigError(fmt::format("{}: \"{}\" is not a list index in key path \"{}\".", origin,
                                      path.substr(end + 1, close - end - 1), path));
      }
      i = close + 1;
      if (i < path.size() && path[i] == '.') ++i;
    } else {
      i = end + 1;
    }
  }
  if (steps.empty()) throw ConfigError(fmt::format("{}: empty key path.", origin));
  return steps;
}

// Values from the command line have no file line: every node of them points at the --set text.
void stampOrigin(ConfigNode& n, const std::string& origin) {
  n.location = {origin, 0, 0};
  for (auto& kl : n.keyLocations) kl = {origin, 0, 0};
  for (auto& kv : n.map) stampOrigin(*kv.second, origin);
  for (auto& e : n.sequence) stampOrigin(*e, origin);
}

void applyOverride(const NodePtr& root, const std::string& text) {
  const std::string origin = fmt::format("--set {}", text);
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError(fmt::format("{}: expected KEY.PATH=VALUE, e.g. --set dem.dt=1e-5.", origin));
  const std::string keyPath = text.substr(0, eq);
  auto steps = splitPath(keyPath, origin);
  TreeBuilder builder;
  NodePtr value = builder.parseText(text.substr(eq + 1), origin, fs::current_path());
  // An empty scene file is an empty map, but `--set key=` or `--set key=null` means "no value".
  if (YAML::Load(text.substr(eq + 1)).IsNull()) {
    value->kind = ConfigNode::Kind::kNull;
    value->map.clear();
    value->keyLocations.clear();
  }
  stampOrigin(*value, origin);

  NodePtr cur = root;
  std::string walked;
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const bool last = s + 1 == steps.size();
    const PathStep& st = steps[s];
    if (!st.key.empty()) {
      if (cur->kind == ConfigNode::Kind::kNull) cur->kind = ConfigNode::Kind::kMap;
      if (cur->kind != ConfigNode::Kind::kMap)
        throw ConfigError(fmt::format("{}: \"{}\" is {} in {}, so it has no key \"{}\".", origin,
                                      walked.empty() ? "the scene root" : walked, kindName(cur->kind),
                                      cur->location.str(), st.key));
      walked += (walked.empty() ? "" : ".") + st.key;
      NodePtr next = cur->find(st.key);
      if (last) {
        if (value->kind == ConfigNode::Kind::kNull) {  // --set key=null removes the key
          cur->erase(st.key);
          return;
        }
        cur->set(st.key, next ? merge(next, value) : value, {origin, 0, 0});
        return;
      }
      if (!next) {
        next = std::make_shared<ConfigNode>();
        next->kind = ConfigNode::Kind::kMap;
        next->location = {origin, 0, 0};
        cur->set(st.key, next, {origin, 0, 0});
      }
      cur = next;
    } else {
      if (cur->kind != ConfigNode::Kind::kSequence)
        throw ConfigError(fmt::format("{}: \"{}\" is {} in {}, not a list.", origin, walked,
                                      kindName(cur->kind), cur->location.str()));
      const auto n = static_cast<std::ptrdiff_t>(cur->sequence.size());
      if (st.index < 0 || st.index >= n)
        throw ConfigError(fmt::format("{}: index {} is out of range: \"{}\" has {} elements ({}).", origin,
                                      st.index, walked, n, cur->location.str()));
      walked += fmt::format("[{}]", st.index);
      if (last) {
        cur->sequence[static_cast<std::size_t>(st.index)] = value;
        return;
      }
      cur = cur->sequence[static_cast<std::size_t>(st.index)];
    }
  }
}

std::size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string fmtNumber(double v) {
  if (v >= Interval::kInf) return "inf";
  if (v <= -Interval::kInf) return "-inf";
  return fmt::format("{}", v);
}

}  // namespace

std::string Location::str() const {
  if (line <= 0) return file;
  return fmt::format("{}:{}:{}", file, line, column);
}

bool Interval::contains(double v) const {
  if (std::isnan(v)) return false;
  const bool aboveLo = loOpen ? v > lo : v >= lo;
  const bool belowHi = hiOpen ? v < hi : v <= hi;
  return aboveLo && belowHi;
}

std::string Interval::str() const {
  return fmt::format("{}{}, {}{}", loOpen ? '(' : '[', fmtNumber(lo), fmtNumber(hi), hiOpen ? ')' : ']');
}

void requireStepCount(const Config& owner, std::string_view key, double endTime, double dt, double limit,
                      const char* step) {
  const double steps = endTime / dt;
  if (steps <= limit) return;
  owner.failAt(key, fmt::format("gives {:.3g} {}s of {:.3g} s to end_time = {:.6g} s, more than the {:.0e} a run may take "
                                "(the count would overflow, or the run outlast any machine). Make the {} longer or "
                                "shorten end_time.",
                                steps, step, dt, endTime, limit, step));
}

void requireWholeSteps(const Config& owner, std::string_view key, double endTime, double dt, const WholeSteps& w) {
  requireStepCount(owner, w.dtKey, endTime, dt, w.limit, w.step);
  const double steps = endTime / dt;
  if (steps >= 1 - 1e-6 && std::abs(steps - std::round(steps)) <= 1e-6) return;
  const double above = std::max(1.0, std::ceil(steps)), below = std::floor(steps);
  owner.at(key).fail(fmt::format(
      "= {:.6g} s is not a whole number of {} of {} = {:.6g} s ({:.4f} {}s). Use {} = {:.6g} s ({} {}s){}, or {} = "
      "{:.6g} s ({} {}s).",
      endTime, w.what, w.dtKey, dt, steps, w.step, key, above * dt, above, w.step,
      below >= 1 ? fmt::format(" or {:.6g} s ({} {}s)", below * dt, below, w.step) : std::string(), w.dtKey,
      endTime / above, above, w.step));
}

std::optional<std::string> suggest(std::string_view word, const std::vector<std::string>& candidates) {
  std::optional<std::string> best;
  std::size_t bestDist = 0;
  for (const auto& c : candidates) {
    const std::size_t d = editDistance(word, c);
    if (!best || d < bestDist) {
      best = c;
      bestDist = d;
    }
  }
  if (!best) return std::nullopt;
  const std::size_t len = std::max(word.size(), best->size());
  const std::size_t allowed = len <= 4 ? 1 : len <= 8 ? 2 : 3;
  if (bestDist > allowed) return std::nullopt;
  return best;
}

Config Config::load(const fs::path& file, const std::vector<std::string>& overrides) {
  TreeBuilder builder;
  NodePtr root = builder.loadFile(file, {});
  for (const auto& o : overrides) applyOverride(root, o);
  return Config(root, std::make_shared<const fs::path>(file), "");
}

Config Config::parse(const std::string& text, const std::string& name, const fs::path& baseDir,
                     const std::vector<std::string>& overrides) {
  TreeBuilder builder;
  NodePtr root = builder.parseText(text, name, baseDir);
  for (const auto& o : overrides) applyOverride(root, o);
  return Config(root, std::make_shared<const fs::path>(name), "");
}

bool Config::isMap() const { return node_ && node_->kind == ConfigNode::Kind::kMap; }
bool Config::isSequence() const { return node_ && node_->kind == ConfigNode::Kind::kSequence; }
bool Config::isScalar() const { return node_ && node_->kind == ConfigNode::Kind::kScalar; }
bool Config::isNull() const { return node_ && node_->kind == ConfigNode::Kind::kNull; }

Location Config::location() const { return node_ ? node_->location : Location{}; }

const fs::path& Config::sceneFile() const {
  static const fs::path kNone;
  return scene_ ? *scene_ : kNone;
}

std::string Config::childPath(std::string_view key) const {
  return path_.empty() ? std::string(key) : fmt::format("{}.{}", path_, key);
}

std::string Config::describe() const {
  const std::string name = path_.empty() ? std::string("the scene root") : path_;
  if (node_ && node_->kind == ConfigNode::Kind::kScalar)
    return fmt::format("{} = {} ({})", name, quoteScalar(node_->scalar), node_->location.str());
  return fmt::format("{} ({})", name, location().str());
}

void Config::fail(const std::string& message) const { throw ConfigError(fmt::format("{}: {}", describe(), message)); }

void Config::failAt(std::string_view key, const std::string& message) const {
  Config c = child(key);
  if (c.valid()) c.fail(message);
  throw ConfigError(fmt::format("{} ({}): {}", childPath(key), location().str(), message));
}

bool Config::has(std::string_view key) const { return child(key).valid(); }

Config Config::child(std::string_view key) const {
  if (!node_) return {};
  if (node_->kind != ConfigNode::Kind::kMap) {
    if (node_->kind == ConfigNode::Kind::kNull) return {};
    fail(fmt::format("expected a map with the key \"{}\", found {}.", key, kindName(node_->kind)));
  }
  node_->asked.emplace(key);
  NodePtr n = node_->find(key);
  if (!n) return {};
  return Config(n, scene_, childPath(key));
}

Config Config::at(std::string_view key) const {
  Config c = child(key);
  if (!c.valid()) {
    std::vector<std::string> present;
    if (node_)
      for (const auto& kv : node_->map) present.push_back(kv.first);
    std::string hint;
    if (auto s = suggest(key, present)) hint = fmt::format(" Found \"{}\": did you mean \"{}\"?", *s, key);
    throw ConfigError(fmt::format("Missing required key \"{}\" in {} ({}).{}", childPath(key),
                                  path_.empty() ? std::string("the scene root") : path_, location().str(), hint));
  }
  return c;
}

namespace {
template <class T>
T convertScalar(const Config& c, const NodePtr& n, const char* expected) {
  if (!n || n->kind != ConfigNode::Kind::kScalar)
    c.fail(fmt::format("expected {}, found {}.", expected, n ? kindName(n->kind) : "nothing"));
  try {
    return YAML::Node(n->scalar).as<T>();
  } catch (const YAML::Exception&) {
    // A whole number too large for its type is not "not a whole number": say what the limit is.
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
      const std::string& text = n->scalar;
      const bool digits = !text.empty() && std::all_of(text.begin() + (text[0] == '-' || text[0] == '+'), text.end(),
                                                        [](char ch) { return ch >= '0' && ch <= '9'; });
      if (digits && text.size() > (text[0] == '-' || text[0] == '+' ? 1u : 0u))
        c.fail(fmt::format("is outside the range of whole numbers this key takes, [{}, {}].",
                           std::numeric_limits<T>::min(), std::numeric_limits<T>::max()));
    }
    c.fail(fmt::format("expected {}.", expected));
  }
}
}  // namespace

template <>
bool Config::as<bool>() const {
  return convertScalar<bool>(*this, node_, "true or false");
}
template <>
long Config::as<long>() const {
  return convertScalar<long>(*this, node_, "a whole number");
}
template <>
int Config::as<int>() const {
  return convertScalar<int>(*this, node_, "a whole number");
}
template <>
std::size_t Config::as<std::size_t>() const {
  const long v = convertScalar<long>(*this, node_, "a whole number >= 0");
  if (v < 0) fail("expected a whole number >= 0.");
  return static_cast<std::size_t>(v);
}
template <>
double Config::as<double>() const {
  const double v = convertScalar<double>(*this, node_, "a number");
  if (!std::isfinite(v)) fail("expected a finite number.");
  return v;
}
template <>
std::string Config::as<std::string>() const {
  if (!node_ || node_->kind != ConfigNode::Kind::kScalar)
    fail(fmt::format("expected a text value, found {}.", node_ ? kindName(node_->kind) : "nothing"));
  return node_->scalar;
}

namespace {
template <class T>
std::vector<T> asVector(const Config& c) {
  if (!c.isSequence()) c.fail("expected a list, e.g. [1, 2, 3].");
  std::vector<T> out;
  for (const auto& e : c.elements()) out.push_back(e.as<T>());
  return out;
}
}  // namespace

template <>
std::vector<double> Config::as<std::vector<double>>() const {
  return asVector<double>(*this);
}
template <>
std::vector<int> Config::as<std::vector<int>>() const {
  return asVector<int>(*this);
}
template <>
std::vector<std::string> Config::as<std::vector<std::string>>() const {
  return asVector<std::string>(*this);
}
template <>
Eigen::Vector3d Config::as<Eigen::Vector3d>() const {
  if (!isSequence() || node_->sequence.size() != 3)
    fail(fmt::format("expected a 3-vector [x, y, z], found {}.",
                     isSequence() ? fmt::format("a list of {} values", node_->sequence.size())
                                  : kindName(node_->kind)));
  auto e = elements();
  return {e[0].as<double>(), e[1].as<double>(), e[2].as<double>()};
}

double Config::get(std::string_view key, const Interval& range) const {
  Config c = at(key);
  const double v = c.as<double>();
  if (!range.contains(v)) c.fail(fmt::format("is outside {}.", range.str()));
  return v;
}

double Config::get(std::string_view key, double fallback, const Interval& range) const {
  Config c = child(key);
  if (!c.valid() || c.isNull()) return fallback;
  return get(key, range);
}

std::string Config::choice(std::string_view key, const std::vector<std::string>& allowed) const {
  Config c = at(key);
  const std::string v = c.as<std::string>();
  if (std::find(allowed.begin(), allowed.end(), v) != allowed.end()) return v;
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  std::string hint;
  if (auto s = suggest(v, allowed)) hint = fmt::format(" Did you mean \"{}\"?", *s);
  c.fail(fmt::format("unknown name; expected one of: {}.{}", list, hint));
}

std::string Config::choice(std::string_view key, const std::vector<std::string>& allowed,
                           const std::string& fallback) const {
  Config c = child(key);
  if (!c.valid() || c.isNull()) return fallback;
  return choice(key, allowed);
}

fs::path Config::filePath(std::string_view key) const {
  Config c = at(key);
  fs::path p = c.as<std::string>();
  if (p.is_absolute()) return p;
  const Location loc = c.location();
  if (loc.line > 0) return fs::path(loc.file).parent_path() / p;  // relative to the writing file
  return p;                                                         // --set: relative to the working dir
}

std::vector<Config> Config::elements() const {
  if (!isSequence()) fail(fmt::format("expected a list, found {}.", node_ ? kindName(node_->kind) : "nothing"));
  std::vector<Config> out;
  for (std::size_t i = 0; i < node_->sequence.size(); ++i)
    out.push_back(Config(node_->sequence[i], scene_, fmt::format("{}[{}]", path_, i)));
  return out;
}

std::vector<std::pair<std::string, Config>> Config::entries() const {
  if (isNull()) return {};
  if (!isMap()) fail(fmt::format("expected a map, found {}.", node_ ? kindName(node_->kind) : "nothing"));
  node_->allKnown = true;
  std::vector<std::pair<std::string, Config>> out;
  for (const auto& [k, v] : node_->map) out.emplace_back(k, Config(v, scene_, childPath(k)));
  return out;
}

std::vector<std::string> Config::askedKeys() const {
  std::set<std::string> out;
  std::function<void(const NodePtr&, const std::string&)> walk = [&](const NodePtr& n, const std::string& path) {
    if (!n) return;
    if (n->kind == ConfigNode::Kind::kSequence) {
      for (const auto& e : n->sequence) walk(e, path + "[]");
      return;
    }
    if (n->kind != ConfigNode::Kind::kMap) return;
    for (const auto& key : n->asked) out.insert(path.empty() ? key : path + "." + key);
    for (const auto& [key, value] : n->map) walk(value, path.empty() ? key : path + "." + key);
  };
  walk(node_, path_);
  return {out.begin(), out.end()};
}

void Config::checkUnknownKeys() const {
  std::vector<std::string> problems;
  std::function<void(const NodePtr&, const std::string&)> walk = [&](const NodePtr& n, const std::string& path) {
    if (n->kind == ConfigNode::Kind::kSequence) {
      for (std::size_t i = 0; i < n->sequence.size(); ++i) walk(n->sequence[i], fmt::format("{}[{}]", path, i));
      return;
    }
    if (n->kind != ConfigNode::Kind::kMap) return;
    std::vector<std::string> asked(n->asked.begin(), n->asked.end());
    for (std::size_t i = 0; i < n->map.size(); ++i) {
      const auto& [key, value] = n->map[i];
      const std::string keyPath = path.empty() ? key : path + "." + key;
      if (n->allKnown || n->asked.count(key)) {
        walk(value, keyPath);
        continue;
      }
      std::string hint;
      if (auto s = suggest(key, asked)) hint = fmt::format(" Did you mean \"{}\"?", *s);
      problems.push_back(fmt::format("Unknown key \"{}\" ({}): this scene does not use it.{}", keyPath,
                                     n->keyLocations[i].str(), hint));
    }
  };
  if (node_) walk(node_, path_);
  if (problems.empty()) return;
  std::string msg;
  for (const auto& p : problems) msg += (msg.empty() ? "" : "\n") + p;
  throw ConfigError(msg);
}

}  // namespace common
