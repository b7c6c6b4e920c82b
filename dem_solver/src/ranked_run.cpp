// Runs on several MPI ranks (dem/ranked_run.hpp): MPI's start and end, what such a run refuses, and the
// runs around RankedSimulation (ranked_simulation.hpp): standalone, and as a coupled participant
// (ranked_participant.hpp); their results through RankedOutput (ranked_output.hpp).
#include "dem/ranked_run.hpp"

#include <malloc.h>
#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/run_loop.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "cosim/solver_bridge.hpp"
#include "dem/coupled_dem.hpp"
#include "dem/stability_monitor.hpp"
#include "dem/time_steps.hpp"
#include "rank_messages.hpp"
#include "stepped_dem.hpp"
#include "ranked_output.hpp"
#include "ranked_participant.hpp"
#include "ranked_simulation.hpp"

namespace dem {

namespace {

bool started = false;  // startRanks() called MPI_Init
using detail::alone;

}  // namespace

bool Ranks::available() { return true; }

Ranks startRanks(int* argc, char*** argv) {
  // The launchers' variables: Open MPI's mpirun, PMIx (Open MPI 5, Slurm), MPICH's and Slurm's PMI.
  const bool launched = std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMIX_RANK") || std::getenv("PMI_SIZE");
  if (!launched) return {};
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  started = true;
  Ranks r;
  MPI_Comm_rank(MPI_COMM_WORLD, &r.rank);
  MPI_Comm_size(MPI_COMM_WORLD, &r.size);
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, r.rank, MPI_INFO_NULL, &node);
  MPI_Comm_size(node, &r.local);
  MPI_Comm_free(&node);
  return r;
}

void stopRanks(int exitCode) {
  if (!started) return;
  if (exitCode != 0 && alone) MPI_Abort(MPI_COMM_WORLD, exitCode);
  MPI_Finalize();
  started = false;
}

