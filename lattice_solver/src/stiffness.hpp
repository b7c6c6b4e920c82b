#pragma once
// The stiffness K of a Model's free dofs, stored one way (scene key solver.operator; model.hpp says what
// each costs). A storage holds K's values only: the model's numbering, rods, springs and rod and hold
// states come in as `m` with every call, so a model can move without its storage pointing back.
//
// Model does everything that does not depend on how K is stored (the load b, fragments, the padded
// space); each storage answers the few questions that do, one virtual call per product or per node.

#include <cstdint>
#include <memory>
#include <type_traits>
#include <vector>

#include <Eigen/Core>
#include <omp.h>

#include "lattice/model.hpp"

namespace lattice {

class Model::Stiffness {
 public:
  virtual ~Stiffness() = default;
  /// y = K x (in parallel).
  virtual void apply(const Model& m, const Eigen::VectorXd& x, Eigen::VectorXd& y) const = 0;
  /// y6 = K̃ x6 in single precision in the padded space (Model::applySingle); not every storage has it.
  virtual void applySingle(const Model& m, const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const;
  /// (K x) at all 6 dofs of the node of block blk; the entries of dofs that are not free are not used.
  virtual Vec6 nodeProduct(const Model& m, std::size_t blk, const Eigen::VectorXd& x) const = 0;
  /// The 6 × 6 diagonal block of K at the node of block blk, rows and columns of dofs that are not
  /// free unused.
  virtual Block nodeDiagonal(const Model& m, std::size_t blk) const = 0;
  /// Rod r (now marked removed) with stiffness k leaves K.
  virtual void remove(const Model& m, std::uint32_t r, const Mat12& k) = 0;
  /// The node of block blk is held: its rows and columns become its intact diagonal (Model::diagonal_).
  virtual void hold(const Model& m, std::size_t blk) = 0;
  /// After one or more hold() calls.
  virtual void afterHolds(const Model& m) { (void)m; }
  /// Values stored for K (for the run's summary).
  virtual std::int64_t nonZeros() const = 0;
  /// K as an Eigen sparse matrix (tests, inspection).
  virtual SparseMatrix matrix(const Model& m) const = 0;
  /// What removals and holds changed in the stored values that the rod and hold states do not give
  /// back (empty when K follows from them alone): kept by checkpoints, in memory and on disk.
  virtual std::vector<Block> values() const = 0;
  /// How the storage is laid out where that changes the rounding of K x (empty when it does not): a
  /// restart rebuilds exactly this layout, so that it continues bit for bit.
  virtual std::vector<std::int32_t> layout() const { return {}; }
  /// Back to `values` (and `layout`, when given) of this storage, the model's rod and hold states
  /// already restored.
  virtual void restore(const Model& m, const std::vector<Block>& values, const std::vector<std::int32_t>& layout) = 0;
};

/// K as 6 × 6 node blocks: the diagonal blocks and one block per pair of rod neighbours (upper triangle),
/// changed in place by removals; the block pattern never changes.
class Model::AssembledBlocks final : public Model::Stiffness {
 public:
  explicit AssembledBlocks(const Model& m);
  void apply(const Model& m, const Eigen::VectorXd& x, Eigen::VectorXd& y) const override;
  Vec6 nodeProduct(const Model& m, std::size_t blk, const Eigen::VectorXd& x) const override;
  Block nodeDiagonal(const Model& m, std::size_t blk) const override;
  void remove(const Model& m, std::uint32_t r, const Mat12& k) override;
  void hold(const Model& m, std::size_t blk) override;
  std::int64_t nonZeros() const override { return static_cast<std::int64_t>(36 * (diag_.size() + upper_.size())); }
  SparseMatrix matrix(const Model& m) const override;
  std::vector<Block> values() const override;
  void restore(const Model& m, const std::vector<Block>& values, const std::vector<std::int32_t>& layout) override;

 private:
  // Adds sign × the rows of rod r's stiffness k that belong to its end `side`. Touches only that node's
  // blocks (safe in parallel over nodes).
  void addRows(const Model& m, std::size_t r, int side, const Mat12& k, double sign);
  // Position in upper_ of block (i, j), i < j (it exists by construction).
  std::size_t upperIndex(std::uint32_t i, std::uint32_t j) const;

