#pragma once
// The linear lattice model: 6 dofs per node (translation u [m], small rotation θ [rad]), one stiffness
// per rod from its rod law, supports for a uniaxial test, and the sparse stiffness K of the free dofs.
//
// Loading (lattice_solver/README.md "Loading"): the nodes on the two planes normal to `axis` at the ends
// of the specimen's box (for a volume specimen its bounding box) are the supports. The face at origin + size is moved by ε·H along the axis (ε the applied strain, H the specimen height), the
// opposite face is held at 0 along the axis. With `lateralFixed` both faces are glued to rigid plates
// (all translations prescribed); otherwise the lateral translations are free except at two nodes per
// face (near the centre: both lateral directions; a quarter width away: the tangential one), which only
// remove the rigid-body motions of each half once the specimen has cracked through.
//
// Unknowns: the free dofs, numbered node by node in a spatial (Morton) order; a dof no rod stiffens
// (rotations of a truss lattice) is not free and stays 0. The equilibrium K x = ε b + h has b the load
// of the prescribed displacements per unit strain and h the values of held fragments (below).
//
// Two operators for K (scene key solver.operator): `assembled` stores K as a symmetric sparse matrix
// of 6 × 6 node blocks (the diagonal blocks and one block per rod: ≈ 330 bytes per rod), and removing a
// rod subtracts its stiffness in place (the block pattern never changes); `matrix_free` stores only each rod's axis and springs (≈ 64 bytes) and
// computes K x rod by rod — the same numbers, a tenth of the memory. A fragment that loses its last
// connection to the supports is held where it is (its rows become diagonal, its rods inert): a
// quasi-static model cannot move a free body, and K would be singular.
//
// Not thread safe; OpenMP inside assembly and strain evaluation.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "lattice/rod_law.hpp"
#include "lattice/specimen.hpp"

namespace common {
class StateArchive;
}

namespace lattice {

/// A side of the specimen box: the nodes on the plane normal to `axis` at its low (side 0) or high
/// (side 1) end.
struct Face {
  int axis = 2;  ///< 0 x, 1 y, 2 z
  int side = 0;  ///< 0 min, 1 max
};

/// Participant mode: how a face couples. Dirichlet: its nodes' three translations are prescribed from
/// outside (their rotations stay free: the other side has no rotations to give); Neumann: its nodes are
/// free and take nodal forces from outside.
enum class FaceMode { kDirichlet, kNeumann };

struct CoupledFace {
  Face face;
  FaceMode mode = FaceMode::kDirichlet;
};

struct Supports {
  int axis = 2;               ///< loading direction: 0 x, 1 y, 2 z
  bool lateralFixed = true;   ///< loaded faces glued to rigid plates
  /// Participant mode: when not empty, these faces replace the uniaxial supports above (a node on two
  /// listed faces belongs to the first). At least one must be Dirichlet (else the lattice floats).
  std::vector<CoupledFace> coupled;
  /// Loaded area A [m²] the stress is the reaction over; 0: the box volume over its height (a box, a
  /// prism along the axis). Volume specimens give the area of their face at the top of the axis.
  double loadedArea = 0.0;
};

enum class Operator { kAssembled, kMatrixFree };

/// Per phase (index = Phase): relative stiffnesses and critical strains (both > 0).
struct PhaseProperties {
  RelativeStiffness stiffness;
  double tensileStrain = 2e-4;      ///< ε_t: a rod is removed when its strain exceeds it
  double compressiveStrain = 2e-3;  ///< ε_c: … or falls below −ε_c
};

class Model {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
  using Block = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;

  Model(const Specimen& specimen, std::unique_ptr<RodLaw> law, const std::array<PhaseProperties, kPhaseCount>& phases,
        const RodSection& section, const Supports& supports, Operator op = Operator::kAssembled);
  Model(Model&&) noexcept;
  Model& operator=(Model&&) noexcept;
  ~Model();

