// The bridge between libfem and libcosim (DESIGN.md §2): wiring only. The coupled behaviour is
// fem::CoupledFem (include/fem/coupled_fem.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/summary.hpp"
#include "cosim/window_loop.hpp"
#include "fem/coupled_fem.hpp"

namespace fem {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary) {
  common::H5Writer h5(outDir / "fem.h5");
  CoupledFem fem(scene, h5);
  cosim::Participant p(name, endpoint);
  cosim::WindowLoopReport loop;
  try {
    loop = cosim::runWindowLoop(p, fem, fmt::format("fem_solver {}", name), [](const std::exception& e) {
      return dynamic_cast<const common::InstabilityError*>(&e) != nullptr;
    });
  } catch (const cosim::CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  }
  h5.flush();
  fem.report(summary, loop.windows);
}

}  // namespace fem
