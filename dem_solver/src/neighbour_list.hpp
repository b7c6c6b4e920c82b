#pragma once
// The neighbour list of dem::Simulation: when the contact candidates must be built again, the sphere-pair
// search, and the active spheres. Candidates stay valid while nothing moved more than its Verlet skin
// since their build: the list keeps the bodies' poses (and the walls' positions) at the last build of
// each kind of candidate — sphere pairs, sphere–plane, sphere–mesh — and compares. The candidates
// themselves belong to their kinds' components (SpherePairs, PlaneWalls, MeshWalls).
//
// Call order: addBody() per body as the scene is built, prepare() at Simulation::initialize(); per step
// needsRebuild(), and at a rebuild findPairs() and the components' builds, each followed by its
// *Built(), then findActive(). Not thread safe; the searches use OpenMP inside. Units SI.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "contact_set.hpp"
#include "dem/bonds.hpp"
#include "dem/model.hpp"
#include "mesh_walls.hpp"
#include "step_context.hpp"
#include "transient.hpp"

namespace dem {

namespace detail {
// The spheres in cell order as the pair search reads them: centres and radii as structure of arrays,
// and each one's index. Eight entries past the last are read, not used.
struct CellOrdered {
  std::vector<double> x, y, z, r;
  std::vector<std::uint32_t> index;
  void resize(std::size_t n) {
    x.resize(n + 8), y.resize(n + 8), z.resize(n + 8), r.resize(n + 8), index.resize(n + 8);
  }
  std::size_t heapBytes() const { return common::heapBytes(x, y, z, r, index); }
};
}  // namespace detail

class NeighbourList {
 public:
  /// Which kinds of candidates to build again.
  struct Rebuild {
    bool pairs = false, planes = false, mesh = false;
  };

  /// A body whose farthest member centre is `reach` from its centre of mass [m].
  void addBody(double reach) { prepared_.bodyReach.push_back(reach); }
  /// `pairsPossible` false: one body only, no sphere pairs to search.
  void prepare(bool pairsPossible) { prepared_.pairsPossible = pairsPossible; }
  /// A run on several ranks: each sphere's rank (`owner`, per sphere) and this one's. findPairs() then keeps
  /// a pair only if this rank is the lower of its spheres' ranks, so that every pair is computed on one
  /// rank, once (the other rank gets the force on its sphere back). Empty: one rank, every pair.
  void setOwners(std::vector<int> owner, int rank) { prepared_.owner = std::move(owner), prepared_.rank = rank; }
  /// Whether this rank computes the pair of spheres s and t (always on one rank).
  bool computes(std::uint32_t s, std::uint32_t t) const {
    return prepared_.owner.empty() || std::min(prepared_.owner[s], prepared_.owner[t]) == prepared_.rank;
  }
  bool pairsPossible() const { return prepared_.pairsPossible; }

  /// Whether a body moved (a member by its body's translation plus the chord of its turn), or a wall,
  /// far enough since each kind's build that a pair outside the candidates may touch: sphere pairs by
  /// half the skin relative to the motion they share, planes and meshes by their skins with the walls'
  /// own motion added. `lone`: every body one sphere at its centre (no turn to bound).
  Rebuild needsRebuild(const Bodies& bodies, bool lone, const SimulationSettings& settings,
                       const std::vector<PlaneWall>& planes, const std::vector<MeshWall>& meshes) const;
  /// The sphere pairs with a law within r_a + r_b + skin, members of one body and bonded pairs left
  /// out, as (law, a, b) sorted by (a, b) (ContactSet::assign orders several laws). Reads
  /// spheres.position, which must be current. The list is the neighbour list's work space, valid until
  /// the next call.
  std::vector<Triple>& findPairs(const StepContext& ctx, const BondSet& bonds);
  /// The poses (and wall positions) of a build of that kind, kept for needsRebuild().
  void pairsBuilt(const Bodies& bodies, bool lone) { keepPoses(atPairs_, bodies, lone); }
  void planesBuilt(const Bodies& bodies, bool lone, const std::vector<PlaneWall>& planes);
  void meshBuilt(const Bodies& bodies, bool lone, const std::vector<MeshWall>& meshes);
  /// The active spheres, those in some candidate (sphere pairs, plane `walls`, mesh) or bond, and per
  /// body its run of them; every sphere's force and torque sums (ctx.force, ctx.torque) are cleared.
  void findActive(const StepContext& ctx, const ContactSet& pairs, const ContactSet& walls,
                  const MeshContacts& mesh, const BondSet& bonds);
  void countRebuild() { ++rebuilds_; }
  void addRebuilds(std::int64_t n) { rebuilds_ += n; }