  std::size_t nodes() const { return nodes_.size(); }
  std::size_t rods() const { return rods_.size(); }
  std::size_t freeDofs() const { return static_cast<std::size_t>(b_.size()); }
  Operator op() const { return op_; }
  /// Values stored for the assembled K (36 per block; 0 for the matrix-free operator).
  std::int64_t nonZeros() const;
  const RodSection& section() const { return section_; }
  const Supports& supports() const { return supports_; }
  /// Specimen height H along the axis and loaded area [m, m²].
  double height() const { return height_; }
  double loadedArea() const { return area_; }
  Phase phase(std::size_t rod) const { return phases_[rod]; }
  const PhaseProperties& phaseProperties(Phase p) const { return props_[static_cast<std::size_t>(p)]; }
  double rodLength(std::size_t rod) const { return length_[rod]; }
  const Rod& rod(std::size_t r) const { return rods_[r]; }
  const std::vector<Vec3>& referenceNodes() const { return nodes_; }

  /// K on the free dofs as an Eigen sparse matrix, built from the blocks (tests, inspection). Assembled
  /// only.
  SparseMatrix stiffness() const;
  /// y = K x (either operator; in parallel).
  void apply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  /// The space of the single-precision inner solves (mixed-precision cg): 6 entries per node, nodes in
  /// the order the rod pass reads them, the entries of dofs that are not free 0. The products there
  /// need no gather from the free dofs into the rods' node order nor scatter back.
  Eigen::Index paddedSize() const { return static_cast<Eigen::Index>(6 * nodes_.size()); }
  /// The first of node n's 6 entries in the padded space.
  std::uint32_t paddedBase(std::size_t node) const { return 6 * slotOf_[node]; }
  /// x6 = scale · x in the padded space.
  void toPadded(const Eigen::VectorXd& x, double scale, Eigen::VectorXf& x6) const;
  /// x += scale · x6 over the free dofs.
  void addFromPadded(const Eigen::VectorXf& x6, double scale, Eigen::VectorXd& x) const;
  /// y6 = K̃ x6 in single precision in the padded space, K̃ from the rods' data rounded to float
  /// (matrix-free operator only): the product of the inner solves of mixed-precision cg. x6 must be 0
  /// at the dofs that are not free; y6 is.
  void applySingle(const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const;
  /// y += K_r x summed over `rods` (alive or removed) at their ends' free dofs: how much K x drops when
  /// those rods go (mixed-precision cg updates its residual with it instead of a new product).
  void addRodProducts(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  /// (K x) restricted to the dofs of one block (the averaging solver's node update).
  Vec6 blockProduct(std::size_t block, const Eigen::VectorXd& x) const;
  /// The diagonal block of K of one node (top-left m × m used, m = its free dofs).
  Block diagonalBlock(std::size_t block) const;
  /// The block of a node, −1 when it has no free dof.
  std::int32_t blockOf(std::size_t node) const { return blockOf_[node]; }
  /// Node blocks of free dofs: block i holds dofs blockStart()[i] … blockStart()[i+1]−1 of one node.
  const std::vector<std::uint32_t>& blockStart() const { return blockStart_; }
  /// Blocks in the order the averaging solver sweeps them: nearest the loaded faces first (the LGM
  /// updates "beginning with the elements along the boundaries", Kozicki & Donzé 2008 §2.2).
  const std::vector<std::uint32_t>& sweepOrder() const { return sweepOrder_; }

  /// The right-hand side ε b + h.
  Eigen::VectorXd rhs(double strain) const;
  /// The held dofs' values (0 for the others): the solution is x(ε) = held + ε K⁻¹b, so
  /// held + (ε'/ε)(x(ε) − held) is exact at ε' while no rod breaks.
  Eigen::VectorXd heldValues() const;
  /// All 6 dofs of every node (6 n + k; k = 0..2 u, 3..5 θ) from the free dofs x at strain ε.
  void fullDisplacement(const Eigen::VectorXd& x, double strain, std::vector<double>& u) const;
  /// Axial strain of a rod, (u_b − u_a)·e/L (small strain), from a full displacement.
  double rodStrain(std::size_t rod, std::span<const double> u) const;
  /// The axial force the specimen exerts on the moving face's supports [N] (positive in tension).
  double reaction(std::span<const double> u) const;
  /// The generalised force (force [N], moment [N·m]) the rods of node n need at its dofs for the full
  /// displacement u: Σ_rods (K_rod u_rod) at n. At a supported dof it is the support force.
  Vec6 nodeForce(std::uint32_t n, std::span<const double> u) const;

  /// Participant mode: the nodes of coupled face i (Supports::coupled order).
  const std::vector<std::uint32_t>& faceNodes(std::size_t i) const { return faceNodes_[i]; }
  /// Participant mode: the right-hand side −K_fc g + f + h for prescribed values g at the constrained
  /// dofs and external nodal forces f at the free dofs (both 6 per node, other entries ignored).
  Eigen::VectorXd rhs(std::span<const double> prescribed, std::span<const double> force) const;
  /// Participant mode: all 6 dofs of every node from the free dofs x and the prescribed values g.
  void fullDisplacement(const Eigen::VectorXd& x, std::span<const double> prescribed, std::vector<double>& u) const;

  /// What removals change (K, the load, the rod and hold states), to go back to: a coupled window is
  /// repeated from its start, and rods that broke in a rejected iterate must come back.
  struct Checkpoint {
    std::vector<Block> stiffness;  // what the storage keeps of K beyond the states (Stiffness::values)
    std::vector<std::int32_t> layout;  // on disk only: the storage's layout (Stiffness::layout)
    Eigen::VectorXd b, h;
    std::vector<std::uint8_t> state, held;
    std::size_t removed = 0, heldCount = 0, logSize = 0;
    void archive(common::StateArchive& a);
  };
  Checkpoint checkpoint() const;
  /// Returns to a checkpoint of this model: rods removed and nodes held since then are back (nothing is
  /// copied when nothing changed). Solvers see restores() change and recompute what they derived from K.
  void restore(const Checkpoint& c);
  std::size_t restores() const { return restores_; }
  /// What a checkpoint on disk must have been written by: nodes, rods, free dofs, operator and stored
  /// values (a lattice of another scene or another operator is refused).
  std::string shape() const;
  /// The state of a Checkpoint and the whole removal log, to or from disk (restart); reading counts
  /// as a restore and refuses (ConfigError) a state of other dimensions. The caller states the shape
  /// (StateArchive::shape) the checkpoint is checked against before anything is read.
  void archive(common::StateArchive& a);

  bool alive(std::size_t rod) const { return state_[rod] == kAlive; }
  /// A rod that can still break: alive and not in a held fragment.
  bool active(std::size_t rod) const { return state_[rod] == kAlive && !held_[rods_[rod][0]]; }
  std::size_t removedCount() const { return removed_; }
  std::size_t heldNodes() const { return heldCount_; }
  bool held(std::size_t node) const { return held_[node] != 0; }

  /// Removes rods (active ones only; COSIM_ASSERT otherwise) and updates K and b in place. Then holds,
  /// at their positions in x, the nodes no longer connected to a support. Returns the nodes newly held.
  std::size_t removeRods(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x);

  /// The 12×12 stiffness of a rod (its law's, in global axes; dofs [u_a θ_a u_b θ_b]).
  Mat12 rodStiffness(std::size_t r) const;
  /// Per node and dof (6 n + k): its free index, or −1.
  const std::vector<std::int32_t>& dofMap() const { return dofMap_; }
  /// The node of each block.
  const std::vector<std::uint32_t>& blockNodes() const { return blockNode_; }
  const Box& box() const { return box_; }
  /// Every removed rod, in the order of removal (solvers update what they derived from K with it).
  const std::vector<std::uint32_t>& removalLog() const { return removalLog_; }

 private:
  // Takes over a checkpoint's state (restore, archive) and tells the solvers through restores().
  void assign(const Checkpoint& c);
  // K's values, stored one way (solver.operator): lattice_solver/src/stiffness.hpp.
  class Stiffness;
  class AssembledBlocks;
  class MatrixFreeRods;
  enum : std::uint8_t { kAlive = 0, kRemoved = 1 };
  // Adds sign × the load of the prescribed displacements through the rows of rod r's stiffness k that
  // belong to its end `side` to b. Touches only that node's rows (safe in parallel over nodes).
  void addSupportLoad(std::size_t r, int side, const Mat12& k, double sign);
  // Generalised forces of rod r at its two ends for the free-dof vector x (constrained dofs as 0).
  std::array<Vec6, 2> rodEndForces(std::size_t r, const Eigen::VectorXd& x) const;
  // The same at one end.
  Vec6 rodEndForce(std::size_t r, int side, const Eigen::VectorXd& x) const { return rodEndForces(r, x)[static_cast<std::size_t>(side)]; }
  // The 6 dofs of node n from x (constrained ones 0).
  Vec6 gather(std::uint32_t n, const Eigen::VectorXd& x) const;
  // The entries of node n's free dofs in `full` (6 per node), in dof order, at the front.
  Vec6 freeEntries(std::uint32_t n, const Vec6& full) const;
  // x6 = scale · x in the padded space (T: double, float).
  template <typename T>
  void pad(const Eigen::VectorXd& x, double scale, Eigen::Matrix<T, Eigen::Dynamic, 1>& x6) const;
  std::size_t holdDetached(const Eigen::VectorXd& x);
  // Whether the ends of each of these (removed) rods are still connected through alive rods (then no
  // piece came loose and holdDetached has nothing to do).
  bool endsStillConnected(std::span<const std::uint32_t> rods) const;
  mutable std::vector<std::uint8_t> reached_;  // scratch of endsStillConnected, all 0 between calls
  // Participant mode: the nodes of each coupled face; the supports for them.
  void coupledSupports(const Specimen& sp);

  Box box_;
  std::vector<Vec3> nodes_;
  std::vector<Rod> rods_;
  std::vector<std::uint32_t> removalLog_;
  std::vector<Phase> phases_;
  std::vector<double> length_;
  std::vector<Vec3> axis_;           // unit vector a → b
  std::vector<RodSprings> springs_;  // per rod, from its law
  std::unique_ptr<RodLaw> law_;
  Operator op_;
  std::array<PhaseProperties, kPhaseCount> props_;
  RodSection section_;
  Supports supports_;
  double height_ = 0.0, area_ = 0.0;

  std::vector<std::int32_t> dofMap_;      // 6 per node: free index or −1
  std::vector<std::int32_t> nodeBase_;    // per node: its first free index (−1: none)
  std::vector<std::uint8_t> freeMask_;    // per node: bit k set when dof k is free
  std::vector<double> prescribed_;        // 6 per node: displacement per unit strain of constrained dofs
  std::vector<std::uint8_t> constrained_; // 6 per node: 1 if prescribed (0 or ε·H)
  std::vector<std::uint8_t> movingFace_;  // per node: on the moving face
  std::vector<std::uint32_t> blockStart_, blockNode_, sweepOrder_;
  std::vector<std::int32_t> blockOf_;
  std::vector<std::uint32_t> nodeRodStart_, nodeRods_;  // node → incident rods
  std::vector<std::uint32_t> slotOf_;   // per node: its slot in the K x scratch (Morton order of the nodes)
  std::vector<std::uint32_t> nodeOfSlot_;  // per slot: its node (the inverse of slotOf_)
  Eigen::VectorXd b_, h_, diagonal_;  // diagonal_: of the intact K, the rows of held nodes
  std::vector<std::uint8_t> state_, held_;
  std::size_t removed_ = 0, heldCount_ = 0, restores_ = 0;
  std::vector<std::vector<std::uint32_t>> faceNodes_;
  std::vector<std::uint32_t> boundaryRods_;  // rods with an end that has a constrained dof
  std::unique_ptr<Stiffness> k_;
};

}  // namespace lattice
