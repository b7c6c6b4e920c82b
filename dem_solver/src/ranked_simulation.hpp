#pragma once
// A Simulation's share of a run on several MPI ranks (dem/ranked_run.hpp), and the messages that keep it
// one run: its slab, its ghosts, each sphere pair computed on one rank, the cuts that move spheres and
// their contacts between ranks. dem_solver/README.md, "Several ranks (MPI)", has the design.
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "dem/ranked_run.hpp"
#include "dem/simulation.hpp"
#include "slabs.hpp"

namespace dem {

class RankedSimulation {
 public:
  // `sim`: the whole scene, built and not initialized, on every rank; each rank keeps and initializes its
  // share: the first cut's, or, from a checkpoint this rank wrote (`from`), the share it held then.
  RankedSimulation(Simulation& sim, const Ranks& ranks, common::StateArchive* from = nullptr);
  // From the checkpoint of a run on another number of ranks: this rank takes up the shares `shares` of
  // that run (its ranks rank, rank + P, rank + 2P, … for P ranks now; none where the run had fewer), cuts
  // the slabs for P ranks and moves the bodies and their contacts there as a cut does. `any`: a share of
  // that run (rank 0's), for a rank that takes up none: the run's clock, walls and integrator.
  RankedSimulation(Simulation& sim, const Ranks& ranks, const std::vector<common::StateArchive*>& shares,
                   common::StateArchive& any);

  /// Writes this rank's share for a restart on as many ranks: the simulation's state, the spheres, the
  /// slabs, the ghosts and the cuts' state.
  void archive(common::StateArchive& a);

  // One step of the whole run; collective. A failure on any rank is every rank's.
  void step();
  /// Wall-clock seconds in the messages of the steps (ghost states and forces, the ledger's sums) and in
  /// the cuts (new slabs, bodies and histories moved, the share's contacts built) [s].
  double messageSeconds() const { return messageSeconds_; }
  double cutSeconds() const { return cutSeconds_; }

  /// This rank's share as it is now, for a coupled run's window that the coupler may repeat: the
  /// simulation's state, its spheres (a cut replaces them), the slabs, the ghosts and the ledger.
  struct Saved;
  std::shared_ptr<const Saved> save() const;
  /// Back to the share save() kept (every rank at once: their shares fit together only at the same step).
  void restore(const Saved& saved);

  // One rank's loadScene() refuses bodies that overlap at the start; here the pairs are each rank's.
  void refuseOverlaps() const;

  const EnergyLedger& ledger() const { return ledger_; }
  double initialEnergy() const { return initial_; }
  /// A local body's number in the whole scene, and whether this rank owns it.
  std::uint64_t id(std::size_t body) const { return body < gid_.size() ? gid_[body] : 0; }
  bool owned(std::size_t body) const { return owner_[body] == rank_; }
  /// A local sphere's number in the whole scene.
  std::uint64_t sphereId(std::size_t sphere) const { return sid_[sphere]; }
  /// The body with this id in the whole scene, if this rank holds it (owned or ghost).
  std::optional<std::uint32_t> local(std::uint64_t id) const;
  /// The sphere with this id in the whole scene, if this rank holds it.
  std::optional<std::uint32_t> localSphere(std::uint64_t id) const;
  std::int64_t migrations() const { return migrations_; }
  /// The spheres of ghost bodies here.
  std::size_t ghosts() const { return ghosts_; }
  std::size_t total() const { return total_; }
  const Slabs& slabs() const { return slabs_; }

  // The ledger summed over the ranks (and whether some rank failed): each rank books its own bodies and
  // the contacts it computes.
  void reduceLedger(bool failed);

 private:
  // The lowest failing rank's diagnosis, on every rank.
  [[noreturn]] void throwAgreed(const std::optional<common::Instability>& mine);

  void pack(std::size_t b, std::vector<double>& out) const;

  // Appends record `r` as the next body of `B` with its members to `S` (their ids to sid_, whether each was
  // ever bonded to `everBonded`); a ghost of a free body moves as kGhost.
  void unpack(const double* r, bool isGhost, Bodies& B, Spheres& S, std::vector<std::uint8_t>& everBonded);