  /// Spheres in any contact candidate or bond (sorted), and per body its run of them: activeStart()[b]
  /// .. activeStart()[b+1]. Only these are moved and gathered each step — a 22,000-sphere block touches
  /// a net with a few thousand.
  const std::vector<std::uint32_t>& active() const { return active_; }
  const std::vector<std::uint32_t>& activeStart() const { return activeStart_; }
  std::int64_t rebuilds() const { return rebuilds_; }

  void archive(common::StateArchive& a) {
    a.io("poses_at_pairs", atPairs_), a.io("poses_at_planes", atPlanes_), a.io("poses_at_mesh", atMesh_);
    a.io("plane_points_at_build", planePointsAtBuild_), a.io("mesh_nodes_at_build", meshNodesAtBuild_);
    a.io("active", active_), a.io("active_start", activeStart_), a.io("rebuilds", rebuilds_);
  }
  std::size_t heapBytes() const {
    return common::heapBytes(atPairs_, atPlanes_, atMesh_, planePointsAtBuild_, meshNodesAtBuild_, active_,
                             activeStart_, prepared_.bodyReach, prepared_.owner, work_->lists, work_->inCandidate,
                             work_->cellOrdered, work_->cellStart, work_->cellIndex, work_->threadCount);
  }

 private:
  struct Poses {
    std::vector<Vec3> position;
    std::vector<Quat> orientation;
    void archive(common::StateArchive& a) { a.io("position", position), a.io("orientation", orientation); }
    std::size_t heapBytes() const { return common::heapBytes(position, orientation); }
  };
  struct Prepared {
    std::vector<double> bodyReach;  // largest distance of a member centre from the body's centre [m]
    bool pairsPossible = true;      // more than one body
    std::vector<int> owner;         // per sphere, its rank (setOwners); empty: one rank
    int rank = 0;
  };
  // The pair search's arrays, kept from build to build.
  struct Work {
    CandidateLists lists;
    std::vector<unsigned char> inCandidate;  // per sphere
    detail::CellOrdered cellOrdered;         // the pair search's copies of the spheres
    std::vector<std::uint32_t> cellStart, cellIndex;  // per cell its first sphere in cell order; per sphere its cell
    std::vector<std::uint32_t> threadCount;  // per thread, its active spheres
  };
  /// The pair search's grid: linked cells of edge ≥ 2 r_max + skin with a layer of empty cells around,
  /// each sphere's cell (Work::cellIndex), each cell's run of spheres (Work::cellStart), the centres and
  /// radii in cell order (Work::cellOrdered). Returns the index offsets of the 9 runs of three cells along
  /// x around a cell (run r: cells row[r] .. row[r] + 2).
  std::array<std::ptrdiff_t, 9> sortIntoCells(const Spheres& spheres, double skin);
  /// The sphere pairs within the skin, by the grid sortIntoCells() made, into `pairs` (empty) sorted by (a, b).
  void collectPairs(const StepContext& ctx, const BondSet& bonds, const std::array<std::ptrdiff_t, 9>& row,
                    std::vector<Triple>& pairs);
  Rebuild needsRebuildLone(const Bodies& bodies, const SimulationSettings& settings,
                           const std::vector<PlaneWall>& planes) const;
  double planesMoved(const std::vector<PlaneWall>& planes) const;  // the farthest a plane moved since its build [m]
  void keepPoses(Poses& at, const Bodies& bodies, bool lone);

  Poses atPairs_, atPlanes_, atMesh_;
  std::vector<Vec3> planePointsAtBuild_;
  std::vector<std::vector<Vec3>> meshNodesAtBuild_;
  std::vector<std::uint32_t> active_, activeStart_;
  std::int64_t rebuilds_ = 0;
  // From the scene (addBody, prepare): copied with the list, so a copy works alone; not archived, a
  // restart builds the scene again.
  Prepared prepared_;
  detail::Transient<Work> work_;
};

}  // namespace dem