  // Diagonal blocks per node block, upper blocks (i < j) in rows upStart_/upCol_, and per block the
  // references loRef_ (with their rows loRow_) to the upper blocks of its column.
  std::vector<Block> diag_, upper_;
  std::vector<std::uint32_t> upStart_, upCol_, loStart_, loRef_, loRow_;
  mutable Eigen::VectorXd xPad_, yPad_;           // scratch of K x: 6 per block
  mutable std::vector<Eigen::VectorXd> yThread_;  // per thread beyond the first: its share of K x
};

namespace detail {
/// Rods per RodBlock: one AVX2 register of T (4 doubles, 8 floats).
template <typename T>
inline constexpr int kRodLanes = 32 / static_cast<int>(sizeof(T));
/// What the matrix-free K x needs of kRodLanes consecutive rods, field by field, so that the rod law
/// runs across the rods in SIMD lanes. Unused lanes have zero springs. T = float is the
/// single-precision copy of the inner solves (Model::applySingle).
template <typename T>
struct alignas(32) RodBlock {
  static constexpr int L = kRodLanes<T>;
  std::uint32_t a[L], b[L];  ///< slots of the ends, a < b
  T e[3][L];                 ///< unit axis a → b
  T halfL[L];
  T shear[L], normalMinusShear[L];      ///< k_s, k_n − k_s
  T bending[L], torsionMinusBending[L];  ///< k_R, k_T − k_R
  void clear(int lane) { shear[lane] = normalMinusShear[lane] = bending[lane] = torsionMinusBending[lane] = 0; }
};

// What a rod exerts at its ends, la at a and lb at b, for end displacements ua, ub (6 each: u, θ), unit
// axis e (a → b), half length h: W = ½[k_n Δn² + k_s |Δs|² + k_T Φt² + k_R |Φb|²] with
// Δ = u_b − u_a − h (θ_a + θ_b) × e and Φ = θ_b − θ_a (rod_law.hpp); F = ∂W/∂Δ, M = ∂W/∂Φ, T = h F × e.
// End a gets (−F, T − M), end b (F, T + M).
// V is double for one rod, or a vector of lanes for several (matrix_free_rods.cpp); ks_n = k_n − k_s,
// kr_t = k_T − k_R.
template <typename V>
inline void rodLoads(const V* ua, const V* ub, const V& ex, const V& ey, const V& ez, const V& h, const V& ks, const V& ksn,
                     const V& kr, const V& krt, V* la, V* lb) {
  const V tx = ua[3] + ub[3], ty = ua[4] + ub[4], tz = ua[5] + ub[5];
  const V dx = ub[0] - ua[0] - h * (ty * ez - tz * ey);
  const V dy = ub[1] - ua[1] - h * (tz * ex - tx * ez);
  const V dz = ub[2] - ua[2] - h * (tx * ey - ty * ex);
  const V px = ub[3] - ua[3], py = ub[4] - ua[4], pz = ub[5] - ua[5];
  const V dn = ksn * (dx * ex + dy * ey + dz * ez);
  const V pt = krt * (px * ex + py * ey + pz * ez);
  const V F0 = ks * dx + dn * ex, F1 = ks * dy + dn * ey, F2 = ks * dz + dn * ez;
  const V M0 = kr * px + pt * ex, M1 = kr * py + pt * ey, M2 = kr * pz + pt * ez;
  const V T0 = h * (F1 * ez - F2 * ey), T1 = h * (F2 * ex - F0 * ez), T2 = h * (F0 * ey - F1 * ex);
  la[0] = -F0, la[1] = -F1, la[2] = -F2, la[3] = T0 - M0, la[4] = T1 - M1, la[5] = T2 - M2;
  lb[0] = F0, lb[1] = F1, lb[2] = F2, lb[3] = T0 + M0, lb[4] = T1 + M1, lb[5] = T2 + M2;
}

// Runs part(t, team, out) on each OpenMP thread t of the team, each writing its own vector (thread 0
// writes y, the others their scratch), and adds them to y in thread order: deterministic for a given
// thread count. K x scatters into rows other threads own, so the shares cannot share one vector.
template <typename Vector, typename Part>
void sumOverThreads(Vector& y, std::vector<Vector>& scratch, const Part& part) {
  const int nt = omp_get_max_threads();
  if (nt == 1) {
    part(std::size_t{0}, std::size_t{1}, y);
    return;
  }
  scratch.resize(static_cast<std::size_t>(nt - 1));
  for (auto& v : scratch) v.resize(y.size());
#pragma omp parallel num_threads(nt)
  {
    const auto size = static_cast<std::size_t>(omp_get_num_threads());
    const auto t = static_cast<std::size_t>(omp_get_thread_num());
    part(t, size, t == 0 ? y : scratch[t - 1]);
#pragma omp barrier
    // Each thread adds the others' parts over its own slice, in thread order: the same sum per entry
    // as a serial loop, without leaving the second core idle.
    const auto n = static_cast<std::size_t>(y.size());
    const auto begin = static_cast<Eigen::Index>(n * t / size), end = static_cast<Eigen::Index>(n * (t + 1) / size);
    for (std::size_t k = 0; k + 1 < size; ++k) y.segment(begin, end - begin) += scratch[k].segment(begin, end - begin);
  }
}
}  // namespace detail

/// K from the rods themselves: each rod that carries stiffness keeps its axis and springs in a record
/// read in sequence (≈ 64 bytes), and K x is computed rod by rod. A rod removed or held later keeps its
/// record with zero springs until the next rebuild (a restore).
class Model::MatrixFreeRods final : public Model::Stiffness {
 public:
  explicit MatrixFreeRods(const Model& m);
  void apply(const Model& m, const Eigen::VectorXd& x, Eigen::VectorXd& y) const override;
  void applySingle(const Model& m, const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const override;
  Vec6 nodeProduct(const Model& m, std::size_t blk, const Eigen::VectorXd& x) const override;
  Block nodeDiagonal(const Model& m, std::size_t blk) const override;
  void remove(const Model& m, std::uint32_t r, const Mat12& k) override;
  void hold(const Model& m, std::size_t blk) override;
  void afterHolds(const Model& m) override { buildFixNodes(m); }
  std::int64_t nonZeros() const override { return 0; }
  SparseMatrix matrix(const Model& m) const override;
  std::vector<Block> values() const override { return {}; }
  /// The record of each rod (−1: none): the stream is rebuilt without removed rods only at a restore,
  /// and the threads' shares of the pass follow the records.
  std::vector<std::int32_t> layout() const override { return streamOf_; }
  void restore(const Model& m, const std::vector<Block>& values, const std::vector<std::int32_t>& layout) override;

 private:
  template <typename T>
  struct RodPass {  // a stream of the rods and the scratch of its product, in precision T
    std::vector<detail::RodBlock<T>> stream;
    mutable Eigen::Matrix<T, Eigen::Dynamic, 1> xPad, yPad;
    mutable std::vector<Eigen::Matrix<T, Eigen::Dynamic, 1>> yThread;
  };
  // y6 = K x6 in the padded space over the records of `pass`; rows of dofs that are not free and of
  // held nodes as the rods leave them (apply, applySingle set them).
  template <typename T>
  static void rodPass(const RodPass<T>& pass, const Eigen::Matrix<T, Eigen::Dynamic, 1>& x6, Eigen::Matrix<T, Eigen::Dynamic, 1>& y6);
  // stream_ from the rod states (construction, restore).
  void buildStream(const Model& m);
  // stream_ with the records of `order` (rods), in that order.
  void fillStream(const Model& m, const std::vector<std::uint32_t>& order);
  // fixNodes_ from the free dofs and the held nodes (construction, holding, restore).
  void buildFixNodes(const Model& m);
  void clearRecord(std::int32_t record);

  // Every rod that carries stiffness (alive, not in a held fragment, some end with a free dof), ordered
  // by its end nodes, with all its product needs in one record.
  RodPass<double> stream_;
  RodPass<float> streamSingle_;
  std::vector<std::int32_t> streamOf_;  // per rod: its record in the streams (block × lanes + lane), −1 if none
  std::vector<std::uint32_t> fixNodes_;  // nodes whose padded rows applySingle sets: not all 6 dofs free, or held
};

}  // namespace lattice
