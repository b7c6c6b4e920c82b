#pragma once
// What every solver executable's coupled mode shares (DESIGN.md §2: the bridge between a solver library
// and libcosim is wiring only): its results file, opened fresh or, on a restart, reopened where the
// checkpoint left it; the window loop; and the loop's errors as the process's exit codes. Header only:
// the solver executables link libcosim and common, the installed libcosim does not need this.

#include <filesystem>
#include <string>

#include "common/errors.hpp"
#include "common/results_file.hpp"
#include "common/summary.hpp"
#include "cosim/window_loop.hpp"

namespace cosim {

/// Runs the window loop as participant `name`; a lost coupler is exit 4, a diverged solver exit 3 (its
/// InstabilityError is reported to the coupler as such).
inline WindowLoopReport runBridge(const std::string& name, const std::string& endpoint, CoupledSolver& solver,
                                  const std::string& label) {
  Participant p(name, endpoint);
  try {
    return runWindowLoop(p, solver, label, [](const std::exception& e) {
      return dynamic_cast<const common::InstabilityError*>(&e) != nullptr;
    });
  } catch (const CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  }
}

/// The whole coupled mode of a solver whose adapter is built from (scene, results file), reads a
/// restart with archive(StateArchive&), describes a scene's dimensions with shape(scene) and reports
/// with report(Summary&): dem_solver's and fem_solver's.
template <class Adapter, class Scene>
void runAdapter(Scene& scene, const std::filesystem::path& h5Path, const std::filesystem::path& restart,
                const std::string& name, const std::string& endpoint, const std::string& label,
                common::Summary& summary) {
  common::ResultsFile start = common::openResults(h5Path, restart, Adapter::kKind, Adapter::shape(scene));
  Adapter adapter(scene, *start.h5);
  if (start.restart) adapter.archive(*start.restart);
  runBridge(name, endpoint, adapter, label);
  start.h5->flush();
  adapter.report(summary);
}

}  // namespace cosim
