// The bridge between libdem and libcosim (DESIGN.md §2): wiring only. The coupled behaviour is
// dem::CoupledDem (include/dem/coupled_dem.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/summary.hpp"
#include "cosim/window_loop.hpp"
#include "dem/coupled_dem.hpp"

namespace dem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary) {
  common::H5Writer h5(outDir / "dem.h5");
  CoupledDem dem(scene, h5);
  cosim::Participant p(name, endpoint);
  cosim::WindowLoopReport loop;
  try {
    loop = cosim::runWindowLoop(p, dem, fmt::format("dem_solver {}", name), [](const std::exception& e) {
      return dynamic_cast<const common::InstabilityError*>(&e) != nullptr;
    });
  } catch (const cosim::CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  }
  h5.flush();
  dem.report(summary, loop.windows);
}

}  // namespace dem
