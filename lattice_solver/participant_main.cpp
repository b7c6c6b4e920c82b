// The bridge between liblattice and libcosim: wiring only. The coupled behaviour is
// lattice::CoupledLattice (include/lattice/coupled_lattice.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"
#include "cosim/solver_bridge.hpp"
#include "lattice/coupled_lattice.hpp"

namespace lattice {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name, const std::filesystem::path& outDir,
                    common::Summary& summary, const std::filesystem::path& restart) {
  if (scene.supports.coupled.empty())
    throw common::ConfigError("a coupled lattice_solver run needs `interface: [{face: z_min, mode: dirichlet}, …]` in its "
                              "scene: the specimen faces the coupler drives.");
  logSpecimen(scene);
  cosim::runAdapter<CoupledLattice>(scene, outDir / "lattice.h5", restart, name, endpoint,
                                       fmt::format("lattice_solver {}", name), summary);
}

}  // namespace lattice