namespace {

// What a run on several ranks cannot do yet, as the key that asks for it.
// `coupled`: a participant, whose interface wall is driven by the coupler.
void refuseWhatRanksCannotRun(const Scene& scene, bool coupled) {
  const Simulation& sim = *scene.sim;
  auto refuse = [](const std::string& what) {
    throw common::ConfigError(fmt::format("{}: a run on several ranks takes spheres and clusters, bonded or not, "
                                          "plane and mesh walls only (dem_solver/README.md, \"Several ranks\"); run it on one rank",
                                          what));
  };
  for (const MeshWall& w : sim.meshWalls().walls()) {
    if (w.motion == MeshWall::Motion::kExternal && !(coupled && w.name == scene.interfaceWall))
      refuse("walls: " + w.name + " driven from outside");
    if (w.oneSided) refuse("walls: " + w.name + " one_sided");
  }
  for (std::size_t a = 0; a < sim.interactions().materials().size(); ++a)
    for (std::size_t b = 0; b < sim.interactions().materials().size(); ++b)
      if (const ContactLaw* law = sim.interactions().law(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
          law && law->rollingFriction() > 0.0)
        refuse("interactions: rolling_friction");
  if (sim.settings().bridging) refuse("bridging");
  if (scene.probe.kind == ProbeSettings::Kind::kImpact || scene.probe.kind == ProbeSettings::Kind::kAcceleration)
    refuse("probe.type");
  if (coupled && scene.output.checkpointInterval > 0) refuse("output.checkpoint_interval");
  if (!coupled && !scene.interfaceWall.empty()) refuse("interface");
  if (coupled && scene.interfaceWall.empty())
    throw common::ConfigError("a coupled dem_solver run on several ranks needs `interface: {wall: NAME}` naming a mesh "
                              "wall with motion: external.");
}

// This rank's share of the run, from the whole scene built on every rank: what standalone and coupled
// runs set up alike.
struct Share {
  // `from`: this rank's checkpoint of a run on as many ranks, whose share it takes up again; with `shares`,
  // rank 0's checkpoint of a run on another number of ranks, whose shares `shares` this rank takes up
  // (RankedSimulation's constructor).
  Share(Scene& scene, const Ranks& ranks, int threads, common::StateArchive* from = nullptr,
        const std::vector<common::StateArchive*>* shares = nullptr);
  Simulation& sim;
  double criticalDt = 0.0, approach = 0.0;  // the whole scene's, before the cut
  std::optional<RankedSimulation> ranked;
  std::optional<StabilityMonitor> monitor;  // of the summed ledger: the same on every rank
};

Share::Share(Scene& scene, const Ranks& ranks, int threads, common::StateArchive* from,
             const std::vector<common::StateArchive*>* shares)
    : sim(*scene.sim) {
  // A cut frees one share's arrays and allocates the next one's, in other sizes. glibc's mmap threshold
  // rises to the largest array freed, so the next ones come from the heap, which grows around the holes:
  // a fixed threshold keeps large arrays mapped and gives them back when freed (2·10⁴ spheres on 2 ranks,
  // 2,000 steps: the ranks' peaks 94 MB together instead of 100).
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  if (threads == 0) omp_set_num_threads(std::max(1, omp_get_num_procs() / ranks.local));
  const double dt = sim.settings().dt;
  common::logger("dem")->info("{} spheres on {} ranks, {} threads each; dt = {:.4g} s, end {:.4g} s ({} steps)",
                              sim.spheres().size(), ranks.size, omp_get_max_threads(), dt, scene.endTime,
                              std::llround(scene.endTime / dt));
  criticalDt = criticalTimeStep(sim), approach = approachSpeedEstimate(sim);
  alone = true;  // from here the ranks wait for each other
  if (shares) ranked.emplace(sim, ranks, *shares, *from);
  else ranked.emplace(sim, ranks, from);
  if (!from) ranked->refuseOverlaps();
  ranked->reduceLedger(false);
  monitor.emplace(ranked->initialEnergy(), ranked->ledger().potential, approach, scene.energyTolerance);
  monitor->nameBodies([this](std::size_t b) { return ranked->id(b); });
}

// A run on several ranks' checkpoint: rank 0's file (OUT/checkpoint/dem.h5, the one --restart names) holds,
// besides its share, how many ranks wrote it and at which step (kRanksCheckpointScope); rank r's share is
// OUT/checkpoint/rank_r/dem_STEP.h5 of that step (earlier steps are removed once rank 0's is written).
// Restarted on as many ranks, each rank takes up its own share; on another number P', rank r takes up the
// shares r, r + P', r + 2P', … and the bodies move to new slabs as in a cut (RankedSimulation).
// Rank `rank`'s share beside rank 0's checkpoint in `folder` (OUT/checkpoint, or where --restart FILE is).
std::filesystem::path shareCheckpoint(const std::filesystem::path& folder, int rank, std::int64_t step) {
  return folder / fmt::format("rank_{}", rank) / fmt::format("dem_{}.h5", step);
}

// Rank 0's results file (reopened where a restart's checkpoint left it) and, on a restart, each rank's
// checkpoint, checked against `shape` (the whole scene's). Any rank's error is every rank's (exit 2).
struct Opened {
  std::unique_ptr<common::H5Writer> h5;
  // The loop's state and, on as many ranks, this rank's share; on another number of ranks rank 0's file.
  std::optional<common::StateArchive> from;
  // On another number of ranks: the shares this rank takes up, rank 0's (`from`) apart.
  bool reshare = false;
  std::vector<common::StateArchive> others;
};

Opened openOnRanks(const std::filesystem::path& outDir, const std::filesystem::path& restart, const std::string& shape,
                   const Ranks& ranks) {
  Opened o;
  std::string error;
  std::int64_t wrote[2] = {0, 0};  // ranks, step
  if (ranks.rank == 0) try {
      common::ResultsFile r =
          common::openResults(outDir / "dem.h5", restart, kStandaloneKind, shape, outDir / "checkpoint" / "dem.h5");
      o.h5 = std::move(r.h5);
      o.from = std::move(r.restart);
      if (o.from && !o.from->has(std::string(kRanksCheckpointScope) + "/ranks"))
        throw common::ConfigError(fmt::format("{}: a checkpoint of a run on one rank; restart it on one rank (without "
                                              "mpirun)",
                                              restart.string()));
      if (o.from) {
        auto scope = o.from->scope(kRanksCheckpointScope);
        o.from->io("ranks", wrote[0]), o.from->io("step", wrote[1]);
      }
    } catch (const common::ConfigError& e) {
      error = e.what();
    }
  detail::agreeOnInput(error, ranks.rank);
  MPI_Bcast(wrote, 2, MPI_INT64_T, 0, MPI_COMM_WORLD);
  if (restart.empty()) {
    // An earlier run's shares in this folder: not for a later --restart of this one.
    if (ranks.rank > 0) std::filesystem::remove_all(shareCheckpoint(outDir / "checkpoint", ranks.rank, 0).parent_path());
    return o;
  }
  // Each share checked whole before use, as rank 0's is (openResults): a damaged one is exit 2 on every rank.
  auto open = [&](const std::filesystem::path& file) {
    common::StateArchive::verify(file);
    common::StateArchive a = common::StateArchive::open(file, kStandaloneKind);
    a.shape(shape);
    return a;
  };
  if (wrote[0] == ranks.size) {
    if (ranks.rank > 0) try {
        o.from = open(shareCheckpoint(restart.parent_path(), ranks.rank, wrote[1]));
      } catch (const common::ConfigError& e) {
        error = e.what();
      }
    detail::agreeOnInput(error, ranks.rank);
    return o;
  }
  try {
    if (ranks.rank > 0) o.from = open(restart);
    for (std::int64_t r = ranks.rank; r < wrote[0]; r += ranks.size)
      if (r > 0) o.others.push_back(open(shareCheckpoint(restart.parent_path(), static_cast<int>(r), wrote[1])));
    o.reshare = true;
  } catch (const common::ConfigError& e) {
    error = e.what();
  }
  detail::agreeOnInput(error, ranks.rank);
  return o;
}

// The exit code common::runApp gives `e`.
int exitCodeOf(const std::exception& e) {
  if (dynamic_cast<const common::ConfigError*>(&e)) return static_cast<int>(common::ExitCode::kBadInput);
  if (const auto* s = dynamic_cast<const common::SimulationError*>(&e)) return static_cast<int>(s->code());
  return 1;
}

}  // namespace

namespace {

/// The DEM on ranks as common::runLoop drives it: every rank runs the loop, with the same clock and the
/// same schedule; rank 0 writes the results, each rank its share of a checkpoint.
class RankedRun final : public SteppedDem {
 public:
  RankedRun(const Scene& scene, Share& share, RankedOutput& output, const Ranks& ranks, std::string shape)
      : SteppedDem(share.sim, scene.endTime), scene_(scene), share_(share), sim_(share.sim), ranked_(*share.ranked), monitor_(*share.monitor),
        output_(output), ranks_(ranks), shape_(std::move(shape)) {}

