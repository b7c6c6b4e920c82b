// RankedOutput (ranked_output.hpp): each rank's share of a row, a snapshot or a count, summed or gathered
// on rank 0, which writes them as one rank would.
#include "ranked_output.hpp"

#include <mpi.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "common/h5_writer.hpp"
#include "common/summary.hpp"
#include "dem/contact_queries.hpp"
#include "dem/bonds.hpp"
#include "rank_messages.hpp"

namespace dem {

namespace {

using detail::allReduce, detail::gatherAtRoot;

// Per sphere of the share (of an owned body): its id, its body's, then the snapshot's values
// (ParticleSnapshot).
constexpr std::size_t kSnapshotRow = 12;
std::vector<double> ownedSnapshot(const Simulation& sim, const RankedSimulation& ranked, const ParticleSnapshot& p) {
  std::vector<double> out;
  const Spheres& S = sim.spheres();
  for (std::size_t s = 0; s < p.radius.size(); ++s) {
    if (!ranked.owned(S.body[s])) continue;
    out.push_back(static_cast<double>(ranked.sphereId(s)));
    out.push_back(static_cast<double>(ranked.id(S.body[s])));
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
  // By body (a bonded sphere is a body of its own), every rank's on rank 0.
  std::vector<double> links, masses;
  const std::vector<std::uint32_t>& body = sim.spheres().body;
  for (const Bond& b : bonds.bonds())
    links.insert(links.end(), {double(ranked.id(body[b.a])), double(ranked.id(body[b.b]))});
  const auto& ever = bonds.everBonded();
  for (std::size_t s = 0; s < ever.size(); ++s)
    if (ever[s] && ranked.owned(body[s]))
      masses.insert(masses.end(), {double(ranked.id(body[s])), sim.bodies().mass[body[s]]});
  links = gatherAtRoot(links, ranks.rank, ranks.size);
  masses = gatherAtRoot(masses, ranks.rank, ranks.size);
  summary.set("bonds_created", static_cast<std::int64_t>(counts[0]));
  summary.set("broken_bonds", static_cast<std::int64_t>(counts[1]));
  summary.set("bond_fracture_energy", ranked.ledger().bondFracture);
  if (ranks.rank != 0) return;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> pairs;
  for (std::size_t i = 0; i < links.size(); i += 2)
    pairs.emplace_back(static_cast<std::uint64_t>(links[i]), static_cast<std::uint64_t>(links[i + 1]));
  std::vector<std::pair<std::uint64_t, double>> bodyMasses;
  for (std::size_t i = 0; i < masses.size(); i += 2) bodyMasses.emplace_back(static_cast<std::uint64_t>(masses[i]), masses[i + 1]);
  reportPieces(pieceMasses(ranked.total(), pairs, bodyMasses), summary);
}

}  // namespace

RankedOutput::RankedOutput(Simulation& sim, const RankedSimulation& ranked, const Ranks& ranks, common::H5Writer* h5,
                           std::vector<std::uint32_t> track)
    : sim_(sim), ranked_(ranked), ranks_(ranks), h5_(h5), track_(std::move(track)) {
  if (h5_) series_.emplace(*h5_, sim_, track_);
}

SeriesRecorder::Row RankedOutput::sample() const {
  std::vector<double> walls = SeriesRecorder::wallRow(sim_);
  MPI_Allreduce(MPI_IN_PLACE, walls.data(), static_cast<int>(walls.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  // A tracked body's contacts are counted where they are computed: on its rank, and on lower ones that
  // hold it as a ghost.
  std::vector<double> contacts(track_.size(), 0.0);
  for (std::size_t i = 0; i < track_.size(); ++i)
    if (const auto b = ranked_.local(track_[i])) contacts[i] = sim_.bodyContacts(*b).count;
  MPI_Allreduce(MPI_IN_PLACE, contacts.data(), static_cast<int>(contacts.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  std::vector<double> rows;  // each tracked body's row from its rank: its place in `track`, then the row
  for (std::size_t i = 0; i < track_.size(); ++i)
    if (const auto b = ranked_.local(track_[i]); b && ranked_.owned(*b)) {
      rows.push_back(static_cast<double>(i));
      const std::vector<double> row = SeriesRecorder::bodyRow(sim_, *b, contacts[i]);
      rows.insert(rows.end(), row.begin(), row.end());
    }
  rows = gatherAtRoot(rows, ranks_.rank, ranks_.size);
  SeriesRecorder::Row row;
  if (!series_) return row;
  row.time = sim_.time();
  row.energy = series_->energyRow(ranked_.ledger(), ranked_.initialEnergy());
  row.walls = std::move(walls);
  row.bodies.resize(track_.size());
  constexpr std::size_t kBodyRow = 13;
  for (std::size_t at = 0; at < rows.size(); at += kBodyRow + 1)
    row.bodies[static_cast<std::size_t>(rows[at])].assign(rows.begin() + static_cast<std::ptrdiff_t>(at + 1),
                                                          rows.begin() + static_cast<std::ptrdiff_t>(at + 1 + kBodyRow));
  return row;
}

void RankedOutput::write(const SeriesRecorder::Row& row) {
  if (series_) series_->write(row);
}

void RankedOutput::flush() {
  if (h5_) h5_->flush();
}

void RankedOutput::writeParticles(double time) {
  // The mesh walls' node forces: each rank's contacts' share, summed.
  std::vector<MeshWall> meshes = sim_.meshWalls().walls();
  for (MeshWall& m : meshes)
    MPI_Allreduce(MPI_IN_PLACE, m.nodeForce.data(), static_cast<int>(3 * m.nodeForce.size()), MPI_DOUBLE, MPI_SUM,
                  MPI_COMM_WORLD);
  const ParticleSnapshot local = particleSnapshot(sim_);
  std::vector<double> all = gatherAtRoot(ownedSnapshot(sim_, ranked_, local), ranks_.rank, ranks_.size);
  std::vector<double> lines = local.lineEnds, forces = local.normalForce;
  lines = gatherAtRoot(lines, ranks_.rank, ranks_.size);
  forces = gatherAtRoot(forces, ranks_.rank, ranks_.size);
  if (!h5_) return;
  const std::size_t n = all.size() / kSnapshotRow;
  ParticleSnapshot p;
  p.position.resize(3 * n), p.velocity.resize(3 * n), p.bodyForce.resize(3 * n), p.radius.resize(n), p.body.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double* r = &all[i * kSnapshotRow];
    const auto s = static_cast<std::size_t>(r[0]);
    for (std::size_t k = 0; k < 3; ++k)
      p.position[3 * s + k] = r[2 + k], p.velocity[3 * s + k] = r[5 + k], p.bodyForce[3 * s + k] = r[8 + k];
    p.radius[s] = r[11];
    p.body[s] = r[1];
  }
  p.lineEnds = std::move(lines), p.normalForce = std::move(forces);
  writeParticleSnapshot(*h5_, time, p);
  writeMeshSnapshots(*h5_, meshes, time);
}

void RankedOutput::report(const Scene& scene, double loopSeconds, double criticalDt, double energyError,
                          common::Summary& summary) const {
  // The whole run's counts: each sphere, pair and wall contact is one rank's.
  const Simulation& sim = sim_;
  const auto contacts = contactCounts(sim);
  // Pair candidates, touching pairs, wall contacts, the probe's sphere volume, spheres, bodies.
  double counts[6] = {static_cast<double>(contacts.pairCandidates), static_cast<double>(contacts.pairs),
                      static_cast<double>(contacts.walls), 0.0, 0.0, 0.0};
  double top = -1e300;
  const Spheres& S = sim.spheres();
  for (std::size_t b = 0; b < sim.bodies().size(); ++b) counts[5] += ranked_.owned(b) ? 1.0 : 0.0;
  for (std::size_t s = 0; s < S.size(); ++s) {
    if (!ranked_.owned(S.body[s])) continue;
    top = std::max(top, S.position[s].z() + S.radius[s]);
    if ((S.position[s].array() >= scene.probe.regionMin.array()).all() &&
        (S.position[s].array() <= scene.probe.regionMax.array()).all())
      counts[3] += 4.0 / 3.0 * 3.14159265358979323846 * std::pow(S.radius[s], 3);
    counts[4] += 1.0;
  }
  MPI_Allreduce(MPI_IN_PLACE, counts, 6, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  top = allReduce(top, MPI_MAX);
  const double rebuilds = allReduce(static_cast<double>(sim.profile().neighbourRebuilds), MPI_MAX);
  const double ghosts = allReduce(static_cast<double>(ranked_.ghosts()), MPI_SUM);
  rusage self{};
  getrusage(RUSAGE_SELF, &self);
  const std::vector<double> memory =
      gatherAtRoot({static_cast<double>(self.ru_maxrss) / 1024.0}, ranks_.rank, ranks_.size);

  summary.setSteps(sim.steps());
  summary.set("end_time", sim.time());
  summary.set("dt", sim.settings().dt);
  summary.set("critical_dt", criticalDt);
  summary.set("skin", sim.settings().skin);
  summary.set("bodies", static_cast<std::int64_t>(counts[5]));
  summary.set("spheres", static_cast<std::int64_t>(counts[4]));
  summary.set("neighbor_rebuilds", static_cast<std::int64_t>(rebuilds));
  summary.set("sphere_pair_candidates_final", static_cast<std::int64_t>(counts[0]));
  summary.set("sphere_contacts_final", static_cast<std::int64_t>(counts[1]));
  summary.set("wall_contacts_final", static_cast<std::int64_t>(counts[2]));
  if (counts[4] > 0) summary.set("coordination_number_final", (2 * counts[1] + counts[2]) / counts[4]);
  summary.set("loop_wall_time_s", loopSeconds);
  summary.set("particle_steps_per_s", loopSeconds > 0 ? counts[4] * static_cast<double>(sim.steps()) / loopSeconds : 0.0);
  summary.set("energy_balance_error", energyError);
  summary.set("kinetic_energy_final", ranked_.ledger().kinetic);
  if (scene.probe.kind == ProbeSettings::Kind::kPacking) {
    summary.set("packing_fraction", counts[3] / (scene.probe.regionMax - scene.probe.regionMin).prod());
    summary.set("bed_height", top);
  }
  reportBondsOnRanks(sim, ranked_, ranks_, summary);
  summary.setCost("processes", static_cast<std::int64_t>(ranks_.size));
  summary.setCost("ranks", static_cast<std::int64_t>(ranks_.size));
  summary.setCost("rank_migrations", ranked_.migrations());
  summary.setCost("ghosts_per_sphere_final", ghosts / counts[4]);
  summary.setCost("slab_axis", std::string(1, "xyz"[ranked_.slabs().axis]));
  // Rank 0's share: its physics, phases and memory by structure (one rank's keys), and where its step's
  // time goes besides them.
  reportCost(sim, summary, loopSeconds);
  summary.setCost("time_rank_messages_s", ranked_.messageSeconds());
  summary.setCost("time_rank_cuts_s", ranked_.cutSeconds());
  if (ranks_.rank == 0) {
    summary.setCost("peak_memory_ranks_mb", memory);
    summary.setCost("peak_memory_all_ranks_mb", std::accumulate(memory.begin(), memory.end(), 0.0));
  }
}

}  // namespace dem
