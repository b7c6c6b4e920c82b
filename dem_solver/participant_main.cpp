// The bridge between libdem and libcosim: wiring only. The coupled behaviour is
// dem::CoupledDem (include/dem/coupled_dem.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "cosim/solver_bridge.hpp"
#include "dem/coupled_dem.hpp"

namespace dem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary, const std::filesystem::path& restart) {
  cosim::runAdapter<CoupledDem>(scene, outDir / "dem.h5", restart, name, endpoint, fmt::format("dem_solver {}", name),
                               summary);
}

}  // namespace dem
