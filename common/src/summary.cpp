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

std::string cleanUtf8(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  const auto* b = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = b[i];
    // The length of a well-formed sequence starting here (Unicode 15, Table 3-7), 0 if none.
    std::size_t len = 0;
    auto cont = [&](std::size_t k, unsigned char lo = 0x80, unsigned char hi = 0xBF) {
      return i + k < n && b[i + k] >= lo && b[i + k] <= hi;
    };
    if (c < 0x80) len = 1;
    else if (c >= 0xC2 && c <= 0xDF && cont(1)) len = 2;
    else if (c == 0xE0 && cont(1, 0xA0) && cont(2)) len = 3;
    else if (((c >= 0xE1 && c <= 0xEC) || c == 0xEE || c == 0xEF) && cont(1) && cont(2)) len = 3;
    else if (c == 0xED && cont(1, 0x80, 0x9F) && cont(2)) len = 3;
    else if (c == 0xF0 && cont(1, 0x90) && cont(2) && cont(3)) len = 4;
    else if (c >= 0xF1 && c <= 0xF3 && cont(1) && cont(2) && cont(3)) len = 4;
    else if (c == 0xF4 && cont(1, 0x80, 0x8F) && cont(2) && cont(3)) len = 4;
    if (len == 0) {
      out += fmt::format("\\x{:02X}", c);
      ++i;
    } else {
      out.append(text.substr(i, len));
      i += len;
    }
  }
  return out;
}

void Summary::write(const std::filesystem::path& file, ExitCode code, const std::string& status,
                    double wallTimeS) const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "scene" << YAML::Value << cleanUtf8(scene_);
  out << YAML::Key << "status" << YAML::Value << cleanUtf8(status);
  out << YAML::Key << "exit_code" << YAML::Value << static_cast<int>(code);
  out << YAML::Key << "wall_time_s" << YAML::Value << wallTimeS;
  out << YAML::Key << "steps" << YAML::Value << steps_;
  if (hasFailure_) {
    out << YAML::Key << "failure" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "cause" << YAML::Value << cleanUtf8(failure_.cause);
    out << YAML::Key << "where" << YAML::Value << cleanUtf8(failure_.where);
    out << YAML::Key << "time" << YAML::Value << failure_.time;
    out << YAML::Key << "evidence" << YAML::Value << cleanUtf8(failure_.evidence);
    out << YAML::Key << "fix" << YAML::Value << cleanUtf8(failure_.fix);
    if (!failure_.settings.empty()) {
      out << YAML::Key << "fix_settings" << YAML::Value << YAML::Flow << YAML::BeginSeq;
      for (const auto& v : failure_.settings) out << cleanUtf8(v);
      out << YAML::EndSeq;
    }
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
    out << YAML::Key << cleanUtf8(key) << YAML::Value;
    std::visit(
        [&](const auto& v) {
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, std::vector<double>>)
            out << YAML::Flow << v;
          else if constexpr (std::is_same_v<T, std::string>)
            out << cleanUtf8(v);
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
      out << YAML::Key << cleanUtf8(key) << YAML::Value;
      std::visit(
          [&](const auto& v) {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::vector<double>>) out << YAML::Flow << v;
            else if constexpr (std::is_same_v<T, std::string>) out << cleanUtf8(v);
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
