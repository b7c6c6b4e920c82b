// RankedSimulation (ranked_simulation.hpp). Each rank holds a Simulation of its share of the bodies (those
// whose centres of mass are in its slab, each with its member spheres) and of ghosts: the bodies of other
// slabs whose spheres may come within reach of its own. A sphere pair is computed by one rank, the lower
// of its spheres' ranks (a member's is its body's; NeighbourList::setOwners), which sends the force and
// torque on the other's body back to its rank: each pair's force and energy is computed once, as on one
// rank, so the ledger is the sum of the ranks' ledgers. Ghosts are not moved here (BodyMotion kGhost):
// their ranks send their states after every step. When some body has moved half the margin since the
// last cut, the slabs are cut again at the sphere counts' quantiles and the bodies move to their new
// ranks with the histories of their contacts. The ghost width covers the contact reach at a neighbour
// rebuild (2 r_max + skin, and both bodies' reach from their centres of mass to their farthest members)
// plus the margin: until the next cut no sphere out of reach of a rank's share can come within it.
#include "ranked_simulation.hpp"

#include <mpi.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>

#include <fmt/format.h>

#include "contact_set.hpp"
#include "dem/contact_queries.hpp"
#include "dem/bonds.hpp"
#include "mesh_walls.hpp"
#include "neighbour_list.hpp"
#include "plane_walls.hpp"
#include "rank_messages.hpp"
#include "sphere_pairs.hpp"

namespace dem {

namespace {

using detail::allReduce, detail::allToAll;
constexpr int kHistogramBins = 4096;
// A body as it travels between ranks: id, state, mass properties, its sphere count (kBody values), then
// each member sphere: its centre in the body frame, radius, material and whether it was ever bonded.
constexpr std::size_t kBody = 32, kMember = 6;
std::size_t recordSize(const double* r) { return kBody + kMember * static_cast<std::size_t>(r[kBody - 1]); }
// The farthest of a record's member centres from its centre of mass [m].
double recordReach(const double* r) {
  double reach = 0.0;
  for (std::size_t k = 0, n = static_cast<std::size_t>(r[kBody - 1]); k < n; ++k) {
    const double* m = r + kBody + kMember * k;
    reach = std::max(reach, std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]));
  }
  return reach;
}
constexpr std::size_t kBondRecord = 13;  // spheres' ids, the bond's constants and its shear force
constexpr std::size_t kGhostState = 16;  // position, velocity, angular velocity and momentum, orientation
constexpr std::size_t kMeshRecord = 12;  // a mesh contact: sphere, mesh, triangle, feature, law, normal, history

}  // namespace

RankedSimulation::RankedSimulation(Simulation& sim, const Ranks& ranks, common::StateArchive* from)
    : sim_(sim), rank_(ranks.rank), size_(ranks.size) {
  takeScene();
  if (from) readShare(*from);
  else migrate();
}

RankedSimulation::RankedSimulation(Simulation& sim, const Ranks& ranks, const std::vector<common::StateArchive*>& shares,
                                   common::StateArchive& any)
    : sim_(sim), rank_(ranks.rank), size_(ranks.size) {
  takeScene();
  if (shares.empty()) readShare(any);  // the run's clock, walls and integrator; the shares' otherwise
  reshare(shares);
}

void RankedSimulation::takeScene() {
  Simulation& sim = sim_;
  sim.resolveSkins();  // from all spheres: the same skins on every rank
  const Bodies& B = sim.bodies_;
  const Spheres& S = sim.spheres_;
  gid_.resize(B.size());
  std::iota(gid_.begin(), gid_.end(), std::uint64_t{0});
  sid_.resize(S.size());
  std::iota(sid_.begin(), sid_.end(), std::uint64_t{0});
  owner_.resize(B.size());
  for (std::size_t b = 0; b < B.size(); ++b) owner_[b] = static_cast<int>(b % static_cast<std::size_t>(size_));
  total_ = B.size();
  firstSphereOf_.assign(B.firstSphere.begin(), B.firstSphere.end());
  for (std::size_t b = 0; b < B.size(); ++b) {
    const Vec3& I = B.inertia[b];
    for (std::uint32_t k = 0; k < B.sphereCount[b]; ++k) reachMax_ = std::max(reachMax_, S.local[B.firstSphere[b] + k].norm());
    sim.loneScene_ &= B.sphereCount[b] == 1 && S.local[B.firstSphere[b]].squaredNorm() == 0.0 && I.x() == I.y() &&
                      I.y() == I.z();
  }
  double rmax = 0.0;
  for (double r : S.radius) rmax = std::max(rmax, r);
  margin_ = sim.settings().rankMargin;
  width_ = 2.0 * rmax + sim.settings().skin + margin_;
}

