// The bridge between libfem and libcosim: wiring only. The coupled behaviour is
// fem::CoupledFem (include/fem/coupled_fem.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "cosim/solver_bridge.hpp"
#include "fem/coupled_fem.hpp"

namespace fem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary, const std::filesystem::path& restart) {
  cosim::runAdapter<CoupledFem>(scene, outDir / "fem.h5", restart, name, endpoint, fmt::format("fem_solver {}", name),
                               summary);
}

}  // namespace fem
