// A standalone run on several MPI ranks (dem/ranked_run.hpp): MPI's start and end, what such a run
// refuses, and the run itself around RankedSimulation (ranked_simulation.hpp): the output by rank 0 and
// the summary of the whole run.
#include "dem/ranked_run.hpp"

#include <malloc.h>
#include <mpi.h>
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <numeric>
#include <optional>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/summary.hpp"
#include "dem/bonds.hpp"
#include "dem/stability_monitor.hpp"
#include "rank_messages.hpp"
#include "ranked_simulation.hpp"

namespace dem {

namespace {

constexpr const char* kStandaloneKind = "dem_solver standalone";
bool started = false;  // startRanks() called MPI_Init
using detail::allReduce, detail::alone, detail::gatherAtRoot;

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
void refuseWhatRanksCannotRun(const Scene& scene) {
  const Simulation& sim = *scene.sim;
  auto refuse = [](const std::string& what) {
    throw common::ConfigError(fmt::format("{}: a run on several ranks takes spheres, bonded or not, plane and mesh walls "
                                          "only (dem_solver/README.md, \"Several ranks\"); run it on one rank",
                                          what));
  };
  const Bodies& B = sim.bodies();
  for (std::size_t b = 0; b < B.size(); ++b)
    if (B.sphereCount[b] != 1 || sim.spheres().local[B.firstSphere[b]].squaredNorm() > 0.0) refuse("clusters");
  for (const MeshWall& w : sim.meshes()) {
    if (w.motion == MeshWall::Motion::kExternal) refuse("walls: " + w.name + " driven from outside");
    if (w.oneSided) refuse("walls: " + w.name + " one_sided");
  }
  for (std::size_t a = 0; a < sim.materials().size(); ++a)
    for (std::size_t b = 0; b < sim.materials().size(); ++b)
      if (const ContactLaw* law = sim.interaction(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
          law && law->rollingFriction() > 0.0)
        refuse("interactions: rolling_friction");
  if (sim.bridgingZone()) refuse("bridging");
  if (scene.probe.kind == ProbeSettings::Kind::kImpact || scene.probe.kind == ProbeSettings::Kind::kAcceleration)
    refuse("probe.type");
  if (scene.output.checkpointInterval > 0) refuse("output.checkpoint_interval");
  if (!scene.interfaceWall.empty()) refuse("interface");
}

// Per sphere of the share, in id order: id, then the snapshot's values (ParticleSnapshot).
std::vector<double> ownedSnapshot(const RankedSimulation& ranked, const ParticleSnapshot& p) {
  std::vector<double> out;
  for (std::size_t s = 0; s < p.radius.size(); ++s) {
    if (!ranked.owned(s)) continue;
    out.push_back(static_cast<double>(ranked.id(s)));
    for (int k = 0; k < 3; ++k) out.push_back(p.position[3 * s + static_cast<std::size_t>(k)]);
    for (int k = 0; k < 3; ++k) out.push_back(p.velocity[3 * s + static_cast<std::size_t>(k)]);
    for (int k = 0; k < 3; ++k) out.push_back(p.bodyForce[3 * s + static_cast<std::size_t>(k)]);
    out.push_back(p.radius[s]);
  }
  return out;
}

// reportBonds for the whole run: the counts summed, the pieces found on rank 0 from every rank's
// intact bonds and bonded spheres (their ids and masses).
void reportBondsOnRanks(const Simulation& sim, const RankedSimulation& ranked, const Ranks& ranks,
                        common::Summary& summary) {
  const BondSet& bonds = sim.bonds();
  double counts[2] = {static_cast<double>(bonds.created()), static_cast<double>(bonds.broken())};
  MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  if (counts[0] == 0) return;
  std::vector<double> links, masses;
  for (const Bond& b : bonds.bonds()) links.insert(links.end(), {double(ranked.id(b.a)), double(ranked.id(b.b))});
  const auto& ever = bonds.everBonded();
  for (std::size_t s = 0; s < ever.size(); ++s)
    if (ever[s] && ranked.owned(s)) masses.insert(masses.end(), {double(ranked.id(s)), sim.bodies().mass[s]});
  links = gatherAtRoot(links, ranks.rank, ranks.size);
  masses = gatherAtRoot(masses, ranks.rank, ranks.size);
  summary.set("bonds_created", static_cast<std::int64_t>(counts[0]));
  summary.set("broken_bonds", static_cast<std::int64_t>(counts[1]));
  summary.set("bond_fracture_energy", ranked.ledger().bondFracture);
  if (ranks.rank != 0) return;
  std::vector<std::uint64_t> parent(ranked.total());
  std::iota(parent.begin(), parent.end(), std::uint64_t{0});
  auto find = [&](std::uint64_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (std::size_t i = 0; i < links.size(); i += 2)
    parent[find(static_cast<std::uint64_t>(links[i]))] = find(static_cast<std::uint64_t>(links[i + 1]));
  std::vector<double> piece(ranked.total(), 0.0);
  for (std::size_t i = 0; i < masses.size(); i += 2) piece[find(static_cast<std::uint64_t>(masses[i]))] += masses[i + 1];
  std::vector<double> pieces;
  for (double m : piece)
    if (m > 0.0) pieces.push_back(m);
  if (pieces.empty()) return;
  summary.set("fragments", static_cast<std::int64_t>(pieces.size()));
  summary.set("largest_fragment_mass_fraction",
              *std::max_element(pieces.begin(), pieces.end()) / std::accumulate(pieces.begin(), pieces.end(), 0.0));
}

}  // namespace

void runSceneOnRanks(Scene& scene, const Ranks& ranks, const std::filesystem::path& outDir, common::Summary& summary,
                     bool progress, int threads) {
  refuseWhatRanksCannotRun(scene);
  // A cut frees one share's arrays and allocates the next one's, in other sizes. glibc's mmap threshold
  // rises to the largest array freed, so the next ones come from the heap, which grows around the holes:
  // a fixed threshold keeps large arrays mapped and gives them back when freed (2·10⁴ spheres on 2 ranks,
  // 2,000 steps: the ranks' peaks 94 MB together instead of 100).
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  if (threads == 0) omp_set_num_threads(std::max(1, omp_get_num_procs() / ranks.local));
  Simulation& sim = *scene.sim;
  auto log = common::logger("dem");
  const bool root = ranks.rank == 0;
  const double dt = sim.settings().dt;
  const std::size_t spheres = sim.spheres().size();
  log->info("{} spheres on {} ranks, {} threads each; dt = {:.4g} s, end {:.4g} s ({} steps)", spheres, ranks.size,
            omp_get_max_threads(), dt, scene.endTime, std::llround(scene.endTime / dt));
  // The whole scene's, before the cut.
  const double criticalDt = sim.criticalTimeStep(), approach = sim.approachSpeedEstimate();
  alone = true;  // from here the ranks wait for each other
  RankedSimulation ranked(sim, ranks);
  ranked.refuseOverlaps();
  ranked.reduceLedger(false);
  StabilityMonitor monitor(ranked.initialEnergy(), ranked.ledger().potential, approach, scene.energyTolerance);
  monitor.nameBodies([&](std::size_t b) { return ranked.id(b); });

  std::unique_ptr<common::H5Writer> h5;
  std::optional<SeriesRecorder> series;  // one rank's layout, rows summed over the ranks
  if (root) {
    h5 = std::move(common::openResults(outDir / "dem.h5", {}, kStandaloneKind, sim.shape(), outDir / "checkpoint" / "dem.h5").h5);
    addMeshWalls(*h5, sim);
    series.emplace(*h5, sim, scene.output.track);
  }
  auto writeSeries = [&] {
    std::vector<double> walls = SeriesRecorder::wallRow(sim);
    MPI_Allreduce(MPI_IN_PLACE, walls.data(), static_cast<int>(walls.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    const std::vector<std::uint32_t>& track = scene.output.track;
    // A tracked body's contacts are counted where they are computed: on its rank, and on lower ones that
    // hold it as a ghost.
    std::vector<double> contacts(track.size(), 0.0);
    for (std::size_t i = 0; i < track.size(); ++i)
      if (const auto b = ranked.local(track[i])) contacts[i] = sim.bodyContacts(*b).count;
    MPI_Allreduce(MPI_IN_PLACE, contacts.data(), static_cast<int>(contacts.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    std::vector<double> rows;  // each tracked body's row from its rank: its place in `track`, then the row
    for (std::size_t i = 0; i < track.size(); ++i)
      if (const auto b = ranked.local(track[i]); b && ranked.owned(*b)) {
        rows.push_back(static_cast<double>(i));
        const std::vector<double> row = SeriesRecorder::bodyRow(sim, *b, contacts[i]);
        rows.insert(rows.end(), row.begin(), row.end());
      }
    rows = gatherAtRoot(rows, ranks.rank, ranks.size);
    if (!root) return;
    SeriesRecorder::Row row;
    row.time = sim.time();
    row.energy = series->energyRow(ranked.ledger(), ranked.initialEnergy());
    row.walls = std::move(walls);
    row.bodies.resize(track.size());
    constexpr std::size_t kBodyRow = 13;
    for (std::size_t at = 0; at < rows.size(); at += kBodyRow + 1)
      row.bodies[static_cast<std::size_t>(rows[at])].assign(rows.begin() + static_cast<std::ptrdiff_t>(at + 1),
                                                            rows.begin() + static_cast<std::ptrdiff_t>(at + 1 + kBodyRow));
    series->write(row);
  };
  auto writeParticles = [&] {
    // The mesh walls' node forces: each rank's contacts' share, summed.
    std::vector<MeshWall> meshes = sim.meshes();
    for (MeshWall& m : meshes)
      MPI_Allreduce(MPI_IN_PLACE, m.nodeForce.data(), static_cast<int>(3 * m.nodeForce.size()), MPI_DOUBLE, MPI_SUM,
                    MPI_COMM_WORLD);
    const ParticleSnapshot local = particleSnapshot(sim);
    std::vector<double> all = gatherAtRoot(ownedSnapshot(ranked, local), ranks.rank, ranks.size);
    std::vector<double> lines = local.lineEnds, forces = local.normalForce;
    lines = gatherAtRoot(lines, ranks.rank, ranks.size);
    forces = gatherAtRoot(forces, ranks.rank, ranks.size);
    if (!root) return;
    constexpr std::size_t kRow = 11;
    const std::size_t n = all.size() / kRow;
    ParticleSnapshot p;
    p.position.resize(3 * n), p.velocity.resize(3 * n), p.bodyForce.resize(3 * n), p.radius.resize(n), p.body.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double* r = &all[i * kRow];
      const auto s = static_cast<std::size_t>(r[0]);
      for (std::size_t k = 0; k < 3; ++k)
        p.position[3 * s + k] = r[1 + k], p.velocity[3 * s + k] = r[4 + k], p.bodyForce[3 * s + k] = r[7 + k];
      p.radius[s] = r[10];
      p.body[s] = r[0];
    }
    p.lineEnds = std::move(lines), p.normalForce = std::move(forces);
    writeParticleSnapshot(*h5, sim.time(), p);
    writeMeshSnapshots(*h5, meshes, sim.time());
  };

  common::Progress bar("dem", scene.endTime, progress && root);
  const auto totalSteps = static_cast<std::int64_t>(std::llround(scene.endTime / dt));
  const double eps = 0.5 * dt;
  double nextSeries = scene.output.seriesInterval, nextSnapshot = scene.output.interval;
  writeSeries();
  if (scene.output.interval > 0) writeParticles();
  const auto loopStart = std::chrono::steady_clock::now();
  // Every rank agrees on a failure (RankedSimulation::step, the summed ledger): all leave the loop
  // together, and the summary says how far the run got.
  try {
    while (sim.steps() < totalSteps) {
      ranked.step();
      try {
        monitor.check(sim, ranked.ledger(), ranked.initialEnergy());  // the same ledger on every rank
      } catch (const common::InstabilityError&) {
        alone = false;
        throw;
      }
      if (sim.time() + eps >= nextSeries) {
        writeSeries();
        nextSeries += scene.output.seriesInterval;
      }
      if (scene.output.interval > 0 && sim.time() + eps >= nextSnapshot) {
        writeParticles();
        nextSnapshot += scene.output.interval;
      }
      bar.update(sim.time(), sim.steps());
    }
  } catch (const common::SimulationError&) {
    if (root) h5->flush();
    summary.setSteps(sim.steps());
    summary.set("end_time", sim.time());
    summary.set("energy_balance_error", monitor.energyError());
    throw;
  }
  bar.finish(sim.time(), sim.steps());
  const double loopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - loopStart).count();
  if (root) h5->flush();

  // The whole run's counts: each sphere, pair and wall contact is one rank's.
  const auto contacts = sim.contactCounts();
  double counts[5] = {static_cast<double>(contacts.pairCandidates), static_cast<double>(contacts.pairs),
                      static_cast<double>(contacts.walls), 0.0, 0.0};
  double top = -1e300;
  const Spheres& S = sim.spheres();
  for (std::size_t s = 0; s < S.size(); ++s) {
    if (!ranked.owned(s)) continue;
    top = std::max(top, S.position[s].z() + S.radius[s]);
    if ((S.position[s].array() >= scene.probe.regionMin.array()).all() &&
        (S.position[s].array() <= scene.probe.regionMax.array()).all())
      counts[3] += 4.0 / 3.0 * 3.14159265358979323846 * std::pow(S.radius[s], 3);
    counts[4] += 1.0;
  }
  MPI_Allreduce(MPI_IN_PLACE, counts, 5, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  top = allReduce(top, MPI_MAX);
  const double rebuilds = allReduce(static_cast<double>(sim.neighbourRebuilds()), MPI_MAX);
  const double ghosts = allReduce(static_cast<double>(ranked.ghosts()), MPI_SUM);
  rusage self{};
  getrusage(RUSAGE_SELF, &self);
  const std::vector<double> memory =
      gatherAtRoot({static_cast<double>(self.ru_maxrss) / 1024.0}, ranks.rank, ranks.size);

  summary.setSteps(sim.steps());
  summary.set("end_time", sim.time());
  summary.set("dt", dt);
  summary.set("critical_dt", criticalDt);
  summary.set("skin", sim.settings().skin);
  summary.set("bodies", static_cast<std::int64_t>(counts[4]));
  summary.set("spheres", static_cast<std::int64_t>(counts[4]));
  summary.set("neighbor_rebuilds", static_cast<std::int64_t>(rebuilds));
  summary.set("sphere_pair_candidates_final", static_cast<std::int64_t>(counts[0]));
  summary.set("sphere_contacts_final", static_cast<std::int64_t>(counts[1]));
  summary.set("wall_contacts_final", static_cast<std::int64_t>(counts[2]));
  if (counts[4] > 0) summary.set("coordination_number_final", (2 * counts[1] + counts[2]) / counts[4]);
  summary.set("loop_wall_time_s", loopSeconds);
  summary.set("particle_steps_per_s", loopSeconds > 0 ? counts[4] * static_cast<double>(sim.steps()) / loopSeconds : 0.0);
  summary.set("energy_balance_error", monitor.energyError());
  summary.set("kinetic_energy_final", ranked.ledger().kinetic);
  if (scene.probe.kind == ProbeSettings::Kind::kPacking) {
    summary.set("packing_fraction", counts[3] / (scene.probe.regionMax - scene.probe.regionMin).prod());
    summary.set("bed_height", top);
  }
  reportBondsOnRanks(sim, ranked, ranks, summary);
  summary.setCost("processes", static_cast<std::int64_t>(ranks.size));
  summary.setCost("ranks", static_cast<std::int64_t>(ranks.size));
  summary.setCost("rank_migrations", ranked.migrations());
  summary.setCost("ghosts_per_sphere_final", ghosts / counts[4]);
  summary.setCost("slab_axis", std::string(1, "xyz"[ranked.slabs().axis]));
  // Rank 0's share: its physics, phases and memory by structure (one rank's keys), and where its step's
  // time goes besides them.
  reportCost(sim, summary, loopSeconds);
  summary.setCost("time_rank_messages_s", ranked.messageSeconds());
  summary.setCost("time_rank_cuts_s", ranked.cutSeconds());
  if (root) {
    summary.setCost("peak_memory_ranks_mb", memory);
    summary.setCost("peak_memory_all_ranks_mb", std::accumulate(memory.begin(), memory.end(), 0.0));
  }
}

}  // namespace dem
