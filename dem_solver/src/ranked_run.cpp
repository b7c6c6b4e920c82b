// A standalone run on several MPI ranks (dem/ranked_run.hpp).
//
// Each rank holds a Simulation of its share of the spheres (those whose centres are in its slab) and of
// ghosts: the spheres of other slabs within `width` of its own. A sphere pair is computed by one rank, the
// lower of its spheres' ranks (NeighbourList::setOwners), which sends the force on the other's sphere back
// to its rank: each pair's force and energy is computed once, as on one rank, so the ledger is the sum of
// the ranks' ledgers. Ghosts are not moved here (BodyMotion kGhost): their ranks send their states after
// every step. When some sphere has moved half the margin since the last cut, the slabs are cut again at
// the sphere counts' quantiles and the spheres move to their new ranks with the histories of their
// contacts. The width covers the contact reach at a neighbour rebuild (2 r_max + skin) plus the margin:
// until the next cut no sphere out of reach of a rank's share can come within it.
#include "dem/ranked_run.hpp"

#include <malloc.h>
#include <mpi.h>
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <bit>
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
#include "contact_set.hpp"
#include "dem/bonds.hpp"
#include "mesh_walls.hpp"
#include "dem/stability_monitor.hpp"
#include "neighbour_list.hpp"
#include "plane_walls.hpp"
#include "slabs.hpp"
#include "sphere_pairs.hpp"

