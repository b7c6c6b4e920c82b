#pragma once
// A lattice scene: reading it from YAML (keys in lattice_solver/README.md), generating the specimen,
// and running the fracture test with outputs (lattice.h5 + lattice.xdmf, summary results).

#include <array>
#include <filesystem>
#include <string>

#include "lattice/fracture_test.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"
#include "lattice/specimen.hpp"

namespace common {
class Config;
class Summary;
}  // namespace common

namespace lattice {

struct Scene {
  Specimen specimen;
  std::array<PhaseProperties, kPhaseCount> phases;
  std::string law = "beam";
  RodSection section;
  Supports supports;
  LoadingSettings loading;
  std::string solver = "cg";
  Operator op = Operator::kAssembled;
  SolverSettings solverSettings;
  int snapshotEvery = 0;  ///< increments between snapshots (0: the final state only)
  double aggregateFraction = 0.0;  ///< placed aggregate volume / specimen volume
  double generationSeconds = 0.0;
};

/// Reads the scene and generates the specimen (so --check also finds aggregates that cannot be
/// packed); every input error is a common::ConfigError naming the key, file and line.
Scene loadScene(const common::Config& cfg);

/// Builds the model from the scene (the rod area `auto` is resolved by loadScene).
Model buildModel(const Scene& scene);

/// Runs the test, writing `outDir`/lattice.h5 (+ .xdmf) and filling `summary`.
void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress);

}  // namespace lattice
