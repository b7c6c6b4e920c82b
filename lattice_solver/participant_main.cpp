// The bridge between liblattice and libcosim (DESIGN.md §2): wiring only. The coupled behaviour is
// lattice::CoupledLatticeRun (include/lattice/coupled_lattice_run.hpp), the window loop is libcosim's.
#include "participant_main.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "cosim/solver_bridge.hpp"
#include "lattice/coupled_lattice_run.hpp"

namespace lattice {

void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name, const std::filesystem::path& outDir,
                    common::Summary& summary) {
  auto log = common::logger("lattice.coupled");
  if (scene.supports.coupled.empty())
    throw common::ConfigError("a coupled lattice_solver run needs `interface: [{face: z_min, mode: dirichlet}, …]` in its "
                              "scene: the specimen faces the coupler drives.");
  const Specimen& sp = scene.specimen;
  logSpecimen(scene);
  Model model = buildModel(scene, true);
  auto solver = makeSolver(scene.solver, scene.solverSettings);
  CoupledLattice lattice(model, *solver, scene.loading.removal, scene.loading.maxRounds, scene.coupledRemoval,
                         scene.settleTolerance);
  const int axis = scene.supports.axis;
  LatticeOutput out(std::make_unique<common::H5Writer>(outDir / "lattice.h5"), sp);
  common::H5Writer& h5 = out.h5();
  CoupledLatticeRun run(scene, model, lattice, out);
  const auto loop = cosim::runBridge(name, endpoint, run, fmt::format("lattice_solver {}", name));
  const CoupledLatticeRun::Results& r = run.results();
  const std::vector<std::string>& meshes = run.meshes();
  const std::int64_t windows = loop.windows;
  const double peakStress = r.peakStress, strainAtPeak = r.strainAtPeak, youngsModulus = r.youngsModulus;
  const int peakWindow = r.peakWindow;
  const std::int64_t lateRemovals = r.lateRemovals;
  struct {
    double time, strain, stress;
  } pending{r.time, r.strain, r.stress};
  out.snapshot(model, lattice.displacement(), lattice.removedAt(), pending.time);
  std::vector<LatticeOutput::Crack> cracks;
  std::vector<std::uint32_t> removed;
  for (const auto& rm : lattice.removals()) {
    cracks.push_back({rm.rod, rm.window, rm.nominalStrain, rm.rodStrain});
    removed.push_back(rm.rod);
  }
  out.cracks(cracks, pending.time);
  h5.flush();

  const auto& eq = lattice.equilibrium();
  summary.setSteps(windows);
  summary.set("coupling_windows", windows);
  summary.set("peak_stress", peakStress);
  summary.set("strain_at_peak", strainAtPeak);
  summary.set("youngs_modulus", youngsModulus);
  summary.set("final_strain", pending.strain);
  summary.set("final_stress", pending.stress);
  reportSpecimen(scene, model, removed, axis, summary);
  // The macro-crack: the rods removed after the peak window, without the diffuse pre-peak microcracking.
  std::vector<std::uint32_t> postPeak;
  for (const auto& rm : lattice.removals())
    if (rm.window > peakWindow) postPeak.push_back(rm.rod);
  const CrackBand band = crackBand(model, postPeak, axis, 2 * sp.meanRodLength());
  summary.set("rods_removed_post_peak", static_cast<std::int64_t>(postPeak.size()));
  summary.set("crack_plane_post_peak", band.plane);
  summary.set("crack_band_fraction_post_peak", band.fraction);
  summary.set("solves", static_cast<std::int64_t>(eq.solves()));
  summary.set("solver_iterations", static_cast<std::int64_t>(eq.iterations()));
  summary.set("solve_time_s", eq.solveSeconds());
  summary.set("removal_time_s", eq.removalSeconds());
  summary.set("late_removals", lateRemovals);
  for (std::size_t i = 0; i < lattice.faces(); ++i) {
    const Eigen::Vector3d f = lattice.resultant(i);
    summary.set("force_" + meshes[i], std::vector<double>{f.x(), f.y(), f.z()});
  }
  log->info("{} windows; peak stress {:.4g} MPa at strain {:.4g}; E = {:.4g} GPa; {} of {} rods removed; {} solves, {} "
            "iterations",
            windows, peakStress / 1e6, strainAtPeak, youngsModulus / 1e9, removed.size(), sp.rods.size(), eq.solves(),
            eq.iterations());
}

}  // namespace lattice
