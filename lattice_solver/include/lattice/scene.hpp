#pragma once
// A lattice scene: reading it from YAML (keys in lattice_solver/README.md), generating the specimen,
// and running the fracture test with outputs (lattice.h5 + lattice.xdmf, summary results).

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "lattice/fracture_test.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"
#include "lattice/specimen.hpp"

namespace common {
class Config;
class H5Writer;
class Summary;
}  // namespace common

namespace lattice {

/// When a coupled lattice removes rods (fracture.coupled; lattice/coupled_lattice.hpp).
enum class CoupledRemoval { kSettled, kIterate };

struct Scene {
  Specimen specimen;
  std::array<PhaseProperties, kPhaseCount> phases;
  std::string law = "beam";
  RodSection section;
  Supports supports;  ///< supports.coupled: the `interface` faces (participant mode)
  LoadingSettings loading;
  bool hasLoading = false;  ///< a `loading` section (standalone runs need one)
  CoupledRemoval coupledRemoval = CoupledRemoval::kSettled;  ///< fracture.coupled (participant mode)
  double settleTolerance = 1e-3;                              ///< fracture.settle_tolerance
  SolverSpec solver;                    ///< `solver:` (cg by default)
  Operator op = Operator::kMatrixFree;  // cg is the default solver
  int snapshotEvery = 0;  ///< increments between snapshots (0: the final state only)
  int checkpointEvery = 0;  ///< increments between checkpoints of a standalone run (0: none)
  double aggregateFraction = 0.0;  ///< placed aggregate volume / specimen volume
  double generationSeconds = 0.0;
};

/// Reads the scene and generates the specimen (so --check also finds aggregates that cannot be
/// packed); every input error is a common::ConfigError naming the key, file and line.
Scene loadScene(const common::Config& cfg);

/// Builds the model from the scene (the rod area `auto` is resolved by loadScene): with the `interface`
/// faces as supports when `coupled`, else with the uniaxial supports of `loading`.
Model buildModel(const Scene& scene, bool coupled = false);
/// Logs the specimen's size (nodes, rods per phase, aggregates).
void logSpecimen(const Scene& scene);

/// Runs the test, writing `outDir`/lattice.h5 (+ .xdmf) and filling `summary`; with `restart` (a
/// checkpoint of this scene, `outDir`/checkpoint/lattice.h5 by default) it continues from there,
/// appending to the results.
void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart = {});

/// Face names of the `interface` key, in Face order: x_min, x_max, y_min, y_max, z_min, z_max.
std::string faceName(const Face& f);

/// lattice.h5 (README "Outputs"), shared by standalone and participant runs: the `rods` mesh (with the
/// specimen's aggregates), its snapshots, and the `cracks` mesh.
class LatticeOutput {
 public:
  /// Writes into `h5` (borrowed: it must outlive this object).
  LatticeOutput(common::H5Writer& h5, const Specimen& specimen);
  common::H5Writer& h5() { return h5_; }
  /// A `rods` snapshot: displacement and rotation per node, strain, removed_at and phase per rod.
  void snapshot(const Model& model, std::span<const double> u, std::span<const int> removedAt, double time);
  struct Crack {
    std::uint32_t rod;
    int increment;          ///< increment (standalone) or coupling window (participant)
    double appliedStrain;   ///< applied (standalone) or nominal (participant) strain when it broke
    double rodStrain;
  };
  /// The `cracks` mesh (nothing when no rod broke).
  void cracks(const std::vector<Crack>& removed, double time);

 private:
  const Specimen& specimen_;
  common::H5Writer& h5_;
  std::vector<double> nodes_, phase_;
};

/// Specimen results shared by both modes: nodes, rods, rods per phase, aggregates, aggregate_fraction,
/// mean_rod_length, rod_area, generation_time_s, and the crack band (crack_plane, crack_band_fraction)
/// of the removed rods along `axis` (± 2 mean rod lengths).
void reportSpecimen(const Scene& scene, const Model& model, std::span<const std::uint32_t> removed, int axis,
                    common::Summary& summary);

/// Crack localisation (docs/validation/lattice.md): the plane normal to `axis` with the most removed
/// rods (by midpoint) within ± halfWidth, and the fraction of all removed rods that lie there.
struct CrackBand {
  double plane = 0.0;     ///< position along the axis [m]
  double fraction = 0.0;  ///< removed rods in the band / removed rods (0 when none)
};
CrackBand crackBand(const Model& model, std::span<const std::uint32_t> removed, int axis, double halfWidth);

}  // namespace lattice
