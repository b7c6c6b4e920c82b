#include "common/summary.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace common {

namespace {
// A map of values as its keys, their kinds (the variant's index) and the values one by one.
void archiveValues(StateArchive& a, const std::string& name, std::map<std::string, Summary::Value>& values) {
  auto scope = a.scope(name);
  std::vector<std::string> keys;
  std::vector<std::int32_t> kinds;
  for (const auto& [key, value] : values) keys.push_back(key), kinds.push_back(static_cast<std::int32_t>(value.index()));
  a.io("keys", keys);
  a.io("kinds", kinds);
  if (kinds.size() != keys.size()) throw ConfigError(fmt::format("{}: {} has {} keys and {} kinds", a.path().string(), name, keys.size(), kinds.size()));
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const std::string slot = std::to_string(i);
    Summary::Value& v = values[keys[i]];
    switch (kinds[i]) {
      case 0: { double x = a.reading() ? 0.0 : std::get<double>(v); a.io(slot, x); v = x; break; }
      case 1: { std::int64_t x = a.reading() ? 0 : std::get<std::int64_t>(v); a.io(slot, x); v = x; break; }
      case 2: { std::string x = a.reading() ? std::string() : std::get<std::string>(v); a.io(slot, x); v = x; break; }
      case 3: { std::vector<double> x = a.reading() ? std::vector<double>() : std::get<std::vector<double>>(v); a.io(slot, x); v = x; break; }
      default: throw ConfigError(fmt::format("{}: {}/{} is of an unknown kind {}", a.path().string(), name, slot, kinds[i]));
    }
  }
}
}  // namespace

void Summary::archive(StateArchive& a) {
  a.io("steps", steps_);
  archiveValues(a, "results", results_);
  archiveValues(a, "cost", cost_);
}

void Summary::write(const std::filesystem::path& file, ExitCode code, const std::string& status,
                    double wallTimeS) const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "scene" << YAML::Value << scene_;
  out << YAML::Key << "status" << YAML::Value << status;
  out << YAML::Key << "exit_code" << YAML::Value << static_cast<int>(code);
  out << YAML::Key << "wall_time_s" << YAML::Value << wallTimeS;
  out << YAML::Key << "steps" << YAML::Value << steps_;
  if (hasFailure_) {
    out << YAML::Key << "failure" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "cause" << YAML::Value << failure_.cause;
    out << YAML::Key << "where" << YAML::Value << failure_.where;
    out << YAML::Key << "time" << YAML::Value << failure_.time;
    out << YAML::Key << "evidence" << YAML::Value << failure_.evidence;
    out << YAML::Key << "fix" << YAML::Value << failure_.fix;
    out << YAML::EndMap;
  }
  std::vector<std::string> nonfinite;
  out << YAML::Key << "results" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : results_) {
    const bool finite = std::visit(
        [](const auto& v) {
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, double>) return std::isfinite(v);
          else if constexpr (std::is_same_v<T, std::vector<double>>)
            return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
          else return true;
        },
        value);
    if (!finite) {
      nonfinite.push_back(key);
      continue;
    }
    out << YAML::Key << key << YAML::Value;
    std::visit(
        [&](const auto& v) {
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, std::vector<double>>)
            out << YAML::Flow << v;
          else
            out << v;
        },
        value);
  }
  out << YAML::EndMap;
  if (!nonfinite.empty()) out << YAML::Key << "nonfinite_results" << YAML::Value << YAML::Flow << nonfinite;
  if (!cost_.empty()) {
    out << YAML::Key << "cost" << YAML::Value << YAML::BeginMap;
    for (const auto& [key, value] : cost_) {
      out << YAML::Key << key << YAML::Value;
      std::visit(
          [&](const auto& v) {
            if constexpr (std::is_same_v<std::decay_t<decltype(v)>, std::vector<double>>) out << YAML::Flow << v;
            else out << v;
          },
          value);
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;

  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
  const auto tmp = std::filesystem::path(file).concat(".tmp");
  {
    std::ofstream f(tmp);
    f << out.c_str() << '\n';
    if (!f) throw SimulationError(fmt::format("cannot write {}.", tmp.string()));
  }
  std::filesystem::rename(tmp, file);
}

}  // namespace common
