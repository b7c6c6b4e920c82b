// Fuzz target: the gmsh mesh reader behind every mesh wall and FEM mesh (common::readTriangleMesh).
// The input is written to a .msh file and read; only a mesh or a located error may come out.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/errors.hpp"
#include "common/mesh_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("cosim_fuzz_" + std::to_string(::getpid()) + ".msh");
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  try {
    (void)common::readTriangleMesh(file);
  } catch (const common::ConfigError&) {
  } catch (const common::SimulationError&) {
  }
  return 0;
}
