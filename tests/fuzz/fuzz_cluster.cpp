// Fuzz target: the DEM cluster-file reader (dem::readClusterFile: YAML sphere lists, or a gmsh mesh
// filled with spheres). Only a cluster or a located error may come out.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/errors.hpp"
#include "dem/cluster.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("cosim_fuzz_" + std::to_string(::getpid()) + "_cluster.yaml");
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  try {
    (void)dem::readClusterFile(file);
  } catch (const common::ConfigError&) {
  } catch (const common::SimulationError&) {
  }
  return 0;
}
