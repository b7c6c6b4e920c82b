#pragma once
// A DEM run on several MPI ranks (`mpirun -np P dem_solver SCENE.yaml`): space is cut into slabs
// of equal sphere counts (dem_solver/src/slabs.hpp), each rank steps its share with the ghosts of its
// neighbours' (dem_solver/src/ranked_simulation.hpp), and rank 0 writes the results in one rank's layout.
// dem_solver/README.md "Several ranks (MPI)" says what such a run supports and how it is checked.
#include <filesystem>
#include <string>

#include "dem/scene.hpp"

namespace common {
class Summary;
}

namespace dem {

/// This process's place in the run: its rank, the number of ranks, and how many share its machine.
struct Ranks {
  int rank = 0, size = 1, local = 1;
  /// Whether this dem_solver was built with MPI.
  static bool available();
};

/// Starts MPI when an MPI launcher (mpirun, mpiexec, srun) started this process; else one rank, and MPI
/// is not loaded. A build without MPI started by a launcher on several ranks returns their number, and
/// the run refuses it (runSceneOnRanks).
Ranks startRanks(int* argc, char*** argv);
/// Ends MPI if startRanks started it. A failure (`exitCode` ≠ 0) of this rank alone, while the others
/// wait for it, aborts the run instead, so that it does not hang; failures all ranks share end normally.
void stopRanks(int exitCode);

/// runScene on `ranks.size` ranks: `scene` built whole on every rank (loadScene), the same results in
/// `outDir` (dem.h5, written by rank 0) as one rank's, within round-off. Spheres and clusters (bonded or
/// not), plane and mesh walls; anything else is a common::ConfigError naming the key. `threads` 0: the machine's cores shared
/// among the ranks on it.
/// The group of rank 0's checkpoint that says how many ranks wrote it (`ranks`) and at which step (`step`).
inline constexpr const char* kRanksCheckpointScope = "run_on_ranks";

/// `restart`: rank 0's checkpoint (OUT/checkpoint/dem.h5) of a run on P ranks. On P ranks each takes up its
/// own share again (OUT/checkpoint/rank_N/) and the run goes on as if it had never stopped, bit for bit; on
/// another number, the shares are cut again (RankedSimulation) and it goes on within round-off. Written
/// every `output.checkpoint_interval` as one rank's.
void runSceneOnRanks(Scene& scene, const Ranks& ranks, const std::filesystem::path& outDir, common::Summary& summary,
                     bool progress, int threads, const std::filesystem::path& restart = {});

/// The coupled participant `name` (dem_solver --couple ENDPOINT) on `ranks.size` ranks: rank 0 talks to
/// the coupler at `endpoint`, the interface wall's displacement goes to every rank and its node forces
/// come back summed (dem_solver/src/ranked_participant.hpp). What runSceneOnRanks takes, with the
/// interface wall driven from outside; the results in one rank's coupled layout.
void runParticipantOnRanks(Scene& scene, const Ranks& ranks, const std::string& endpoint, const std::string& name,
                           const std::filesystem::path& outDir, common::Summary& summary, int threads);

}  // namespace dem