  // Every rank agrees on a failure (RankedSimulation::step, the summed ledger): all leave the loop
  // together, and the summary says how far the run got.
  void step() override {
    ranked_.step();
    try {
      monitor_.check(sim_, ranked_.ledger(), ranked_.initialEnergy());  // the same ledger on every rank
    } catch (const common::InstabilityError&) {
      alone = false;
      throw;
    }
  }

  void writeSeries(common::SeriesRow) override { output_.write(output_.sample()); }
  // The row is gathered from every rank: only a failure all ranks share (alone is false) has them all here.
  bool canWriteFailedState() const override { return !alone; }
  void writeSnapshot(bool) override { output_.writeParticles(sim_.time()); }

  // The shares' state is read where the run is cut (Share), before the loop: a restart reads the monitor.
  void archive(common::StateArchive& a) override {
    if (!a.reading()) {
      a.shape(shape_);
      ranked_.archive(a);
    }
    a.io("monitor", monitor_);
    if (a.reading()) return;
    auto scope = a.scope(kRanksCheckpointScope);
    std::int64_t wrote[2] = {ranks_.size, steps()};
    a.io("ranks", wrote[0]), a.io("step", wrote[1]);
  }

  // Every rank's share first, then rank 0's file, which names their step: a run stopped in between
  // restarts from the checkpoint before, whose shares are still there.
  void writeCheckpoint(const std::filesystem::path& file, const std::string& kind,
                       const std::function<void(common::StateArchive&)>& fill) override {
    const bool root = ranks_.rank == 0;
    const std::filesystem::path mine = shareCheckpoint(file.parent_path(), ranks_.rank, steps());
    if (!root) {
      std::filesystem::create_directories(mine.parent_path());
      common::StateArchive::write(mine, kind, fill);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (root) common::StateArchive::write(file, kind, fill);
    MPI_Barrier(MPI_COMM_WORLD);
    if (!root)
      for (const auto& old : std::filesystem::directory_iterator(mine.parent_path()))
        if (old.path() != mine) std::filesystem::remove(old.path());
  }

  void report(common::Summary& summary, double loopSeconds, bool failed) override {
    if (failed) {
      summary.set("end_time", sim_.time());
      summary.set("energy_balance_error", monitor_.energyError());
      return;
    }
    output_.report(scene_, loopSeconds, share_.criticalDt, monitor_.energyError(), summary);
  }

 private:
  const Scene& scene_;
  Share& share_;
  Simulation& sim_;
  RankedSimulation& ranked_;
  StabilityMonitor& monitor_;
  RankedOutput& output_;
  Ranks ranks_;
  std::string shape_;
};

}  // namespace

void runSceneOnRanks(Scene& scene, const Ranks& ranks, const std::filesystem::path& outDir, common::Summary& summary,
                     bool progress, int threads, const std::filesystem::path& restart) {
  refuseWhatRanksCannotRun(scene, false);
  const std::string shape = scene.sim->shape();  // the whole scene's, which every rank's checkpoint states
  alone = true;
  Opened opened = openOnRanks(outDir, restart, shape, ranks);
  std::vector<common::StateArchive*> shares;  // on another number of ranks: those this rank takes up
  if (opened.reshare && ranks.rank == 0) shares.push_back(&*opened.from);
  for (common::StateArchive& a : opened.others) shares.push_back(&a);
  Share share(scene, ranks, threads, opened.from ? &*opened.from : nullptr, opened.reshare ? &shares : nullptr);
  opened.others.clear(), shares.clear();  // taken up: closed (the loop reads its state from `from`)
  common::H5Writer* h5 = opened.h5.get();
  if (h5) addMeshWalls(*h5, share.sim);
  RankedOutput output(share.sim, *share.ranked, ranks, h5, scene.output.track);
  RankedRun run(scene, share, output, ranks, shape);
  common::RunLoopSettings s = loopSettings(scene, outDir, kStandaloneKind, progress && ranks.rank == 0);
  common::runLoop(run, std::move(s), h5, opened.from, restart, summary);
}

void runParticipantOnRanks(Scene& scene, const Ranks& ranks, const std::string& endpoint, const std::string& name,
                           const std::filesystem::path& outDir, common::Summary& summary, int threads) {
  refuseWhatRanksCannotRun(scene, true);
  Share share(scene, ranks, threads);
  Simulation& sim = share.sim;
  std::unique_ptr<common::H5Writer> h5;
  if (ranks.rank == 0) {
    h5 = std::move(common::openResults(outDir / "dem.h5", {}, CoupledDem::kKind, CoupledDem::shape(scene)).h5);
    addMeshWalls(*h5, sim);
  }
  RankedOutput output(sim, *share.ranked, ranks, h5.get(), CoupledDem::recordedBodies(scene));
  RankedParticipant participant(scene, *share.ranked, output, *share.monitor, share.criticalDt, ranks.rank);
  const auto loopStart = std::chrono::steady_clock::now();
  try {
    if (ranks.rank == 0) {
      try {
        cosim::WindowLoopOptions options;
        options.label = fmt::format("dem_solver {} (rank 0 of {})", name, ranks.size);
        cosim::runBridge(name, endpoint, participant, std::move(options));
        participant.finish();
      } catch (const std::exception& e) {
        participant.stop(exitCodeOf(e), e.what());
        throw;
      }
    } else {
      participant.follow();
    }
  } catch (const std::exception&) {
    output.flush();
    summary.setSteps(sim.steps());
    summary.set("end_time", sim.time());
    summary.set("coupling_windows", participant.committed());
    throw;
  }
  const double loopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - loopStart).count();
  output.flush();
  output.report(scene, loopSeconds, share.criticalDt, share.monitor->energyError(), summary);
  summary.set("coupling_windows", participant.committed());
  summary.set("mesh_skin", sim.settings().meshSkin);
}

}  // namespace dem
