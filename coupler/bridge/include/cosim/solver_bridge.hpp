#pragma once
// What every solver executable's coupled mode shares (DESIGN.md §2: the bridge between a solver library
// and libcosim is wiring only): its results file, opened fresh or, on a restart, reopened where the
// checkpoint left it; the window loop; and the loop's errors as the process's exit codes. Header only:
// the solver executables link libcosim and common, the installed libcosim does not need this.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "cosim/window_loop.hpp"

namespace cosim {

struct BridgeStart {
  std::optional<common::StateArchive> restart;  ///< the checkpoint to read the state from (--restart)
  std::unique_ptr<common::H5Writer> h5;
};

/// Opens `restart` (a checkpoint of `kind` and of a solver of `shape`; empty: a fresh run) and the
/// results file at `h5Path`: created, or reopened and cut back to the checkpoint's extent — only once
/// the checkpoint proved whole (every checksum) and of this scene, so a refused restart changes nothing.
inline BridgeStart startBridge(const std::filesystem::path& h5Path, const std::filesystem::path& restart,
                               const std::string& kind, const std::string& shape) {
  BridgeStart s;
  if (restart.empty()) {
    s.h5 = std::make_unique<common::H5Writer>(h5Path);
    return s;
  }
  common::StateArchive::verify(restart);
  s.restart = common::StateArchive::open(restart, kind);
  s.restart->shape(shape);
  common::H5Extent extent;
  s.restart->io(kCheckpointOutput, extent);
  s.h5 = std::make_unique<common::H5Writer>(h5Path, extent);
  return s;
}

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
  BridgeStart start = startBridge(h5Path, restart, Adapter::kKind, Adapter::shape(scene));
  Adapter adapter(scene, *start.h5);
  if (start.restart) adapter.archive(*start.restart);
  runBridge(name, endpoint, adapter, label);
  start.h5->flush();
  adapter.report(summary);
}

}  // namespace cosim
