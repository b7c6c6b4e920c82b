// Fuzz target: the scene loader (YAML, includes, --set overrides) with the DEM scene on top. Input: the
// first line, if it starts with "--set ", is one override; the rest is the scene text. Any outcome but
// a loaded scene, a common::ConfigError or a common::SimulationError (both: exit 2 or a located run
// error) is a finding — std::bad_alloc, out_of_range, a crash or a hang.
#include <cstdint>
#include <filesystem>
#include <string>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "dem/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> overrides;
  if (text.rfind("--set ", 0) == 0) {
    const auto eol = text.find('\n');
    overrides.push_back(text.substr(6, eol == std::string::npos ? std::string::npos : eol - 6));
    text = eol == std::string::npos ? "" : text.substr(eol + 1);
  }
  try {
    const common::Config cfg = common::Config::parse(text, "fuzz.yaml", std::filesystem::temp_directory_path(), overrides);
    (void)dem::loadScene(cfg);
  } catch (const common::ConfigError&) {
  } catch (const common::SimulationError&) {
  }
  return 0;
}
