// Fuzz target: the lattice scene loader, which reads the specimen keys and generates the specimen
// (random or cubic lattice, aggregates). Input: the scene text. Only a scene or a located error may
// come out; a size the machine cannot hold must be refused before generating.
#include <cstdint>
#include <string>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "lattice/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)lattice::loadScene(common::Config::parse(text, "fuzz.yaml"));
  } catch (const common::ConfigError&) {
  } catch (const common::SimulationError&) {
  }
  return 0;
}
