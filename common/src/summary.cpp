#include "common/summary.hpp"

#include <fstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

namespace common {

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
  out << YAML::Key << "results" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : results_) {
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
  out << YAML::EndMap << YAML::EndMap;

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