void RankedSimulation::archiveShare(common::StateArchive& a) {
  auto scope = a.scope("ranks");
  a.io("spheres", sim_.spheres_);
  a.io("ids", gid_), a.io("sphere_ids", sid_), a.io("owner", owner_), a.io("slabs", slabs_), a.io("send_to", sendTo_);
  a.io("ghost_from", ghostFrom_), a.io("anchor", anchor_), a.io("ghosts", ghosts_), a.io("migrations", migrations_);
  a.io("cut_due", cutDue_), a.io("bonds_formed", bondsFormed_);
}

void RankedSimulation::archive(common::StateArchive& a) {
  sim_.archiveState(a);
  archiveShare(a);
}

void RankedSimulation::readShare(common::StateArchive& a) {
  Bodies bodies;
  {
    auto scope = a.scope("simulation");
    a.io("bodies", bodies);
  }
  archiveShare(a);  // the spheres into sim_.spheres_, moved on below
  // The share set up as the scene's bodies would be (initialize(): the neighbour list's and the
  // integrator's prepared parts), then its state read over it.
  const auto none = [](std::uint32_t, std::uint32_t) { return ContactHistory{}; };
  Spheres spheres = std::move(sim_.spheres_);
  std::vector<int> owner = sphereOwners(spheres);
  sim_.replaceBodies(std::move(bodies), std::move(spheres), std::move(owner), rank_, none, none);
  sim_.archiveState(a);
}

