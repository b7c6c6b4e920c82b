#pragma once
// What every solver executable's coupled mode shares (the bridge between a solver library
// and libcosim is wiring only): its results file, opened fresh or, on a restart, reopened where the
// checkpoint left it; the window loop; and the loop's errors as the process's exit codes. Header only:
// the solver executables link libcosim and common, the installed libcosim does not need this.

#include <concepts>
#include <filesystem>
#include <string>

#include "common/errors.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "cosim/window_loop.hpp"

namespace cosim {

/// Runs the window loop as participant `name`; a lost coupler is exit 4, a diverged solver exit 3 (its
/// InstabilityError is reported to the coupler as such).
inline WindowLoopReport runBridge(const std::string& name, const std::string& endpoint, CoupledSolver& solver,
                                  WindowLoopOptions options) {
  Participant p(name, endpoint);
  options.diverged = [](const std::exception& e) { return dynamic_cast<const common::InstabilityError*>(&e) != nullptr; };
  try {
    return runWindowLoop(p, solver, options);
  } catch (const CouplingError& e) {
    throw common::SimulationError(e.what(), common::ExitCode::kCoupling);
  }
}

/// What runAdapter needs of a solver's coupled adapter besides the window loop's calls (CoupledSolver):
/// the kind of its checkpoints and a scene's dimensions, known before it is built (to open the results
/// and check a restart against them); built from the scene and its results file; its state written and
/// read by one function (an on-disk checkpoint, a restart); and what it measured, for the summary.
template <class Adapter, class Scene>
concept SceneAdapter = std::derived_from<Adapter, CoupledSolver> &&
                       std::constructible_from<Adapter, Scene&, common::H5Writer&> &&
                       requires(const Scene& scene, Adapter& adapter, common::StateArchive& archive,
                                common::Summary& summary) {
                         { Adapter::kKind } -> std::convertible_to<const char*>;
                         { Adapter::shape(scene) } -> std::convertible_to<std::string>;
                         adapter.archive(archive);
                         adapter.report(summary);  // may write its last outputs first
                       };

/// The whole coupled mode of a solver, every solver executable's. An on-disk checkpoint is one
/// StateArchive of kind Adapter::kKind holding the adapter's state and the window loop's (`window_loop`).
template <class Adapter, class Scene>
  requires SceneAdapter<Adapter, Scene>
void runAdapter(Scene& scene, const std::filesystem::path& h5Path, const std::filesystem::path& restart,
                const std::string& name, const std::string& endpoint, const std::string& label,
                common::Summary& summary) {
  common::ResultsFile start = common::openResults(h5Path, restart, Adapter::kKind, Adapter::shape(scene));
  Adapter adapter(scene, *start.h5);
  WindowLoopOptions options;
  options.label = label;
  if (start.restart) {
    adapter.archive(*start.restart);
    start.restart->io("window_loop", options.resume);
  }
  options.writeCheckpoint = [&adapter](const std::string& path, const WindowLoopState& state) {
    common::StateArchive::write(path, Adapter::kKind, [&](common::StateArchive& a) {
      adapter.archive(a);
      WindowLoopState loop = state;
      a.io("window_loop", loop);
    });
  };
  runBridge(name, endpoint, adapter, std::move(options));
  start.h5->flush();
  adapter.report(summary);
}

}  // namespace cosim