namespace dem {

namespace {

constexpr const char* kStandaloneKind = "dem_solver standalone";
constexpr int kHistogramBins = 4096;
bool started = false;  // startRanks() called MPI_Init
// Whether a failure now would be this rank's alone, the others waiting for it in a collective: then the
// run is aborted (stopRanks), not finalized, so that nothing hangs. Failures all ranks agree on (the
// scene's errors, the summed ledger's verdict, throwAgreed) end every rank together.
bool alone = false;

double allReduce(double v, MPI_Op op) {
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, op, MPI_COMM_WORLD);
  return v;
}

// What `out[r]` holds goes to rank r; returns what came from every rank, in rank order. `expected`: how
// many values each rank sends here, when known (else they are exchanged first).
std::vector<double> allToAll(const std::vector<std::vector<double>>& out, const std::vector<int>* expected = nullptr) {
  const auto P = out.size();
  std::vector<int> sendCount(P), recvCount(P), sendAt(P, 0), recvAt(P, 0);
  for (std::size_t r = 0; r < P; ++r) sendCount[r] = static_cast<int>(out[r].size());
  if (expected) recvCount = *expected;
  else MPI_Alltoall(sendCount.data(), 1, MPI_INT, recvCount.data(), 1, MPI_INT, MPI_COMM_WORLD);
  std::partial_sum(sendCount.begin(), sendCount.end() - 1, sendAt.begin() + 1);
  std::partial_sum(recvCount.begin(), recvCount.end() - 1, recvAt.begin() + 1);
  std::vector<double> send, recv(static_cast<std::size_t>(recvAt.back() + recvCount.back()));
  send.reserve(static_cast<std::size_t>(sendAt.back() + sendCount.back()));
  for (const auto& o : out) send.insert(send.end(), o.begin(), o.end());
  MPI_Alltoallv(send.data(), sendCount.data(), sendAt.data(), MPI_DOUBLE, recv.data(), recvCount.data(),
                recvAt.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  return recv;
}

// Every rank's `mine` at rank 0, in rank order (empty on the others).
std::vector<double> gatherAtRoot(const std::vector<double>& mine, int rank, int size) {
  int n = static_cast<int>(mine.size());
  std::vector<int> count(static_cast<std::size_t>(size)), at(static_cast<std::size_t>(size), 0);
  MPI_Gather(&n, 1, MPI_INT, count.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<double> all;
  if (rank == 0) {
    std::partial_sum(count.begin(), count.end() - 1, at.begin() + 1);
    all.resize(static_cast<std::size_t>(at.back() + count.back()));
  }
  MPI_Gatherv(mine.data(), n, MPI_DOUBLE, all.data(), count.data(), at.data(), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return all;
}

// A body as it travels between ranks: id, state, mass properties, its sphere.
constexpr std::size_t kRecord = 34;
constexpr std::size_t kBondRecord = 13;  // spheres' ids, the bond's constants and its shear force
constexpr std::size_t kGhostState = 16;  // position, velocity, angular velocity and momentum, orientation
constexpr std::size_t kMeshRecord = 12;  // a mesh contact: sphere, mesh, triangle, feature, law, normal, history

}  // namespace

// A Simulation's share of a run on several ranks, and the messages that keep it one run.
class RankedSimulation {
 public:
  // `sim`: the whole scene, built and not initialized, on every rank; each rank keeps and initializes its
  // share.
  RankedSimulation(Simulation& sim, const Ranks& ranks) : sim_(sim), rank_(ranks.rank), size_(ranks.size) {
    sim.resolveSkins();  // from all spheres: the same skins on every rank
    const Bodies& B = sim.bodies_;
    gid_.resize(B.size());
    std::iota(gid_.begin(), gid_.end(), std::uint64_t{0});
    owner_.resize(B.size());
    for (std::size_t b = 0; b < B.size(); ++b) owner_[b] = static_cast<int>(b % static_cast<std::size_t>(size_));
    total_ = B.size();
    double rmax = 0.0;
    for (double r : sim.spheres_.radius) rmax = std::max(rmax, r);
    margin_ = sim.settings().rankMargin;
    width_ = 2.0 * rmax + sim.settings().skin + margin_;
    migrate();
  }

  // One step of the whole run; collective. A failure on any rank is every rank's.
  void step() {
    // The cut the last step asked for, now: between steps the state stays whole for the output (a cut
    // clears the forces and contacts that the next force pass computes again).
    if (cutDue_) {
      const double start = MPI_Wtime();
      migrate();
      cutSeconds_ += MPI_Wtime() - start;
      cutDue_ = false;
    }
    Bodies& B = sim_.bodies_;
    const bool computes = sim_.steps() > 0;
    // An owned body whose contacts are all computed on other ranks is not active here: its sums are
    // not cleared by the force pass. (At step 0 they hold initialize()'s forces, which the step uses.)
    if (computes)
      for (const auto& list : sendTo_)
        for (auto b : list) B.force[b].setZero(), B.torque[b].setZero();
    sim_.prepareStep();
    double mark = MPI_Wtime();
    if (computes) returnGhostForces();
    messageSeconds_ += MPI_Wtime() - mark;
    std::optional<common::Instability> failure;
    try {
      sim_.finishStep();
    } catch (const common::InstabilityError& e) {
      failure = e.info();
      if (failure->where.rfind("body ", 0) == 0)
        failure->where = fmt::format("body {}", gid_[std::stoul(failure->where.substr(5))]);
    }
    mark = MPI_Wtime();
    sendGhostStates();
    reduceLedger(failure.has_value());
    if (failed_ > 0) throwAgreed(failure);
    double moved2 = 0.0;
    for (std::size_t b = 0; b < B.size(); ++b)
      if (owner_[b] == rank_) moved2 = std::max(moved2, (B.position[b] - anchor_[b]).squaredNorm());
    cutDue_ = 2.0 * std::sqrt(allReduce(moved2, MPI_MAX)) > margin_;
    messageSeconds_ += MPI_Wtime() - mark;
  }
  /// Wall-clock seconds in the messages of the steps (ghost states and forces, the ledger's sums) and in
  /// the cuts (new slabs, bodies and histories moved, the share's contacts built) [s].
  double messageSeconds() const { return messageSeconds_; }
  double cutSeconds() const { return cutSeconds_; }

  // One rank's loadScene() refuses bodies that overlap at the start; here the pairs are each rank's.
  void refuseOverlaps() const {
    const auto [a, b, overlap] = sim_.largestSphereOverlap();
    const Spheres& S = sim_.spheres_;
    struct {
      double ratio;
      int rank;
    } worst{-1.0, rank_};
    const double tolerance = S.size() > 0 ? 1e-3 * std::min(S.radius[a], S.radius[b]) : 1.0;
    if (S.size() > 0) worst.ratio = overlap / tolerance;
    MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE_INT, MPI_MAXLOC, MPI_COMM_WORLD);
    if (worst.ratio <= 1.0) return;
    std::uint64_t bodies[2] = {gid_[S.body[a]], gid_[S.body[b]]};
    double values[2] = {overlap, tolerance};
    MPI_Bcast(bodies, 2, MPI_UINT64_T, worst.rank, MPI_COMM_WORLD);
    MPI_Bcast(values, 2, MPI_DOUBLE, worst.rank, MPI_COMM_WORLD);
    alone = false;
    throw common::ConfigError(fmt::format("body {} overlaps body {} by {:.4g} m at the start (tolerance {:.3g} m = 0.1 % of "
                                          "the smaller sphere radius); move them apart (dem_solver --check on one rank "
                                          "names the line)",
                                          bodies[1], bodies[0], values[0], values[1]));
  }

  const EnergyLedger& ledger() const { return ledger_; }
  double initialEnergy() const { return initial_; }
  std::uint64_t id(std::size_t body) const { return body < gid_.size() ? gid_[body] : 0; }
  bool owned(std::size_t body) const { return owner_[body] == rank_; }
  /// The body with this id in the whole scene, if this rank holds it (owned or ghost).
  std::optional<std::uint32_t> local(std::uint64_t id) const {
    const auto it = std::lower_bound(gid_.begin(), gid_.end(), id);
    if (it == gid_.end() || *it != id) return std::nullopt;
    return static_cast<std::uint32_t>(it - gid_.begin());
  }
  std::int64_t migrations() const { return migrations_; }
  std::size_t ghosts() const { return ghosts_; }
  std::size_t total() const { return total_; }
  const Slabs& slabs() const { return slabs_; }

  // The ledger summed over the ranks (and whether some rank failed): each rank books its own bodies and
  // the contacts it computes.
  void reduceLedger(bool failed) {
    const EnergyLedger& e = sim_.energy();
    double v[11] = {e.kinetic,  e.potential, e.elastic,  e.damping,           e.friction,        e.cundall,
                    e.bondFracture, e.wallWork, e.externalWork, sim_.initialEnergy(), failed ? 1.0 : 0.0};
    // Summed at rank 0 and sent to all: every rank's monitor judges the same bits (an Allreduce may round
    // differently on different ranks, and then only some would stop).
    MPI_Reduce(rank_ == 0 ? MPI_IN_PLACE : v, v, 11, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    MPI_Bcast(v, 11, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    ledger_ = EnergyLedger{v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]};
    initial_ = v[9];
    failed_ = static_cast<int>(v[10]);
  }

 private:
  // The lowest failing rank's diagnosis, on every rank.
  [[noreturn]] void throwAgreed(const std::optional<common::Instability>& mine) {
    const int first = static_cast<int>(allReduce(mine ? rank_ : size_, MPI_MIN));
    std::string text;
    if (rank_ == first) {
      const auto& i = *mine;
      text = fmt::format("{}\x1f{}\x1f{:.17g}\x1f{}\x1f{}", i.cause, i.where, i.time, i.evidence, i.fix);
      for (const auto& s : i.settings) text += "\x1f" + s;
    }
    int n = static_cast<int>(text.size());
    MPI_Bcast(&n, 1, MPI_INT, first, MPI_COMM_WORLD);
    text.resize(static_cast<std::size_t>(n));
    MPI_Bcast(text.data(), n, MPI_CHAR, first, MPI_COMM_WORLD);
    std::vector<std::string> part;
    for (std::size_t at = 0;;) {
      const auto next = text.find('\x1f', at);
      part.push_back(text.substr(at, next - at));
      if (next == std::string::npos) break;
      at = next + 1;
    }
    common::Instability i{part[0], fmt::format("{} (rank {})", part[1], first), std::stod(part[2]), part[3], part[4]};
    i.settings.assign(part.begin() + 5, part.end());
    alone = false;
    throw common::InstabilityError(i);
  }

  void pack(std::size_t b, std::vector<double>& out) const {
    const Bodies& B = sim_.bodies_;
    const Spheres& S = sim_.spheres_;
    const auto s = B.firstSphere[b];
    const Quat& q = B.orientation[b];
    const double rec[kRecord] = {static_cast<double>(gid_[b]),
                                 B.position[b].x(), B.position[b].y(), B.position[b].z(),
                                 B.velocity[b].x(), B.velocity[b].y(), B.velocity[b].z(),
                                 B.angularVelocity[b].x(), B.angularVelocity[b].y(), B.angularVelocity[b].z(),
                                 B.angularMomentum[b].x(), B.angularMomentum[b].y(), B.angularMomentum[b].z(),
                                 q.w(), q.x(), q.y(), q.z(), B.mass[b],
                                 B.inertia[b].x(), B.inertia[b].y(), B.inertia[b].z(),
                                 B.force[b].x(), B.force[b].y(), B.force[b].z(),
                                 B.torque[b].x(), B.torque[b].y(), B.torque[b].z(),
                                 B.externalForce[b].x(), B.externalForce[b].y(), B.externalForce[b].z(),
                                 static_cast<double>(B.fixed[b]), S.radius[s], static_cast<double>(S.material[s]),
                                 s < sim_.bonds_.everBonded().size() ? static_cast<double>(sim_.bonds_.everBonded()[s]) : 0.0};
    out.insert(out.end(), rec, rec + kRecord);
  }

  // Appends record `r` as body `b` of `B` and `S`; a ghost of a free body moves as kGhost.
  static void unpack(const double* r, bool isGhost, Bodies& B, Spheres& S) {
    auto v = [&](int i) { return Vec3(r[i], r[i + 1], r[i + 2]); };
    const auto b = static_cast<std::uint32_t>(B.size());
    B.position.push_back(v(1)), B.velocity.push_back(v(4)), B.angularVelocity.push_back(v(7));
    B.angularMomentum.push_back(v(10)), B.orientation.push_back(Quat(r[13], r[14], r[15], r[16]));
    B.mass.push_back(r[17]), B.inertia.push_back(v(18)), B.force.push_back(v(21)), B.torque.push_back(v(24));
    B.externalForce.push_back(v(27));
    const auto motion = static_cast<std::uint8_t>(r[30]);
    B.fixed.push_back(!isGhost ? motion : motion == kFixed ? std::uint8_t{kFixedGhost} : std::uint8_t{kGhost});
    B.firstSphere.push_back(b), B.sphereCount.push_back(1);
    S.local.push_back(Vec3::Zero()), S.position.push_back(v(1)), S.radius.push_back(r[31]);
    S.material.push_back(static_cast<std::uint32_t>(r[32])), S.body.push_back(b);
  }

  static void reserve(Bodies& B, Spheres& S, std::size_t n) {
    for (auto* v : {&B.position, &B.velocity, &B.angularVelocity, &B.angularMomentum, &B.inertia, &B.force, &B.torque,
                    &B.externalForce, &S.local, &S.position})
      v->reserve(n);
    B.orientation.reserve(n), B.mass.reserve(n), B.fixed.reserve(n), B.firstSphere.reserve(n);
    B.sphereCount.reserve(n), S.radius.reserve(n), S.material.reserve(n), S.body.reserve(n);
  }

  Slabs cut() const {
    const Bodies& B = sim_.bodies_;
    double lo[3], hi[3];
    for (int c = 0; c < 3; ++c) lo[c] = std::numeric_limits<double>::infinity(), hi[c] = -lo[c];
    for (std::size_t b = 0; b < B.size(); ++b)
      if (owner_[b] == rank_)
        for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], B.position[b][c]), hi[c] = std::max(hi[c], B.position[b][c]);
    MPI_Allreduce(MPI_IN_PLACE, lo, 3, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, hi, 3, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    int axis = 0;
    for (int c = 1; c < 3; ++c)
      if (hi[c] - lo[c] > hi[axis] - lo[axis]) axis = c;
    std::vector<double> counts(kHistogramBins, 0.0);
    const double span = std::max(hi[axis] - lo[axis], 1e-300);
    for (std::size_t b = 0; b < B.size(); ++b)
      if (owner_[b] == rank_) {
        const auto i = static_cast<std::size_t>((B.position[b][axis] - lo[axis]) / span * kHistogramBins);
        counts[std::min(i, counts.size() - 1)] += 1.0;
      }
    MPI_Allreduce(MPI_IN_PLACE, counts.data(), kHistogramBins, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return Slabs::fromHistogram(axis, lo[axis], hi[axis], counts, size_);
  }

  // New slabs; every body to its new rank, the touching contacts' histories to the rank that computes
  // them next, the ghosts to the ranks that need them.
  void migrate() {
    const Bodies& B = sim_.bodies_;
    slabs_ = cut();
    const int axis = slabs_.axis;
    // A ghost's new rank follows from the same position bits and cuts as on its own rank.
    std::vector<int> next(B.size());
    for (std::size_t b = 0; b < B.size(); ++b) next[b] = slabs_.owner(B.position[b][axis]);
    const auto P = static_cast<std::size_t>(size_);
    std::vector<std::vector<double>> bodiesOut(P), historiesOut(P);
    for (std::size_t b = 0; b < B.size(); ++b)
      if (owner_[b] == rank_) pack(b, bodiesOut[static_cast<std::size_t>(next[b])]);
    if (sim_.steps() > 0) {
      const ContactSet& pairs = sim_.pairs_->contacts();
      for (std::size_t k = 0; k < pairs.size(); ++k) {
        const ContactHistory& h = pairs.history[k];
        if (!(h.lastOverlap > 0.0)) continue;  // an open contact's history starts afresh
        const auto a = pairs.a[k], b = pairs.b[k];
        historiesOut[static_cast<std::size_t>(std::min(next[a], next[b]))].insert(
            historiesOut[static_cast<std::size_t>(std::min(next[a], next[b]))].end(),
            {0.0, static_cast<double>(gid_[a]), static_cast<double>(gid_[b]), h.shearForce.x(), h.shearForce.y(),
             h.shearForce.z(), h.lastOverlap});
      }
      const ContactSet& walls = sim_.planeWalls_->contacts();
      for (std::size_t k = 0; k < walls.size(); ++k) {
        const ContactHistory& h = walls.history[k];
        if (!(h.lastOverlap > 0.0)) continue;
        historiesOut[static_cast<std::size_t>(next[walls.a[k]])].insert(
            historiesOut[static_cast<std::size_t>(next[walls.a[k]])].end(),
            {1.0, static_cast<double>(gid_[walls.a[k]]), static_cast<double>(walls.b[k]), h.shearForce.x(),
             h.shearForce.y(), h.shearForce.z(), h.lastOverlap});
      }
    }
    // Mesh contacts (of owned spheres only) with the sphere: the feature key (its bits as a double), the
    // law, the normal and the history, which the next step's contact on that feature takes over.
    std::vector<std::vector<double>> meshOut(P);
    if (sim_.steps() > 0) {
      const MeshContacts& mc = sim_.meshWalls_->contacts();
      for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
        const MeshContact& c = mc.contacts[i];
        const ContactHistory& h = mc.history[i];
        const Vec3& n = c.point.normal;
        meshOut[static_cast<std::size_t>(next[c.sphere])].insert(
            meshOut[static_cast<std::size_t>(next[c.sphere])].end(),
            {static_cast<double>(gid_[c.sphere]), static_cast<double>(c.mesh), static_cast<double>(c.triangle),
             std::bit_cast<double>(c.key), static_cast<double>(c.law), n.x(), n.y(), n.z(), h.shearForce.x(),
             h.shearForce.y(), h.shearForce.z(), h.lastOverlap});
      }
    }
    // Bonds to the rank that computes their pair next.
    std::vector<std::vector<double>> bondsOut(P);
    for (const Bond& d : sim_.bonds_.bonds()) {
      auto& to = bondsOut[static_cast<std::size_t>(std::min(next[d.a], next[d.b]))];
      to.insert(to.end(), {static_cast<double>(gid_[d.a]), static_cast<double>(gid_[d.b]), d.kn, d.ks, d.tensile,
                           d.cohesion, d.friction, d.restOverlap, d.gammaN, d.gammaT, d.shearForce.x(),
                           d.shearForce.y(), d.shearForce.z()});
    }
    // What the share was is packed: its arrays and contacts go before the new ones come (the peak of a
    // cut is then one share, not two).
    sim_.releaseBodies();
    std::vector<double> bondRecords = allToAll(bondsOut);
    bondsOut = {};
    std::vector<double> meshes = allToAll(meshOut);
    meshOut = {};
    std::vector<double> mine = allToAll(bodiesOut);
    bodiesOut = {};
    std::vector<double> histories = allToAll(historiesOut);
    historiesOut = {};
    // The share in id order, and the ghosts each rank needs from it.
    std::vector<const double*> share;
    for (std::size_t i = 0; i < mine.size(); i += kRecord) share.push_back(&mine[i]);
    std::sort(share.begin(), share.end(), [](const double* x, const double* y) { return x[0] < y[0]; });
    std::vector<std::vector<double>> ghostsOut(P);
    for (const double* r : share)
      slabs_.near(r[1 + axis], width_, rank_, [&](int to) {
        ghostsOut[static_cast<std::size_t>(to)].insert(ghostsOut[static_cast<std::size_t>(to)].end(), r, r + kRecord);
      });
    std::vector<double> ghosts = allToAll(ghostsOut);
    ghostsOut = {};
    // Local numbering in id order, owned and ghosts together: a pair's (a, b) order and the order of a
    // sphere's contacts are those of one rank.
    struct Entry {
      const double* record;
      int owner;
    };
    std::vector<Entry> all;
    all.reserve(share.size() + ghosts.size() / kRecord);
    for (const double* r : share) all.push_back({r, rank_});
    for (std::size_t i = 0; i < ghosts.size(); i += kRecord)
      all.push_back({&ghosts[i], slabs_.owner(ghosts[i + 1 + static_cast<std::size_t>(axis)])});
    std::sort(all.begin(), all.end(), [](const Entry& x, const Entry& y) { return x.record[0] < y.record[0]; });
    Bodies bodies;
    Spheres spheres;
    reserve(bodies, spheres, all.size());
    gid_.clear(), owner_.clear();
    sendTo_.assign(P, {}), ghostFrom_.assign(P, {});
    std::vector<std::uint8_t> everBonded;
    everBonded.reserve(all.size());
    for (const Entry& e : all) {
      const auto b = static_cast<std::uint32_t>(gid_.size());
      unpack(e.record, e.owner != rank_, bodies, spheres);
      everBonded.push_back(e.record[33] > 0.0 ? 1 : 0);
      gid_.push_back(static_cast<std::uint64_t>(e.record[0]));
      owner_.push_back(e.owner);
      if (e.owner != rank_) ghostFrom_[static_cast<std::size_t>(e.owner)].push_back(b);
      else slabs_.near(e.record[1 + axis], width_, rank_, [&](int to) { sendTo_[static_cast<std::size_t>(to)].push_back(b); });
    }
    ghosts_ = all.size() - share.size();
    // The histories by their sides' ids (pairs: a < b, walls: sphere, wall), sorted for the lookups.
    using Keyed = std::pair<std::pair<std::uint64_t, std::uint64_t>, ContactHistory>;
    std::vector<Keyed> pairHistory, wallHistory;
    for (std::size_t i = 0; i < histories.size(); i += 7) {
      const double* h = &histories[i];
      Keyed k{{static_cast<std::uint64_t>(h[1]), static_cast<std::uint64_t>(h[2])}, {Vec3(h[3], h[4], h[5]), h[6]}};
      (h[0] == 0.0 ? pairHistory : wallHistory).push_back(k);
    }
    auto byKey = [](const Keyed& x, const Keyed& y) { return x.first < y.first; };
    std::sort(pairHistory.begin(), pairHistory.end(), byKey);
    std::sort(wallHistory.begin(), wallHistory.end(), byKey);
    auto find = [&](const std::vector<Keyed>& in, std::uint64_t a, std::uint64_t b) {
      const auto it = std::lower_bound(in.begin(), in.end(), Keyed{{a, b}, {}}, byKey);
      return it != in.end() && it->first == std::pair(a, b) ? it->second : ContactHistory{};
    };
    auto pairOf = [&](std::uint32_t a, std::uint32_t b) { return find(pairHistory, gid_[a], gid_[b]); };
    auto wallOf = [&](std::uint32_t s, std::uint32_t w) { return find(wallHistory, gid_[s], w); };
    mine = {}, ghosts = {}, histories = {}, all = {}, share = {};
    std::vector<int> owner(owner_.begin(), owner_.end());
    const bool first = sim_.steps() == 0;
    if (!first && bondsFormed_) {
      // The bonds with their spheres' new numbers, before the contacts are built (bonded pairs are none).
      std::vector<Bond> bonds;
      for (std::size_t i = 0; i < bondRecords.size(); i += kBondRecord) {
        const double* r = &bondRecords[i];
        const auto a = local(static_cast<std::uint64_t>(r[0])), b = local(static_cast<std::uint64_t>(r[1]));
        if (!a || !b)
          throw common::SimulationError(fmt::format("the bond of spheres {} and {} reaches beyond the ghost layer "
                                                    "(neighbor.rank_margin); run on one rank",
                                                    r[0], r[1]));
        Bond d;
        d.a = *a, d.b = *b, d.kn = r[2], d.ks = r[3], d.tensile = r[4], d.cohesion = r[5], d.friction = r[6];
        d.restOverlap = r[7], d.gammaN = r[8], d.gammaT = r[9], d.shearForce = Vec3(r[10], r[11], r[12]);
        bonds.push_back(d);
      }
      const std::size_t nm = sim_.materials_.size();
      auto lawOf = [&](std::uint32_t x, std::uint32_t y) -> const BondingLaw* {
        const int l = sim_.lawOf_[spheres.material[x] * nm + spheres.material[y]];
        return l < 0 ? nullptr : sim_.laws_[static_cast<std::size_t>(l)]->bonding();
      };
      sim_.bonds_.replace(std::move(bonds), std::move(everBonded), lawOf, true);
    }
    bondRecords = {};
    sim_.replaceBodies(std::move(bodies), std::move(spheres), std::move(owner), rank_, pairOf, wallOf);
    // initialize() decided rotation from the share's spins: the run's is any rank's (later cuts keep it).
    if (first) {
      sim_.rotation_ = allReduce(sim_.rotation_ ? 1.0 : 0.0, MPI_MAX) > 0.0;
      bondsFormed_ = allReduce(static_cast<double>(sim_.bonds_.created()), MPI_MAX) > 0.0;
    }
    if (!meshes.empty()) {
      std::vector<MeshContact> contacts;
      std::vector<ContactHistory> history;
      for (std::size_t i = 0; i < meshes.size(); i += kMeshRecord) {
        const double* r = &meshes[i];
        MeshContact c;
        c.sphere = *local(static_cast<std::uint64_t>(r[0]));  // an owned sphere: it came with its contacts
        c.mesh = static_cast<std::uint32_t>(r[1]), c.triangle = static_cast<std::uint32_t>(r[2]);
        c.key = std::bit_cast<std::uint64_t>(r[3]), c.law = static_cast<int>(r[4]);
        c.point.normal = Vec3(r[5], r[6], r[7]);
        contacts.push_back(c);
        history.push_back({Vec3(r[8], r[9], r[10]), r[11]});
      }
      // By (law, sphere, mesh) as the step leaves them; a sphere's contacts with a mesh in their order.
      std::vector<std::size_t> order(contacts.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      auto key = [&](std::size_t i) { return std::tuple(contacts[i].law, contacts[i].sphere, contacts[i].mesh); };
      std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return key(x) < key(y); });
      std::vector<MeshContact> sortedContacts;
      std::vector<ContactHistory> sortedHistory;
      for (auto i : order) sortedContacts.push_back(contacts[i]), sortedHistory.push_back(history[i]);
      sim_.meshWalls_->setLastContacts(std::move(sortedContacts), std::move(sortedHistory));
    }
    anchor_ = sim_.bodies_.position;
    ++migrations_;
    // The first force pass, initialize()'s, is whole only with the other ranks' shares of it.
    if (first) returnGhostForces();
  }

  void sendGhostStates() {
    Bodies& B = sim_.bodies_;
    const auto P = static_cast<std::size_t>(size_);
    std::vector<std::vector<double>> out(P);
    for (std::size_t r = 0; r < P; ++r)
      for (auto b : sendTo_[r]) {
        const Quat& q = B.orientation[b];
        const double s[kGhostState] = {B.position[b].x(), B.position[b].y(), B.position[b].z(),
                                       B.velocity[b].x(), B.velocity[b].y(), B.velocity[b].z(),
                                       B.angularVelocity[b].x(), B.angularVelocity[b].y(), B.angularVelocity[b].z(),
                                       B.angularMomentum[b].x(), B.angularMomentum[b].y(), B.angularMomentum[b].z(),
                                       q.w(), q.x(), q.y(), q.z()};
        out[r].insert(out[r].end(), s, s + kGhostState);
      }
    std::vector<int> expected(P);
    for (std::size_t r = 0; r < P; ++r) expected[r] = static_cast<int>(kGhostState * ghostFrom_[r].size());
    const std::vector<double> in = allToAll(out, &expected);
    std::size_t i = 0;
    for (std::size_t r = 0; r < P; ++r)
      for (auto b : ghostFrom_[r]) {
        const double* s = &in[i];
        i += kGhostState;
        B.position[b] = Vec3(s[0], s[1], s[2]), B.velocity[b] = Vec3(s[3], s[4], s[5]);
        B.angularVelocity[b] = Vec3(s[6], s[7], s[8]), B.angularMomentum[b] = Vec3(s[9], s[10], s[11]);
        B.orientation[b] = Quat(s[12], s[13], s[14], s[15]);
      }
  }

  // The forces this rank's pairs put on ghosts, added to their bodies on their own ranks.
  void returnGhostForces() {
    Bodies& B = sim_.bodies_;
    const auto P = static_cast<std::size_t>(size_);
    std::vector<std::vector<double>> out(P);
    for (std::size_t r = 0; r < P; ++r)
      for (auto b : ghostFrom_[r]) {
        const Vec3 &f = B.force[b], &t = B.torque[b];
        out[r].insert(out[r].end(), {f.x(), f.y(), f.z(), t.x(), t.y(), t.z()});
      }
    std::vector<int> expected(P);
    for (std::size_t r = 0; r < P; ++r) expected[r] = static_cast<int>(6 * sendTo_[r].size());
    const std::vector<double> in = allToAll(out, &expected);
    std::size_t i = 0;
    for (std::size_t r = 0; r < P; ++r)
      for (auto b : sendTo_[r]) {
        B.force[b] += Vec3(in[i], in[i + 1], in[i + 2]);
        B.torque[b] += Vec3(in[i + 3], in[i + 4], in[i + 5]);
        i += 6;
      }
  }

  Simulation& sim_;
  int rank_, size_;
  std::size_t total_ = 0;  // bodies in the whole scene
  double margin_ = 0.0, width_ = 0.0;
  Slabs slabs_;
  std::vector<std::uint64_t> gid_;  // per local body, its number in the whole scene
  std::vector<int> owner_;          // per local body, its rank
  // Per rank: the owned bodies it holds as ghosts, and the ghosts it owns, both in id order.
  std::vector<std::vector<std::uint32_t>> sendTo_, ghostFrom_;
  std::vector<Vec3> anchor_;  // positions at the last cut
  std::int64_t migrations_ = 0;
  std::size_t ghosts_ = 0;
  EnergyLedger ledger_;
  double initial_ = 0.0;
  int failed_ = 0;
  double messageSeconds_ = 0.0, cutSeconds_ = 0.0;
  bool cutDue_ = false;
  bool bondsFormed_ = false;  // on some rank, at the start
};

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
    throw common::ConfigError(fmt::format("{}: a run on several ranks takes spheres, plane and mesh walls only (dem_solver/README.md, "
                                          "\"Several ranks\"); run it on one rank",
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
  std::vector<std::string> planeNames;
  for (const auto& p : sim.planes()) planeNames.push_back(p.name);
  if (root) {
    h5 = std::move(common::openResults(outDir / "dem.h5", {}, kStandaloneKind, sim.shape(), outDir / "checkpoint" / "dem.h5").h5);
    std::vector<std::string> energyColumns = {"kinetic", "potential", "elastic",       "damping", "friction",
                                              "cundall", "wall_work", "external_work", "residual"};
    if (sim.bondingLaws()) energyColumns.insert(energyColumns.begin() + 6, "bond_fracture");
    h5->addSeries("energy", energyColumns);
    for (auto b : scene.output.track)
      h5->addSeries(fmt::format("body_{}", b), {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz", "contacts"});
    std::vector<std::string> wallColumns;
    for (const auto& name : planeNames)
      for (const char* c : {"_fx", "_fy", "_fz"}) wallColumns.push_back(name + c);
    for (const auto& m : sim.meshes())
      for (const char* c : {"_fx", "_fy", "_fz", "_mx", "_my", "_mz"}) wallColumns.push_back(m.name + c);
    if (!wallColumns.empty()) h5->addSeries("walls", wallColumns);
    addMeshWalls(*h5, sim);
  }
  auto writeSeries = [&] {
    const EnergyLedger& e = ranked.ledger();
    std::vector<double> walls;
    for (const auto& f : sim.planeForces()) walls.insert(walls.end(), {f.x(), f.y(), f.z()});
    for (const auto& m : sim.meshes())
      walls.insert(walls.end(), {m.force.x(), m.force.y(), m.force.z(), m.moment.x(), m.moment.y(), m.moment.z()});
    MPI_Allreduce(MPI_IN_PLACE, walls.data(), static_cast<int>(walls.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    const std::vector<std::uint32_t>& track = scene.output.track;
    // A tracked body's contacts are counted where they are computed: on its rank, and on lower ones that
    // hold it as a ghost.
    std::vector<double> contacts(track.size(), 0.0);
    for (std::size_t i = 0; i < track.size(); ++i)
      if (const auto b = ranked.local(track[i])) contacts[i] = sim.bodyContacts(*b).count;
    MPI_Allreduce(MPI_IN_PLACE, contacts.data(), static_cast<int>(contacts.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    std::vector<double> rows;  // each tracked body's row from its rank: its place in `track`, then the row
    for (std::size_t i = 0; i < track.size(); ++i) {
      const auto b = ranked.local(track[i]);
      if (!b || !ranked.owned(*b)) continue;
      const Vec3 v = sim.bodyVelocity(*b);
      const Vec3 &x = sim.bodies().position[*b], &w = sim.bodies().angularVelocity[*b], &f = sim.bodies().force[*b];
      rows.insert(rows.end(), {static_cast<double>(i), x.x(), x.y(), x.z(), v.x(), v.y(), v.z(), w.x(), w.y(), w.z(),
                               f.x(), f.y(), f.z()});
    }
    rows = gatherAtRoot(rows, ranks.rank, ranks.size);
    if (!root) return;
    std::vector<double> energy = {e.kinetic, e.potential, e.elastic,      e.damping,
                                  e.friction, e.cundall,   e.wallWork,     e.externalWork,
                                  e.residual(ranked.initialEnergy())};
    if (sim.bondingLaws()) energy.insert(energy.begin() + 6, e.bondFracture);
    h5->append("energy", sim.time(), energy);
    for (std::size_t at = 0; at < rows.size(); at += 13) {
      const auto i = static_cast<std::size_t>(rows[at]);
      std::vector<double> row(rows.begin() + static_cast<std::ptrdiff_t>(at) + 1,
                              rows.begin() + static_cast<std::ptrdiff_t>(at) + 13);
      row.push_back(contacts[i]);
      h5->append(fmt::format("body_{}", track[i]), sim.time(), row);
    }
    if (!walls.empty()) h5->append("walls", sim.time(), walls);
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