  static void reserve(Bodies& B, Spheres& S, std::size_t bodies, std::size_t spheres);
  // Each sphere's rank: its body's.
  std::vector<int> sphereOwners(const Spheres& spheres) const;

  // Ids, owners and reaches from the whole scene that `sim` holds when the constructors start.
  void takeScene();
  Slabs cut() const;
  // Slabs for size_ ranks at the sphere counts' quantiles along the longest axis of the owned centres;
  // forEachOwned(visit) calls visit(centre, sphere count) for each body this rank owns. Collective.
  template <class ForEachOwned>
  Slabs cutAt(ForEachOwned&& forEachOwned) const;

  // What archive() writes besides the simulation's state, and reads back from a checkpoint.
  void archiveShare(common::StateArchive& a);
  // The share a checkpoint holds, initialized and then set to its state.
  void readShare(common::StateArchive& a);

  // New slabs; every body to its new rank, the touching contacts' histories to the rank that computes
  // them next, the ghosts to the ranks that need them.
  void migrate();
  // What a cut sends, per destination rank: the owned bodies with their members, the touching contacts'
  // histories, the mesh contacts and the bonds, to the ranks of `next` (per local body).
  struct Parcels {
    explicit Parcels(std::size_t ranks) : bodies(ranks), histories(ranks), meshes(ranks), bonds(ranks) {}
    // Appends `more`'s parcels to these, rank by rank, and empties them.
    void append(Parcels& more);
    std::vector<std::vector<double>> bodies, histories, meshes, bonds;
  };
  Parcels packShare(const std::vector<int>& next) const;
  // The second half of a cut: `out` sent, the share unpacked from what every rank sent here (bodies and
  // ghosts, histories, mesh contacts, bonds). Collective.
  void receive(Parcels out);
  // The shares of a checkpoint of a run on another number of ranks, redistributed (the constructor above).
  void reshare(const std::vector<common::StateArchive*>& shares);
  // The new share from its bodies' records (`mine`), with the ghosts the other ranks send for it: its
  // bodies, spheres and bonded flags, and the ids, owners and ghost lists here.
  void unpackShare(std::vector<double>& mine, Bodies& bodies, Spheres& spheres, std::vector<std::uint8_t>& everBonded);
  // The bonds received, between this rank's spheres.
  std::vector<Bond> unpackBonds(const std::vector<double>& records) const;
  // The mesh contacts received, which the next step's contacts on the same features take up.
  void setMeshContacts(const std::vector<double>& records);

  using BodyLists = std::vector<std::vector<std::uint32_t>>;  // per rank, local bodies in id order
  // `width` values per body, packed from the bodies `from[r]` for rank r, unpacked into the bodies
  // `into[r]` from rank r (the two ends of the same lists: a ghost's state out, its force back).
  template <class Pack, class Unpack>
  void exchange(const BodyLists& from, const BodyLists& into, std::size_t width, Pack pack, Unpack unpack);

  void sendGhostStates();

  // The forces this rank's pairs put on ghosts, added to their bodies on their own ranks.
  void returnGhostForces();

  Simulation& sim_;
  int rank_, size_;
  std::size_t total_ = 0;  // bodies in the whole scene
  double margin_ = 0.0, width_ = 0.0;
  Slabs slabs_;
  std::vector<std::uint64_t> gid_;  // per local body, its number in the whole scene
  std::vector<std::uint64_t> sid_;  // per local sphere, its number in the whole scene (ascending, as gid_)
  std::vector<std::uint64_t> firstSphereOf_;  // per body of the whole scene, its first sphere's number
  double reachMax_ = 0.0;  // the farthest member centre from its body's centre of mass in the scene [m]
  std::vector<int> owner_;          // per local body, its rank
  // Per rank: the owned bodies it holds as ghosts, and the ghosts it owns, both in id order.
  BodyLists sendTo_, ghostFrom_;
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

}  // namespace dem