void RankedSimulation::step() {
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

struct RankedSimulation::Saved {
  std::shared_ptr<const Simulation::Checkpoint> sim;
  Spheres spheres;
  Slabs slabs;
  std::vector<std::uint64_t> gid, sid;
  std::vector<int> owner;
  BodyLists sendTo, ghostFrom;
  std::vector<Vec3> anchor;
  std::size_t ghosts;
  EnergyLedger ledger;
  double initial;
  bool cutDue;
};

std::shared_ptr<const RankedSimulation::Saved> RankedSimulation::save() const {
  return std::make_shared<const Saved>(Saved{sim_.saveCheckpoint(), sim_.spheres_, slabs_, gid_, sid_, owner_, sendTo_,
                                             ghostFrom_, anchor_, ghosts_, ledger_, initial_, cutDue_});
}

void RankedSimulation::restore(const Saved& s) {
  // The spheres too, which a cut since save() replaced (bodies and contacts are in the checkpoint). The cuts
  // counted and the timers go on: the repeated window's cuts are work done.
  sim_.spheres_ = s.spheres;
  sim_.restoreCheckpoint(*s.sim);
  slabs_ = s.slabs, gid_ = s.gid, sid_ = s.sid, owner_ = s.owner, sendTo_ = s.sendTo, ghostFrom_ = s.ghostFrom;
  anchor_ = s.anchor, ghosts_ = s.ghosts, ledger_ = s.ledger, initial_ = s.initial, cutDue_ = s.cutDue;
}

void RankedSimulation::refuseOverlaps() const {
  const auto [a, b, overlap] = largestSphereOverlap(sim_);
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
  detail::alone = false;
  throw common::ConfigError(fmt::format("body {} overlaps body {} by {:.4g} m at the start (tolerance {:.3g} m = 0.1 % of "
                                        "the smaller sphere radius); move them apart (dem_solver --check on one rank "
                                        "names the line)",
                                        bodies[1], bodies[0], values[0], values[1]));
}

std::optional<std::uint32_t> RankedSimulation::local(std::uint64_t id) const {
  const auto it = std::lower_bound(gid_.begin(), gid_.end(), id);
  if (it == gid_.end() || *it != id) return std::nullopt;
  return static_cast<std::uint32_t>(it - gid_.begin());
}

std::optional<std::uint32_t> RankedSimulation::localSphere(std::uint64_t id) const {
  const auto it = std::lower_bound(sid_.begin(), sid_.end(), id);
  if (it == sid_.end() || *it != id) return std::nullopt;
  return static_cast<std::uint32_t>(it - sid_.begin());
}

std::vector<int> RankedSimulation::sphereOwners(const Spheres& spheres) const {
  std::vector<int> owner(spheres.size());
  for (std::size_t s = 0; s < spheres.size(); ++s) owner[s] = owner_[spheres.body[s]];
  return owner;
}

void RankedSimulation::reduceLedger(bool failed) {
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

void RankedSimulation::throwAgreed(const std::optional<common::Instability>& mine) {
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
  detail::alone = false;
  throw common::InstabilityError(i);
}

void RankedSimulation::pack(std::size_t b, std::vector<double>& out) const {
  const Bodies& B = sim_.bodies_;
  const Spheres& S = sim_.spheres_;
  const Quat& q = B.orientation[b];
  const double rec[kBody] = {static_cast<double>(gid_[b]),
                             B.position[b].x(), B.position[b].y(), B.position[b].z(),
                             B.velocity[b].x(), B.velocity[b].y(), B.velocity[b].z(),
                             B.angularVelocity[b].x(), B.angularVelocity[b].y(), B.angularVelocity[b].z(),
                             B.angularMomentum[b].x(), B.angularMomentum[b].y(), B.angularMomentum[b].z(),
                             q.w(), q.x(), q.y(), q.z(), B.mass[b],
                             B.inertia[b].x(), B.inertia[b].y(), B.inertia[b].z(),
                             B.force[b].x(), B.force[b].y(), B.force[b].z(),
                             B.torque[b].x(), B.torque[b].y(), B.torque[b].z(),
                             B.externalForce[b].x(), B.externalForce[b].y(), B.externalForce[b].z(),
                             static_cast<double>(B.fixed[b]), static_cast<double>(B.sphereCount[b])};
  out.insert(out.end(), rec, rec + kBody);
  const auto& ever = sim_.bonds_.everBonded();
  for (std::uint32_t s = B.firstSphere[b], end = s + B.sphereCount[b]; s < end; ++s)
    out.insert(out.end(), {S.local[s].x(), S.local[s].y(), S.local[s].z(), S.radius[s], static_cast<double>(S.material[s]),
                           s < ever.size() ? static_cast<double>(ever[s]) : 0.0});
}

void RankedSimulation::unpack(const double* r, bool isGhost, Bodies& B, Spheres& S, std::vector<std::uint8_t>& everBonded) {
  auto v = [&](std::size_t i) { return Vec3(r[i], r[i + 1], r[i + 2]); };
  const auto b = static_cast<std::uint32_t>(B.size());
  const auto gid = static_cast<std::uint64_t>(r[0]);
  B.position.push_back(v(1)), B.velocity.push_back(v(4)), B.angularVelocity.push_back(v(7));
  B.angularMomentum.push_back(v(10)), B.orientation.push_back(Quat(r[13], r[14], r[15], r[16]));
  B.mass.push_back(r[17]), B.inertia.push_back(v(18)), B.force.push_back(v(21)), B.torque.push_back(v(24));
  B.externalForce.push_back(v(27));
  const auto motion = static_cast<std::uint8_t>(r[30]);
  B.fixed.push_back(!isGhost ? motion : motion == kFixed ? std::uint8_t{kFixedGhost} : std::uint8_t{kGhost});
  const auto n = static_cast<std::uint32_t>(r[kBody - 1]);
  B.firstSphere.push_back(static_cast<std::uint32_t>(S.size())), B.sphereCount.push_back(n);
  // Member centres are placed from the body's pose once the share is whole (replaceBodies).
  for (std::uint32_t k = 0; k < n; ++k) {
    const double* m = r + kBody + kMember * k;
    S.local.push_back(v(kBody + kMember * k)), S.position.push_back(v(1)), S.radius.push_back(m[3]);
    S.material.push_back(static_cast<std::uint32_t>(m[4])), S.body.push_back(b);
    sid_.push_back(firstSphereOf_[gid] + k);
    everBonded.push_back(m[5] > 0.0 ? 1 : 0);
  }
}

void RankedSimulation::reserve(Bodies& B, Spheres& S, std::size_t bodies, std::size_t spheres) {
  for (auto* v : {&B.position, &B.velocity, &B.angularVelocity, &B.angularMomentum, &B.inertia, &B.force, &B.torque,
                  &B.externalForce})
    v->reserve(bodies);
  B.orientation.reserve(bodies), B.mass.reserve(bodies), B.fixed.reserve(bodies), B.firstSphere.reserve(bodies);
  B.sphereCount.reserve(bodies);
  S.local.reserve(spheres), S.position.reserve(spheres), S.radius.reserve(spheres), S.material.reserve(spheres);
  S.body.reserve(spheres);
}

Slabs RankedSimulation::cut() const {
  const Bodies& B = sim_.bodies_;
  return cutAt([&](auto&& visit) {
    for (std::size_t b = 0; b < B.size(); ++b)
      if (owner_[b] == rank_) visit(B.position[b], B.sphereCount[b]);
  });
}

template <class ForEachOwned>
Slabs RankedSimulation::cutAt(ForEachOwned&& forEachOwned) const {
  double lo[3], hi[3];
  for (int c = 0; c < 3; ++c) lo[c] = std::numeric_limits<double>::infinity(), hi[c] = -lo[c];
  forEachOwned([&](const Vec3& x, std::uint32_t) {
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], x[c]), hi[c] = std::max(hi[c], x[c]);
  });
  MPI_Allreduce(MPI_IN_PLACE, lo, 3, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, hi, 3, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  int axis = 0;
  for (int c = 1; c < 3; ++c)
    if (hi[c] - lo[c] > hi[axis] - lo[axis]) axis = c;
  std::vector<double> counts(kHistogramBins, 0.0);
  const double span = std::max(hi[axis] - lo[axis], 1e-300);
  forEachOwned([&](const Vec3& x, std::uint32_t spheres) {
    const auto i = static_cast<std::size_t>((x[axis] - lo[axis]) / span * kHistogramBins);
    counts[std::min(i, counts.size() - 1)] += spheres;  // the work goes with the spheres
  });
  MPI_Allreduce(MPI_IN_PLACE, counts.data(), kHistogramBins, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return Slabs::fromHistogram(axis, lo[axis], hi[axis], counts, size_);
}

namespace {

// The contact histories a cut brings, by their sides' global ids (pairs: sphere a < sphere b; walls:
// sphere, wall), sorted for the lookups: records of (kind 0 pair / 1 plane wall, id, id, shear xyz, overlap).
class HistoryIndex {
 public:
  explicit HistoryIndex(const std::vector<double>& records) {
    for (std::size_t i = 0; i < records.size(); i += 7) {
      const double* h = &records[i];
      Keyed k{{static_cast<std::uint64_t>(h[1]), static_cast<std::uint64_t>(h[2])}, {Vec3(h[3], h[4], h[5]), h[6]}};
      (h[0] == 0.0 ? pairs_ : walls_).push_back(k);
    }
    std::sort(pairs_.begin(), pairs_.end(), byKey);
    std::sort(walls_.begin(), walls_.end(), byKey);
  }
  ContactHistory pair(std::uint64_t a, std::uint64_t b) const { return find(pairs_, a, b); }
  ContactHistory wall(std::uint64_t sphere, std::uint64_t wall) const { return find(walls_, sphere, wall); }

 private:
  using Keyed = std::pair<std::pair<std::uint64_t, std::uint64_t>, ContactHistory>;
  static bool byKey(const Keyed& x, const Keyed& y) { return x.first < y.first; }
  static ContactHistory find(const std::vector<Keyed>& in, std::uint64_t a, std::uint64_t b) {
    const auto it = std::lower_bound(in.begin(), in.end(), Keyed{{a, b}, {}}, byKey);
    return it != in.end() && it->first == std::pair(a, b) ? it->second : ContactHistory{};
  }
  std::vector<Keyed> pairs_, walls_;
};

}  // namespace

RankedSimulation::Parcels RankedSimulation::packShare(const std::vector<int>& next) const {
  const Bodies& B = sim_.bodies_;
  const Spheres& S = sim_.spheres_;
  auto nextOf = [&](std::uint32_t sphere) { return next[S.body[sphere]]; };
  Parcels out(static_cast<std::size_t>(size_));
  for (std::size_t b = 0; b < B.size(); ++b)
    if (owner_[b] == rank_) pack(b, out.bodies[static_cast<std::size_t>(next[b])]);
  // Each touching contact's history to the rank that computes it next (an open contact's starts afresh),
  // by its spheres' ids: kind 0, a sphere pair; kind 1, a sphere and a plane wall.
  auto sendHistories = [&](const ContactSet& set, double kind, auto rankOf, auto second) {
    for (std::size_t k = 0; k < set.size(); ++k) {
      const ContactHistory& h = set.history[k];
      if (!(h.lastOverlap > 0.0)) continue;
      auto& to = out.histories[static_cast<std::size_t>(rankOf(k))];
      to.insert(to.end(), {kind, static_cast<double>(sid_[set.a[k]]), second(k), h.shearForce.x(), h.shearForce.y(),
                           h.shearForce.z(), h.lastOverlap});
    }
  };
  if (sim_.steps() == 0) return out;  // the first cut: no contacts yet, no bonds formed
  const ContactSet& pairs = sim_.pairs_->contacts();
  sendHistories(pairs, 0.0, [&](std::size_t k) { return std::min(nextOf(pairs.a[k]), nextOf(pairs.b[k])); },
                [&](std::size_t k) { return static_cast<double>(sid_[pairs.b[k]]); });
  const ContactSet& walls = sim_.planeWalls_->contacts();
  sendHistories(walls, 1.0, [&](std::size_t k) { return nextOf(walls.a[k]); },
                [&](std::size_t k) { return static_cast<double>(walls.b[k]); });
  // Mesh contacts (of owned spheres only) with the sphere: the feature key (its bits as a double), the
  // law, the normal and the history, which the next step's contact on that feature takes over.
  const MeshContacts& mc = sim_.meshWalls_->contacts();
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    const MeshContact& c = mc.contacts[i];
    const ContactHistory& h = mc.history[i];
    const Vec3& n = c.point.normal;
    auto& to = out.meshes[static_cast<std::size_t>(nextOf(c.sphere))];
    to.insert(to.end(), {static_cast<double>(sid_[c.sphere]), static_cast<double>(c.mesh), static_cast<double>(c.triangle),
                         std::bit_cast<double>(c.key), static_cast<double>(c.law), n.x(), n.y(), n.z(),
                         h.shearForce.x(), h.shearForce.y(), h.shearForce.z(), h.lastOverlap});
  }
  // Bonds to the rank that computes their pair next.
  for (const Bond& d : sim_.bonds_.bonds()) {
    auto& to = out.bonds[static_cast<std::size_t>(std::min(nextOf(d.a), nextOf(d.b)))];
    to.insert(to.end(), {static_cast<double>(sid_[d.a]), static_cast<double>(sid_[d.b]), d.kn, d.ks, d.tensile,
                         d.cohesion, d.friction, d.restOverlap, d.gammaN, d.gammaT, d.shearForce.x(),
                         d.shearForce.y(), d.shearForce.z()});
  }
  return out;
}

void RankedSimulation::Parcels::append(Parcels& more) {
  for (auto [to, from] : {std::pair{&bodies, &more.bodies}, std::pair{&histories, &more.histories},
                          std::pair{&meshes, &more.meshes}, std::pair{&bonds, &more.bonds}})
    for (std::size_t r = 0; r < to->size(); ++r) (*to)[r].insert((*to)[r].end(), (*from)[r].begin(), (*from)[r].end()), (*from)[r] = {};
}

void RankedSimulation::unpackShare(std::vector<double>& mine, Bodies& bodies, Spheres& spheres,
                                   std::vector<std::uint8_t>& everBonded) {
  const int axis = slabs_.axis;
  const auto P = static_cast<std::size_t>(size_);
  // The share in id order, and the ghosts each rank needs from it: a body whose centre of mass is within
  // the width, its reach and the largest reach of a rank's slab may touch a sphere there.
  auto reachOf = [&](const double* r) { return width_ + reachMax_ + recordReach(r); };
  std::vector<const double*> share;
  for (std::size_t i = 0; i < mine.size(); i += recordSize(&mine[i])) share.push_back(&mine[i]);
  std::sort(share.begin(), share.end(), [](const double* x, const double* y) { return x[0] < y[0]; });
  std::vector<std::vector<double>> ghostsOut(P);
  for (const double* r : share)
    slabs_.near(r[1 + axis], reachOf(r), rank_, [&](int to) {
      ghostsOut[static_cast<std::size_t>(to)].insert(ghostsOut[static_cast<std::size_t>(to)].end(), r, r + recordSize(r));
    });
  const std::vector<double> ghosts = allToAll(ghostsOut);
  ghostsOut = {};
  // Local numbering in id order, owned and ghosts together: a pair's (a, b) order and the order of a
  // sphere's contacts are those of one rank.
  struct Entry {
    const double* record;
    int owner;
  };
  std::vector<Entry> all;
  all.reserve(share.size() + ghosts.size() / kBody);
  for (const double* r : share) all.push_back({r, rank_});
  for (std::size_t i = 0; i < ghosts.size(); i += recordSize(&ghosts[i]))
    all.push_back({&ghosts[i], slabs_.owner(ghosts[i + 1 + static_cast<std::size_t>(axis)])});
  std::sort(all.begin(), all.end(), [](const Entry& x, const Entry& y) { return x.record[0] < y.record[0]; });
  std::size_t members = 0;
  for (const Entry& e : all) members += static_cast<std::size_t>(e.record[kBody - 1]);
  reserve(bodies, spheres, all.size(), members);
  gid_.clear(), sid_.clear(), owner_.clear();
  sid_.reserve(members);
  sendTo_.assign(P, {}), ghostFrom_.assign(P, {});
  everBonded.reserve(members);
  for (const Entry& e : all) {
    const auto b = static_cast<std::uint32_t>(gid_.size());
    unpack(e.record, e.owner != rank_, bodies, spheres, everBonded);
    gid_.push_back(static_cast<std::uint64_t>(e.record[0]));
    owner_.push_back(e.owner);
    if (e.owner != rank_) ghostFrom_[static_cast<std::size_t>(e.owner)].push_back(b);
    else slabs_.near(e.record[1 + axis], reachOf(e.record), rank_, [&](int to) { sendTo_[static_cast<std::size_t>(to)].push_back(b); });
  }
  ghosts_ = spheres.size();
  for (const double* r : share) ghosts_ -= static_cast<std::size_t>(r[kBody - 1]);
}

std::vector<Bond> RankedSimulation::unpackBonds(const std::vector<double>& records) const {
  std::vector<Bond> bonds;
  for (std::size_t i = 0; i < records.size(); i += kBondRecord) {
    const double* r = &records[i];
    const auto a = localSphere(static_cast<std::uint64_t>(r[0])), b = localSphere(static_cast<std::uint64_t>(r[1]));
    if (!a || !b)
      throw common::SimulationError(fmt::format("the bond of spheres {} and {} reaches beyond the ghost layer "
                                                "(neighbor.rank_margin); run on one rank",
                                                r[0], r[1]));
    Bond d;
    d.a = *a, d.b = *b, d.kn = r[2], d.ks = r[3], d.tensile = r[4], d.cohesion = r[5], d.friction = r[6];
    d.restOverlap = r[7], d.gammaN = r[8], d.gammaT = r[9], d.shearForce = Vec3(r[10], r[11], r[12]);
    bonds.push_back(d);
  }
  return bonds;
}

void RankedSimulation::setMeshContacts(const std::vector<double>& records) {
  std::vector<MeshContact> contacts;
  std::vector<ContactHistory> history;
  for (std::size_t i = 0; i < records.size(); i += kMeshRecord) {
    const double* r = &records[i];
    MeshContact c;
    c.sphere = *localSphere(static_cast<std::uint64_t>(r[0]));  // an owned sphere: it came with its contacts
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

void RankedSimulation::migrate() {
  const Bodies& B = sim_.bodies_;
  slabs_ = cut();
  // A ghost's new rank follows from the same position bits and cuts as on its own rank.
  std::vector<int> next(B.size());
  for (std::size_t b = 0; b < B.size(); ++b) next[b] = slabs_.owner(B.position[b][slabs_.axis]);
  receive(packShare(next));
}

void RankedSimulation::receive(Parcels out) {
  // What the share was is packed: its arrays and contacts go before the new ones come (the peak of a
  // cut is then one share, not two), and each parcel as soon as it is sent.
  sim_.releaseBodies();
  auto send = [](std::vector<std::vector<double>>& parcels) {
    std::vector<double> in = allToAll(parcels);
    parcels = {};
    return in;
  };
  const std::vector<double> bondRecords = send(out.bonds), meshes = send(out.meshes);
  std::vector<double> mine = send(out.bodies);
  const HistoryIndex histories(send(out.histories));
  Bodies bodies;
  Spheres spheres;
  std::vector<std::uint8_t> everBonded;
  unpackShare(mine, bodies, spheres, everBonded);
  mine = {};
  std::vector<int> owner = sphereOwners(spheres);
  const bool first = sim_.steps() == 0;
  if (!first && bondsFormed_) {
    // The bonds with their spheres' new numbers, before the contacts are built (bonded pairs are none).
    auto lawOf = [&](std::uint32_t x, std::uint32_t y) {
      return sim_.interactions_.bonding(spheres.material[x], spheres.material[y]);
    };
    sim_.bonds_.replace(unpackBonds(bondRecords), std::move(everBonded), lawOf, true);
  }
  auto pairOf = [&](std::uint32_t a, std::uint32_t b) { return histories.pair(sid_[a], sid_[b]); };
  auto wallOf = [&](std::uint32_t s, std::uint32_t w) { return histories.wall(sid_[s], w); };
  sim_.replaceBodies(std::move(bodies), std::move(spheres), std::move(owner), rank_, pairOf, wallOf);
  // initialize() decided rotation from the share's spins: the run's is any rank's (later cuts keep it).
  if (first) {
    sim_.rotation_ = allReduce(sim_.rotation_ ? 1.0 : 0.0, MPI_MAX) > 0.0;
    bondsFormed_ = allReduce(static_cast<double>(sim_.bonds_.created()), MPI_MAX) > 0.0;
  }
  if (!meshes.empty()) setMeshContacts(meshes);
  anchor_ = sim_.bodies_.position;
  ++migrations_;
  // The first force pass, initialize()'s, is whole only with the other ranks' shares of it.
  if (first) returnGhostForces();
}

void RankedSimulation::reshare(const std::vector<common::StateArchive*>& shares) {
  const int self = rank_;
  // The new slabs from the owned bodies of the shares this rank takes up: their centres and sphere counts.
  struct Owned {
    std::vector<Vec3> position;
    std::vector<std::uint32_t> spheres;
  } owned;
  // A share that cannot be read is every rank's error (exit 2), before the collective steps.
  std::string error;
  try {
    for (std::size_t k = 0; k < shares.size(); ++k) {
      common::StateArchive& a = *shares[k];
      const int wrote = self + static_cast<int>(k) * size_;
      Bodies bodies;
      std::vector<int> owner;
      {
        auto scope = a.scope("simulation");
        a.io("bodies", bodies);
      }
      {
        auto scope = a.scope("ranks");
        a.io("owner", owner);
      }
      if (owner.size() != bodies.size())
        throw common::ConfigError(fmt::format("{}: {} bodies and {} owners: a damaged share", a.path().string(),
                                              bodies.size(), owner.size()));
      for (std::size_t b = 0; b < bodies.size(); ++b)
        if (owner[b] == wrote) owned.position.push_back(bodies.position[b]), owned.spheres.push_back(bodies.sphereCount[b]);
    }
  } catch (const common::ConfigError& e) {
    error = e.what();
  }
  detail::agreeOnInput(error, self);
  const Slabs slabs = cutAt([&](auto&& visit) {
    for (std::size_t i = 0; i < owned.position.size(); ++i) visit(owned.position[i], owned.spheres[i]);
  });
  owned = {};
  // Each share as its own rank held it, packed for the new ranks as a cut packs it: its owned bodies, the
  // histories of the contacts it computed, its spheres' mesh contacts and its bonds. The ledger's terms and
  // the bond counts are the shares' sums (each rank books its own bodies, contacts and bonds: the run's
  // totals are unchanged).
  Parcels all(static_cast<std::size_t>(size_));
  EnergyLedger ledger{};
  double initial = 0.0;
  std::int64_t created = 0, broken = 0;  // bonds
  std::int64_t rebuilds = 0;  // the neighbour list's, the same on every rank of a run
  for (std::size_t k = 0; k < shares.size() && error.empty(); ++k) {
    rank_ = self + static_cast<int>(k) * size_;  // the share's rank in the run that wrote it
    try {
      readShare(*shares[k]);
    } catch (const common::ConfigError& e) {
      error = e.what();
      break;
    }
    const Bodies& B = sim_.bodies_;
    std::vector<int> next(B.size());
    for (std::size_t b = 0; b < B.size(); ++b) next[b] = slabs.owner(B.position[b][slabs.axis]);
    Parcels out = packShare(next);
    all.append(out);
    ledger += sim_.energy_;
    initial += sim_.initialEnergy_;
    created += sim_.bonds_.created(), broken += sim_.bonds_.broken();
    rebuilds = std::max(rebuilds, sim_.neighbours_->rebuilds());
  }
  rank_ = self;
  detail::agreeOnInput(error, self);
  slabs_ = slabs;
  receive(std::move(all));
  sim_.energy_ = ledger;
  sim_.initialEnergy_ = initial;
  sim_.bonds_.setCounts(created, broken);
  sim_.neighbours_->addRebuilds(std::max<std::int64_t>(rebuilds - sim_.neighbours_->rebuilds(), 0));
  cutDue_ = false;
}

template <class Pack, class Unpack>
void RankedSimulation::exchange(const BodyLists& from, const BodyLists& into, std::size_t width, Pack pack,
                                Unpack unpack) {
  const auto P = static_cast<std::size_t>(size_);
  std::vector<std::vector<double>> out(P);
  std::vector<int> expected(P);
  for (std::size_t r = 0; r < P; ++r) {
    for (auto b : from[r]) pack(b, out[r]);
    expected[r] = static_cast<int>(width * into[r].size());
  }
  const std::vector<double> in = allToAll(out, &expected);
  std::size_t i = 0;
  for (std::size_t r = 0; r < P; ++r)
    for (auto b : into[r]) unpack(b, &in[i]), i += width;
}

void RankedSimulation::sendGhostStates() {
  Bodies& B = sim_.bodies_;
  exchange(
      sendTo_, ghostFrom_, kGhostState,
      [&](std::uint32_t b, std::vector<double>& out) {
        const Quat& q = B.orientation[b];
        out.insert(out.end(), {B.position[b].x(), B.position[b].y(), B.position[b].z(), B.velocity[b].x(),
                               B.velocity[b].y(), B.velocity[b].z(), B.angularVelocity[b].x(),
                               B.angularVelocity[b].y(), B.angularVelocity[b].z(), B.angularMomentum[b].x(),
                               B.angularMomentum[b].y(), B.angularMomentum[b].z(), q.w(), q.x(), q.y(), q.z()});
      },
      [&](std::uint32_t b, const double* s) {
        B.position[b] = Vec3(s[0], s[1], s[2]), B.velocity[b] = Vec3(s[3], s[4], s[5]);
        B.angularVelocity[b] = Vec3(s[6], s[7], s[8]), B.angularMomentum[b] = Vec3(s[9], s[10], s[11]);
        B.orientation[b] = Quat(s[12], s[13], s[14], s[15]);
      });
}

void RankedSimulation::returnGhostForces() {
  Bodies& B = sim_.bodies_;
  exchange(
      ghostFrom_, sendTo_, 6,
      [&](std::uint32_t b, std::vector<double>& out) {
        const Vec3 &f = B.force[b], &t = B.torque[b];
        out.insert(out.end(), {f.x(), f.y(), f.z(), t.x(), t.y(), t.z()});
      },
      [&](std::uint32_t b, const double* s) {
        B.force[b] += Vec3(s[0], s[1], s[2]);
        B.torque[b] += Vec3(s[3], s[4], s[5]);
      });
}

}  // namespace dem
