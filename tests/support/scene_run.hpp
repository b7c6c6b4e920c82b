#pragma once
// Runs an executable of build/bin on a scene of configs/ and reads its summary.yaml: the way
// integration and validation tests get results (never from log text).

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#ifndef COSIM_BIN_DIR
#error "COSIM_BIN_DIR must be defined by the build"
#endif
#ifndef COSIM_SOURCE_DIR
#error "COSIM_SOURCE_DIR must be defined by the build"
#endif

namespace testsupport {

struct SceneRun {
  int exitCode = -1;
  YAML::Node summary;   ///< summary.yaml (null when none was written)
  std::string output;   ///< stdout + stderr of the run
  std::filesystem::path outDir;

  double result(const std::string& key) const { return summary["results"][key].as<double>(); }
  std::string status() const { return summary["status"].as<std::string>(); }
};

inline std::filesystem::path sourcePath(const std::string& relative) {
  return std::filesystem::path(COSIM_SOURCE_DIR) / relative;
}

/// Runs `exe` (a name in build/bin) on `scene` (a path relative to the source tree, or absolute) with
/// --set overrides, into a fresh folder below the system temporary directory. `environment`: NAME=VALUE
/// words set for the run.
inline SceneRun runScene(const std::string& exe, const std::string& scene, const std::vector<std::string>& sets = {},
                         const std::vector<std::string>& extraArgs = {},
                         const std::vector<std::string>& environment = {}) {
  static std::mt19937_64 rng(std::random_device{}());
  SceneRun r;
  r.outDir = std::filesystem::temp_directory_path() / ("cosim_run_" + std::to_string(rng()));
  std::filesystem::create_directories(r.outDir);
  const std::filesystem::path scenePath =
      std::filesystem::path(scene).is_absolute() ? std::filesystem::path(scene) : sourcePath(scene);
  auto quote = [](const std::string& s) {  // one shell word, single quotes inside kept
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
  };
  std::ostringstream cmd;
  // ctest runs two tests at once on two cores: spinning OpenMP threads would starve each other.
  cmd << "env ";
  for (const auto& e : environment) cmd << quote(e) << " ";
  cmd << "OMP_WAIT_POLICY=passive " << quote(std::string(COSIM_BIN_DIR) + "/" + exe) << " " << quote(scenePath.string()) << " --quiet --out "
      << quote(r.outDir.string());
  for (const auto& s : sets) cmd << " --set " << quote(s);
  for (const auto& a : extraArgs) cmd << " " << quote(a);
  const auto log = r.outDir / "console.txt";
  cmd << " > '" << log.string() << "' 2>&1";
  const int status = std::system(cmd.str().c_str());
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  r.output.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const auto summary = r.outDir / "summary.yaml";
  if (std::filesystem::exists(summary)) r.summary = YAML::LoadFile(summary.string());
  return r;
}

/// Writes `text` to a scene file in a fresh temporary folder and returns its path.
inline std::filesystem::path writeScene(const std::string& name, const std::string& text) {
  static std::mt19937_64 rng(std::random_device{}());
  const auto dir = std::filesystem::temp_directory_path() / ("cosim_scene_" + std::to_string(rng()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}

}  // namespace testsupport
