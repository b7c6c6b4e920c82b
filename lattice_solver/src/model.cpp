#include "lattice/model.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <omp.h>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "common/errors.hpp"

namespace lattice {

namespace {

// Interleaves the low 21 bits of x with two zero bits between each (Morton code helper).
std::uint64_t spread(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
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

// What a rod exerts at its ends, la at a and lb at b, for end displacements ua, ub (6 each: u, θ), unit
// axis e (a → b), half length h: W = ½[k_n Δn² + k_s |Δs|² + k_T Φt² + k_R |Φb|²] with
// Δ = u_b − u_a − h (θ_a + θ_b) × e and Φ = θ_b − θ_a (rod_law.hpp); F = ∂W/∂Δ, M = ∂W/∂Φ, T = h F × e.
// End a gets (−F, T − M), end b (F, T + M).
// V is double for one rod, or a vector of lanes for several (rodProductsIn); ks_n = k_n − k_s, kr_t = k_T − k_R.
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

// y += K x over the blocks [begin, end) (Model::applyRodPass): the rod law of rodLoads in SIMD across
// the rods of a block, the ends' loads added one rod after the other.
// GCC 12 reports the lane arrays below as maybe used uninitialised (each is written in full first).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#if defined(__SSE2__)
#define LATTICE_SSE_TRANSPOSE 1
// The single-precision pass moves each rod's 6 entries between per-node rows and its 8 lanes with
// 4 × 4 transposes (entries 0–3) and unpacks (entries 4–5) instead of one insert or extract per entry:
// those were a third of its instructions. SSE only, so the baseline clone has them too.
typedef float Float4 __attribute__((vector_size(16)));
typedef float Float8 __attribute__((vector_size(32)));
// v[c] = entry c of the nodes at p[0..7].
[[gnu::always_inline]] inline void gatherRows(const float* const* p, Float8* v) {
  Float4 half[2][6];
  for (int k = 0; k < 2; ++k) {
    const float* const* q = p + 4 * k;
    __m128 r0 = _mm_loadu_ps(q[0]), r1 = _mm_loadu_ps(q[1]), r2 = _mm_loadu_ps(q[2]), r3 = _mm_loadu_ps(q[3]);
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    const __m128 z = _mm_setzero_ps();
    const __m128 s = _mm_unpacklo_ps(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(q[0] + 4)),
                                     _mm_loadl_pi(z, reinterpret_cast<const __m64*>(q[1] + 4)));
    const __m128 t = _mm_unpacklo_ps(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(q[2] + 4)),
                                     _mm_loadl_pi(z, reinterpret_cast<const __m64*>(q[3] + 4)));
    half[k][0] = r0, half[k][1] = r1, half[k][2] = r2, half[k][3] = r3;
    half[k][4] = _mm_movelh_ps(s, t), half[k][5] = _mm_movehl_ps(t, s);
  }
  for (int c = 0; c < 6; ++c) v[c] = __builtin_shufflevector(half[0][c], half[1][c], 0, 1, 2, 3, 4, 5, 6, 7);
}
// The inverse: lane l's entries 0–3 in row[l], 4–5 in the low half of pair[l].
[[gnu::always_inline]] inline void scatterRows(const Float8* v, __m128* row, __m128* pair) {
  for (int k = 0; k < 2; ++k) {
    auto part = [&](int c) -> __m128 {
      return k == 0 ? __builtin_shufflevector(v[c], v[c], 0, 1, 2, 3) : __builtin_shufflevector(v[c], v[c], 4, 5, 6, 7);
    };
    __m128 r0 = part(0), r1 = part(1), r2 = part(2), r3 = part(3);
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    row[4 * k] = r0, row[4 * k + 1] = r1, row[4 * k + 2] = r2, row[4 * k + 3] = r3;
    const __m128 u = _mm_unpacklo_ps(part(4), part(5)), w = _mm_unpackhi_ps(part(4), part(5));
    pair[4 * k] = u, pair[4 * k + 1] = _mm_movehl_ps(u, u), pair[4 * k + 2] = w, pair[4 * k + 3] = _mm_movehl_ps(w, w);
  }
}
// y[0..5] += the row and pair.
[[gnu::always_inline]] inline void addRow(float* y, __m128 row, __m128 pair) {
  _mm_storeu_ps(y, _mm_add_ps(_mm_loadu_ps(y), row));
  auto* hi = reinterpret_cast<__m64*>(y + 4);
  _mm_storel_pi(hi, _mm_add_ps(_mm_loadl_pi(_mm_setzero_ps(), hi), pair));
}
#endif

template <typename T>
[[gnu::always_inline]] inline void rodProductsIn(const detail::RodBlock<T>* begin, const detail::RodBlock<T>* end, const T* xs,
                                                 T* ys) {
  if (begin == end) return;
  constexpr int L = detail::kRodLanes<T>;
  constexpr std::ptrdiff_t kAhead = 16 / L;  // blocks: 16 rods ahead
  typedef T Lanes __attribute__((vector_size(sizeof(T) * L)));
  // Built from scalars straight into registers (a store of lanes read back as a vector would stall).
  auto lanes = [&]<std::size_t... l>(Lanes& v, const T* const* ends, int c, std::index_sequence<l...>) { v = Lanes{ends[l][c]...}; };
  // Records run by their first end a, so a's load is summed in registers and written once per run:
  // writing it back per rod made the next rod's read of it wait on the store.
  std::uint32_t cur = begin->a[0];
  T fa[6] = {0, 0, 0, 0, 0, 0};
  auto flush = [&] {
    T* y = ys + 6 * static_cast<std::size_t>(cur);
    for (int c = 0; c < 6; ++c) y[c] += fa[c];
  };
#if LATTICE_SSE_TRANSPOSE
  __m128 faRow = _mm_setzero_ps(), faPair = _mm_setzero_ps();  // fa of the single-precision pass
#endif
  for (const detail::RodBlock<T>* p = begin; p != end; ++p) {
    const detail::RodBlock<T>& s = *p;
    // The b ends are scattered over x and y (L3, not L1): fetch a few blocks ahead.
    if (end - p > kAhead)
      for (int l = 0; l < L; ++l) {
        const std::size_t o = 6 * static_cast<std::size_t>(p[kAhead].b[l]);
        __builtin_prefetch(xs + o);
        __builtin_prefetch(xs + o + 5);
        __builtin_prefetch(ys + o, 1);
        __builtin_prefetch(ys + o + 5, 1);
      }
    const T* xa[L];
    const T* xb[L];
    for (int l = 0; l < L; ++l) {
      xa[l] = xs + 6 * static_cast<std::size_t>(s.a[l]);
      xb[l] = xs + 6 * static_cast<std::size_t>(s.b[l]);
    }
    Lanes ua[6], ub[6], la[6], lb[6];
#if LATTICE_SSE_TRANSPOSE
    if constexpr (std::is_same_v<T, float>) {
      gatherRows(xa, ua);
      gatherRows(xb, ub);
    } else
#endif
      for (int c = 0; c < 6; ++c) {
        lanes(ua[c], xa, c, std::make_index_sequence<L>{});
        lanes(ub[c], xb, c, std::make_index_sequence<L>{});
      }
    Lanes ex, ey, ez, h, ks, kb, knMinusKs, ktMinusKb;
    std::memcpy(&ex, s.e[0], sizeof ex);
    std::memcpy(&ey, s.e[1], sizeof ey);
    std::memcpy(&ez, s.e[2], sizeof ez);
    std::memcpy(&h, s.halfL, sizeof h);
    std::memcpy(&ks, s.shear, sizeof ks);
    std::memcpy(&kb, s.bending, sizeof kb);
    std::memcpy(&knMinusKs, s.normalMinusShear, sizeof knMinusKs);
    std::memcpy(&ktMinusKb, s.torsionMinusBending, sizeof ktMinusKb);
    rodLoads(ua, ub, ex, ey, ez, h, ks, knMinusKs, kb, ktMinusKb, la, lb);
#if LATTICE_SSE_TRANSPOSE
    if constexpr (std::is_same_v<T, float>) {
      // The same additions in the same order as the loop below, four entries at a time.
      __m128 rowA[L], pairA[L], rowB[L], pairB[L];
      scatterRows(la, rowA, pairA);
      scatterRows(lb, rowB, pairB);
      for (int l = 0; l < L; ++l) {
        if (s.a[l] != cur) {
          addRow(ys + 6 * static_cast<std::size_t>(cur), faRow, faPair);
          faRow = faPair = _mm_setzero_ps();
          cur = s.a[l];
        }
        faRow = _mm_add_ps(faRow, rowA[l]);
        faPair = _mm_add_ps(faPair, pairA[l]);
        addRow(ys + 6 * static_cast<std::size_t>(s.b[l]), rowB[l], pairB[l]);
      }
      continue;
    }
#endif
    for (int l = 0; l < L; ++l) {
      if (s.a[l] != cur) {
        flush();
        for (T& v : fa) v = 0;
        cur = s.a[l];
      }
      for (int c = 0; c < 6; ++c) fa[c] += la[c][l];
      T* yb = ys + 6 * static_cast<std::size_t>(s.b[l]);
      for (int c = 0; c < 6; ++c) yb[c] += lb[c][l];
    }
  }
#if LATTICE_SSE_TRANSPOSE
  if constexpr (std::is_same_v<T, float>) {
    addRow(ys + 6 * static_cast<std::size_t>(cur), faRow, faPair);
    return;
  }
#endif
  flush();
}

// Built twice on x86-64, for the baseline and for AVX2 + FMA, and picked at load time.
#if defined(__x86_64__) && defined(__GNUC__)
#define LATTICE_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define LATTICE_CLONES
#endif
LATTICE_CLONES void rodProducts(const detail::RodBlock<double>* begin, const detail::RodBlock<double>* end, const double* xs,
                                double* ys) {
  rodProductsIn(begin, end, xs, ys);
}
LATTICE_CLONES void rodProducts(const detail::RodBlock<float>* begin, const detail::RodBlock<float>* end, const float* xs,
                                float* ys) {
  rodProductsIn(begin, end, xs, ys);
}
#undef LATTICE_CLONES
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

}  // namespace

Model::Model(const Specimen& sp, std::unique_ptr<RodLaw> law, const std::array<PhaseProperties, kPhaseCount>& phases,
             const RodSection& section, const Supports& supports, Operator op)
    : box_(sp.box), nodes_(sp.nodes), rods_(sp.rods), phases_(sp.phases), law_(std::move(law)), op_(op), props_(phases),
      section_(section), supports_(supports) {
  COSIM_ASSERT(phases_.size() == rods_.size(), "{} phases for {} rods", phases_.size(), rods_.size());
  const std::size_t N = nodes_.size();
  const int ax = supports_.axis;
  height_ = sp.box.size[ax];
  area_ = supports_.loadedArea > 0 ? supports_.loadedArea : sp.box.volume() / height_;
  length_.resize(rods_.size());
  axis_.resize(rods_.size());
  springs_.resize(rods_.size());
  for (std::size_t r = 0; r < rods_.size(); ++r) {
    const Vec3 d = nodes_[rods_[r][1]] - nodes_[rods_[r][0]];
    length_[r] = d.norm();
    axis_[r] = d / length_[r];
    springs_[r] = law_->springs(length_[r], props_[static_cast<std::size_t>(phases_[r])].stiffness, section_);
  }

  nodeRodStart_.assign(N + 1, 0);
  for (const auto& rod : rods_)
    for (auto n : rod) ++nodeRodStart_[n + 1];
  std::partial_sum(nodeRodStart_.begin(), nodeRodStart_.end(), nodeRodStart_.begin());
  nodeRods_.resize(nodeRodStart_.back());
  {
    std::vector<std::uint32_t> fill(nodeRodStart_.begin(), nodeRodStart_.end() - 1);
    for (std::uint32_t r = 0; r < rods_.size(); ++r)
      for (auto n : rods_[r]) nodeRods_[fill[n]++] = r;
  }

  // Supports.
  constrained_.assign(6 * N, 0);
  prescribed_.assign(6 * N, 0.0);
  movingFace_.assign(N, 0);
  const double lo = sp.box.origin[ax], hi = lo + height_, tol = 1e-9 * height_;
  if (!supports_.coupled.empty()) {
    coupledSupports(sp);
  } else {
    std::vector<std::uint32_t> face[2];
    for (std::uint32_t n = 0; n < N; ++n) {
      if (nodeRodStart_[n + 1] == nodeRodStart_[n]) continue;
      if (std::abs(nodes_[n][ax] - lo) <= tol) face[0].push_back(n);
      if (std::abs(nodes_[n][ax] - hi) <= tol) face[1].push_back(n);
    }
    if (face[0].empty() || face[1].empty())
      throw std::invalid_argument("the specimen has no rod ends on one of its loaded faces");
    const int l1 = (ax + 1) % 3, l2 = (ax + 2) % 3;
    for (int f = 0; f < 2; ++f) {
      for (auto n : face[f]) {
        constrained_[6 * n + static_cast<std::size_t>(ax)] = 1;
        if (f == 1) {
          prescribed_[6 * n + static_cast<std::size_t>(ax)] = height_;
          movingFace_[n] = 1;
        }
        if (supports_.lateralFixed) constrained_[6 * n + static_cast<std::size_t>(l1)] = constrained_[6 * n + static_cast<std::size_t>(l2)] = 1;
      }
      if (!supports_.lateralFixed) {
        Vec3 centre = sp.box.origin + 0.5 * sp.box.size;
        centre[ax] = f == 0 ? lo : hi;
        Vec3 quarter = centre;
        quarter[l1] += 0.25 * sp.box.size[l1];
        auto nearest = [&](const Vec3& p, std::uint32_t skip) {
          std::uint32_t best = face[f].front() == skip ? face[f].back() : face[f].front();
          for (auto n : face[f])
            if (n != skip && (nodes_[n] - p).squaredNorm() < (nodes_[best] - p).squaredNorm()) best = n;
          return best;
        };
        const std::uint32_t c = nearest(centre, ~0u);
        constrained_[6 * c + static_cast<std::size_t>(l1)] = constrained_[6 * c + static_cast<std::size_t>(l2)] = 1;
        if (face[f].size() > 1) constrained_[6 * nearest(quarter, c) + static_cast<std::size_t>(l2)] = 1;
      }
    }
  }

  // Rotations are unknowns only when the law stiffens them (a truss lattice has none).
  bool rotations = false;
  for (const auto& p : props_) {
    const Mat12 probe = law_->stiffness(Vec3::UnitX(), 1.0, p.stiffness, section_);
    rotations = rotations || probe.diagonal().segment<3>(3).maxCoeff() > 0.0;
  }

  // Free dofs node by node in Morton order, so neighbours in space are neighbours in memory.
  std::vector<std::uint64_t> key(N);
  for (std::size_t n = 0; n < N; ++n) {
    std::uint64_t k = 0;
    for (int d = 0; d < 3; ++d) {
      const double t = std::clamp((nodes_[n][d] - sp.box.origin[d]) / sp.box.size[d], 0.0, 1.0);
      k |= spread(static_cast<std::uint64_t>(t * 2097151.0)) << d;
    }
    key[n] = k;
  }
  std::vector<std::uint32_t> order(N);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) { return key[a] < key[b]; });
  slotOf_.resize(N);
  for (std::uint32_t i = 0; i < N; ++i) slotOf_[order[i]] = i;
  nodeOfSlot_ = order;
  dofMap_.assign(6 * N, -1);
  blockOf_.assign(N, -1);
  auto& blockOf = blockOf_;
  std::int32_t next = 0;
  blockStart_.push_back(0);
  for (auto n : order) {
    if (nodeRodStart_[n + 1] == nodeRodStart_[n]) continue;
    const std::int32_t first = next;
    for (int k = 0; k < 6; ++k)
      if (!constrained_[6 * n + static_cast<std::size_t>(k)] && (k < 3 || rotations)) dofMap_[6 * n + static_cast<std::size_t>(k)] = next++;
    if (next == first) continue;
    blockOf[n] = static_cast<std::int32_t>(blockNode_.size());
    blockNode_.push_back(n);
    blockStart_.push_back(static_cast<std::uint32_t>(next));
  }
  const auto nFree = static_cast<Eigen::Index>(next);
  nodeBase_.assign(N, -1);
  freeMask_.assign(N, 0);
  for (std::size_t n = 0; n < N; ++n)
    for (int k = 0; k < 6; ++k)
      if (dofMap_[6 * n + static_cast<std::size_t>(k)] >= 0) {
        if (nodeBase_[n] < 0) nodeBase_[n] = dofMap_[6 * n + static_cast<std::size_t>(k)];
        freeMask_[n] = static_cast<std::uint8_t>(freeMask_[n] | (1u << k));
      }
  b_ = Eigen::VectorXd::Zero(nFree);
  h_ = Eigen::VectorXd::Zero(nFree);
  state_.assign(rods_.size(), kAlive);
  held_.assign(N, 0);
  for (std::uint32_t r = 0; r < rods_.size(); ++r)
    for (auto n : rods_[r])
      if (std::any_of(constrained_.begin() + 6 * n, constrained_.begin() + 6 * n + 6, [](auto c) { return c != 0; })) {
        boundaryRods_.push_back(r);
        break;
      }

  sweepOrder_.resize(blockNode_.size());
  std::iota(sweepOrder_.begin(), sweepOrder_.end(), 0u);
  std::vector<double> depth(blockNode_.size());
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const double z = nodes_[blockNode_[blk]][ax];
    depth[blk] = std::min(z - lo, hi - z);
  }
  std::stable_sort(sweepOrder_.begin(), sweepOrder_.end(), [&](auto a, auto b) { return depth[a] < depth[b]; });

  if (op_ == Operator::kMatrixFree) {
    // b from the rods at the supports; the diagonal (kept for holding fragments) from the node blocks.
#pragma omp parallel for schedule(dynamic, 256)
    for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
      const std::uint32_t n = blockNode_[blk];
      for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
        const std::uint32_t r = nodeRods_[i];
        const int side = rods_[r][0] == n ? 0 : 1;
        bool touchesSupport = false;
        for (auto end : rods_[r])
          for (int k = 0; k < 6; ++k) touchesSupport = touchesSupport || prescribed_[6 * end + static_cast<std::size_t>(k)] != 0.0;
        if (touchesSupport) addRodRows(r, side, rodStiffness(r), 1.0);
      }
    }
    diagonal_.resize(nFree);
#pragma omp parallel for schedule(dynamic, 256)
    for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
      const Block d = diagonalBlock(blk);
      for (auto i = blockStart_[blk]; i < blockStart_[blk + 1]; ++i) diagonal_[i] = d(i - blockStart_[blk], i - blockStart_[blk]);
    }
    buildStream();
    buildFixNodes();
    return;
  }

  // Block pattern: per node block i, the blocks j > i of its rod neighbours (upper triangle; K is
  // symmetric), and for the other direction references to the blocks (j, i), j < i.
  const std::size_t nb = blockNode_.size();
  upStart_.assign(nb + 1, 0);
  std::vector<std::vector<std::uint32_t>> up(nb);
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < nb; ++blk) {
    const std::uint32_t n = blockNode_[blk];
    for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
      const auto& rod = rods_[nodeRods_[i]];
      const std::int32_t j = blockOf[rod[0] == n ? rod[1] : rod[0]];
      if (j > static_cast<std::int32_t>(blk)) up[blk].push_back(static_cast<std::uint32_t>(j));
    }
    std::sort(up[blk].begin(), up[blk].end());
    up[blk].erase(std::unique(up[blk].begin(), up[blk].end()), up[blk].end());
  }
  for (std::size_t blk = 0; blk < nb; ++blk) upStart_[blk + 1] = upStart_[blk] + static_cast<std::uint32_t>(up[blk].size());
  upCol_.resize(upStart_.back());
  for (std::size_t blk = 0; blk < nb; ++blk) std::copy(up[blk].begin(), up[blk].end(), upCol_.begin() + upStart_[blk]);
  up = {};
  upper_.assign(upCol_.size(), Block::Zero());
  diag_.assign(nb, Block::Zero());
  loStart_.assign(nb + 1, 0);
  for (auto j : upCol_) ++loStart_[j + 1];
  std::partial_sum(loStart_.begin(), loStart_.end(), loStart_.begin());
  loRef_.resize(upCol_.size());
  loRow_.resize(upCol_.size());
  {
    std::vector<std::uint32_t> fill(loStart_.begin(), loStart_.end() - 1);
    for (std::uint32_t blk = 0; blk < nb; ++blk)
      for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) {
        const auto q = fill[upCol_[p]]++;
        loRef_[q] = p;
        loRow_[q] = blk;
      }
  }

  // Values: each node adds its diagonal block and the upper blocks of its own row, so threads never
  // write the same block.
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t blk = 0; blk < nb; ++blk) {
    const std::uint32_t n = blockNode_[blk];
    for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
      const std::uint32_t r = nodeRods_[i];
      addRodRows(r, rods_[r][0] == n ? 0 : 1, rodStiffness(r), 1.0);
    }
  }
  diagonal_.resize(nFree);
  for (std::size_t blk = 0; blk < nb; ++blk) {
    const Block d = diagonalBlock(blk);
    for (auto i = blockStart_[blk]; i < blockStart_[blk + 1]; ++i) diagonal_[i] = d(i - blockStart_[blk], i - blockStart_[blk]);
  }
}

void Model::coupledSupports(const Specimen& sp) {
  const std::size_t N = nodes_.size();
  std::vector<std::uint8_t> taken(N, 0);
  bool dirichlet = false;
  for (const auto& cf : supports_.coupled) {
    const int ax = cf.face.axis;
    const double plane = sp.box.origin[ax] + (cf.face.side == 1 ? sp.box.size[ax] : 0.0), tol = 1e-9 * sp.box.size[ax];
    auto& nodes = faceNodes_.emplace_back();
    for (std::uint32_t n = 0; n < N; ++n) {
      if (taken[n] || nodeRodStart_[n + 1] == nodeRodStart_[n] || std::abs(nodes_[n][ax] - plane) > tol) continue;
      taken[n] = 1;
      nodes.push_back(n);
      if (cf.mode == FaceMode::kDirichlet)
        for (std::size_t k = 0; k < 3; ++k) constrained_[6 * n + k] = 1;
    }
    if (nodes.empty()) throw std::invalid_argument(fmt::format("coupled face {} has no rod ends", faceNodes_.size() - 1));
    dirichlet = dirichlet || cf.mode == FaceMode::kDirichlet;
  }
  if (!dirichlet) throw std::invalid_argument("no coupled face is dirichlet: nothing holds the lattice");
}

Mat12 Model::rodStiffness(std::size_t r) const { return lattice::rodStiffness(axis_[r], length_[r], springs_[r]); }

Model::SparseMatrix Model::stiffness() const {
  COSIM_ASSERT(op_ == Operator::kAssembled, "the matrix-free model has no assembled stiffness");
  std::vector<Eigen::Triplet<double>> t;
  auto add = [&](std::size_t bi, std::size_t bj, const Block& B) {
    const std::uint32_t ni = blockNode_[bi], nj = blockNode_[bj];
    for (int a = 0; a < 6; ++a)
      for (int c = 0; c < 6; ++c) {
        const std::int32_t row = dofMap_[6 * ni + static_cast<std::size_t>(a)], col = dofMap_[6 * nj + static_cast<std::size_t>(c)];
        if (row >= 0 && col >= 0 && B(a, c) != 0.0) t.emplace_back(row, col, B(a, c));
      }
  };
  for (std::size_t bi = 0; bi < blockNode_.size(); ++bi) {
    add(bi, bi, diag_[bi]);
    for (auto p = upStart_[bi]; p < upStart_[bi + 1]; ++p) {
      add(bi, upCol_[p], upper_[p]);
      add(upCol_[p], bi, upper_[p].transpose());
    }
  }
  SparseMatrix K(static_cast<Eigen::Index>(freeDofs()), static_cast<Eigen::Index>(freeDofs()));
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

std::int64_t Model::nonZeros() const {
  return op_ == Operator::kAssembled ? static_cast<std::int64_t>(36 * (diag_.size() + upper_.size())) : 0;
}

Model::Vec6 Model::gather(std::uint32_t n, const Eigen::VectorXd& x) const {
  const std::uint8_t mask = freeMask_[n];
  if (mask == 0x3f) return x.segment<6>(nodeBase_[n]);  // an inner node: six consecutive free dofs
  Vec6 u = Vec6::Zero();
  for (int k = 0; k < 6; ++k)
    if (mask & (1u << k)) u[k] = x[dofMap_[6 * n + static_cast<std::size_t>(k)]];
  return u;
}

std::array<Model::Vec6, 2> Model::rodEndForces(std::size_t r, const Eigen::VectorXd& x) const {
  const Vec6 ua = gather(rods_[r][0], x), ub = gather(rods_[r][1], x);
  const Vec3& e = axis_[r];
  const RodSprings& k = springs_[r];
  std::array<Vec6, 2> l;
  rodLoads(ua.data(), ub.data(), e[0], e[1], e[2], 0.5 * length_[r], k.shear, k.normal - k.shear, k.bending, k.torsion - k.bending,
           l[0].data(), l[1].data());
  return l;
}

void Model::addRodProducts(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  for (const std::uint32_t r : rods) {
    const std::array<Vec6, 2> f = rodEndForces(r, x);
    for (int side = 0; side < 2; ++side) {
      const std::uint32_t n = rods_[r][static_cast<std::size_t>(side)];
      for (int c = 0; c < 6; ++c)
        if (const std::int32_t dof = dofMap_[6 * n + static_cast<std::size_t>(c)]; dof >= 0) y[dof] += f[static_cast<std::size_t>(side)][c];
    }
  }
}

Model::Vec6 Model::blockProduct(std::size_t blk, const Eigen::VectorXd& x) const {
  const int first = static_cast<int>(blockStart_[blk]);
  const int m = static_cast<int>(blockStart_[blk + 1]) - first;
  Vec6 y = Vec6::Zero();
  const std::uint32_t n = blockNode_[blk];
  if (op_ == Operator::kAssembled) {
    Vec6 f = diag_[blk] * gather(n, x);
    for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) f.noalias() += upper_[p] * gather(blockNode_[upCol_[p]], x);
    for (auto q = loStart_[blk]; q < loStart_[blk + 1]; ++q)
      f.noalias() += upper_[loRef_[q]].transpose() * gather(blockNode_[loRow_[q]], x);
    int i = 0;
    for (int k = 0; k < 6; ++k)
      if (freeMask_[n] & (1u << k)) y[i++] = f[k];
    return y;
  }
  if (held_[n]) {
    for (int i = 0; i < m; ++i) y[i] = diagonal_[first + i] * x[first + i];
    return y;
  }
  Vec6 f = Vec6::Zero();
  for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
    const std::uint32_t r = nodeRods_[i];
    if (state_[r] == kAlive) f += rodEndForce(r, rods_[r][0] == n ? 0 : 1, x);
  }
  int i = 0;
  for (int k = 0; k < 6; ++k)
    if (dofMap_[6 * n + static_cast<std::size_t>(k)] >= 0) y[i++] = f[k];
  return y;
}

void Model::apply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  if (op_ == Operator::kAssembled) applyBlocks(x, y);
  else applyRods(x, y);
}

void Model::buildStream() {
  std::vector<std::uint32_t> order;
  order.reserve(rods_.size());
  for (std::uint32_t r = 0; r < rods_.size(); ++r) {
    const auto& rod = rods_[r];
    if (state_[r] == kAlive && !held_[rod[0]] && (blockOf_[rod[0]] >= 0 || blockOf_[rod[1]] >= 0)) order.push_back(r);
  }
  auto key = [&](std::uint32_t r) { return std::minmax(slotOf_[rods_[r][0]], slotOf_[rods_[r][1]]); };
  std::sort(order.begin(), order.end(), [&](auto p, auto q) { return key(p) < key(q); });
  constexpr auto L = static_cast<std::size_t>(detail::kRodLanes<double>);
  auto& blocks = stream_.stream;
  blocks.assign((order.size() + L - 1) / L, detail::RodBlock<double>{});
  streamOf_.assign(rods_.size(), -1);
  for (std::size_t i = 0; i < order.size(); ++i) {
    // Stored from its end with the smaller slot: the law is the same seen from b with e → −e (Δ, Φ
    // and F, M flip sign, the moments (L/2) F × e do not).
    const std::uint32_t r = order[i];
    const std::uint32_t sa = slotOf_[rods_[r][0]], sb = slotOf_[rods_[r][1]];
    const bool flip = sb < sa;
    const Vec3 e = flip ? Vec3(-axis_[r]) : axis_[r];
    const RodSprings& k = springs_[r];
    detail::RodBlock<double>& blk = blocks[i / L];
    const std::size_t l = i % L;
    blk.a[l] = flip ? sb : sa;
    blk.b[l] = flip ? sa : sb;
    for (int c = 0; c < 3; ++c) blk.e[c][l] = e[c];
    blk.halfL[l] = 0.5 * length_[r];
    blk.shear[l] = k.shear;
    blk.normalMinusShear[l] = k.normal - k.shear;
    blk.bending[l] = k.bending;
    blk.torsionMinusBending[l] = k.torsion - k.bending;
    streamOf_[r] = static_cast<std::int32_t>(i);
  }
  // Unused lanes of the last block: a rod from and to the last record's first end, without springs.
  for (std::size_t i = order.size(); i < blocks.size() * L; ++i) {
    detail::RodBlock<double>& blk = blocks[i / L];
    blk.a[i % L] = blk.b[i % L] = blk.a[0];
  }
  // The single-precision copy: each rod's data rounded, so K̃ is the exact stiffness of slightly
  // different rods (symmetric, and within float round-off of K rod by rod).
  // Twice the lanes in float: record i is lane i % Lf of block i / Lf.
  constexpr auto Lf = static_cast<std::size_t>(detail::kRodLanes<float>);
  auto& single = streamSingle_.stream;
  single.assign((order.size() + Lf - 1) / Lf, detail::RodBlock<float>{});
  for (std::size_t i = 0; i < single.size() * Lf; ++i) {
    auto& f = single[i / Lf];
    const std::size_t l = i % Lf;
    if (i >= order.size()) {  // unused lanes, as above
      f.a[l] = f.b[l] = f.a[0];
      continue;
    }
    const auto& d = blocks[i / L];
    const std::size_t k = i % L;
    f.a[l] = d.a[k];
    f.b[l] = d.b[k];
    for (int c = 0; c < 3; ++c) f.e[c][l] = static_cast<float>(d.e[c][k]);
    f.halfL[l] = static_cast<float>(d.halfL[k]);
    f.shear[l] = static_cast<float>(d.shear[k]);
    f.normalMinusShear[l] = static_cast<float>(d.normalMinusShear[k]);
    f.bending[l] = static_cast<float>(d.bending[k]);
    f.torsionMinusBending[l] = static_cast<float>(d.torsionMinusBending[k]);
  }
}

template <typename T>
void Model::pad(const Eigen::VectorXd& x, double scale, Eigen::Matrix<T, Eigen::Dynamic, 1>& x6) const {
  const std::size_t N = nodes_.size();
  x6.resize(static_cast<Eigen::Index>(6 * N));
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < N; ++i) {
    const std::uint32_t n = nodeOfSlot_[i];
    auto u = x6.template segment<6>(static_cast<Eigen::Index>(6 * i));
    const std::uint8_t mask = freeMask_[n];
    if (mask == 0x3f) {  // an inner node: six consecutive free dofs
      u = (scale * x.segment<6>(nodeBase_[n])).template cast<T>();
      continue;
    }
    u.setZero();
    for (int k = 0; k < 6; ++k)
      if (mask & (1u << k)) u[k] = static_cast<T>(scale * x[dofMap_[6 * n + static_cast<std::size_t>(k)]]);
  }
}

template <typename T>
void Model::rodPass(const RodPass<T>& pass, const Eigen::Matrix<T, Eigen::Dynamic, 1>& x6, Eigen::Matrix<T, Eigen::Dynamic, 1>& y6) const {
  // The rod law of rodEndForce, each rod once for both its ends; each thread sums its share of the
  // records into its own vector.
  const auto& blocks = pass.stream;
  y6.resize(x6.size());
  sumOverThreads(y6, pass.yThread, [&](std::size_t t, std::size_t team, Eigen::Matrix<T, Eigen::Dynamic, 1>& out) {
    out.setZero();
    rodProducts(blocks.data() + blocks.size() * t / team, blocks.data() + blocks.size() * (t + 1) / team, x6.data(), out.data());
  });
}

void Model::applyRods(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  pad(x, 1.0, stream_.xPad);
  rodPass(stream_, stream_.xPad, stream_.yPad);
  y.resize(x.size());
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    auto k = static_cast<Eigen::Index>(blockStart_[blk]);
    if (held_[n]) {  // its rods carry no stiffness: the row is the original diagonal
      for (; k < static_cast<Eigen::Index>(blockStart_[blk + 1]); ++k) y[k] = diagonal_[k] * x[k];
      continue;
    }
    const auto slot = static_cast<Eigen::Index>(6 * slotOf_[n]);
    const std::uint8_t mask = freeMask_[n];
    if (mask == 0x3f) {  // an inner node: six consecutive free dofs
      y.segment<6>(k) = stream_.yPad.segment<6>(slot);
      continue;
    }
    for (int c = 0; c < 6; ++c)
      if (mask & (1u << c)) y[k++] = stream_.yPad[slot + c];
  }
}

void Model::toPadded(const Eigen::VectorXd& x, double scale, Eigen::VectorXf& x6) const { pad(x, scale, x6); }

void Model::addFromPadded(const Eigen::VectorXf& x6, double scale, Eigen::VectorXd& x) const {
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    auto k = static_cast<Eigen::Index>(blockStart_[blk]);
    const auto slot = static_cast<Eigen::Index>(6 * slotOf_[n]);
    for (int c = 0; c < 6; ++c)
      if (freeMask_[n] & (1u << c)) x[k++] += scale * static_cast<double>(x6[slot + c]);
  }
}

void Model::applySingle(const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const {
  COSIM_ASSERT(op_ == Operator::kMatrixFree, "the single-precision product needs the matrix-free operator");
  COSIM_ASSERT(x6.size() == paddedSize(), "{} entries for the padded space of {}", x6.size(), paddedSize());
  rodPass(streamSingle_, x6, y6);
  // The rows the rods do not give: 0 for the dofs that are not free, the original diagonal for held
  // nodes (their rods carry no stiffness).
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < fixNodes_.size(); ++i) {
    const std::uint32_t n = fixNodes_[i];
    const auto base = static_cast<Eigen::Index>(6 * slotOf_[n]);
    for (int k = 0; k < 6; ++k) {
      const std::int32_t dof = dofMap_[6 * n + static_cast<std::size_t>(k)];
      y6[base + k] = dof < 0 ? 0.0f : held_[n] ? static_cast<float>(diagonal_[dof]) * x6[base + k] : y6[base + k];
    }
  }
}

void Model::buildFixNodes() {
  fixNodes_.clear();
  for (std::uint32_t n = 0; n < nodes_.size(); ++n)
    if (freeMask_[n] != 0x3f || held_[n]) fixNodes_.push_back(n);
}

Model::Block Model::diagonalBlock(std::size_t blk) const {
  const int first = static_cast<int>(blockStart_[blk]);
  const int m = static_cast<int>(blockStart_[blk + 1]) - first;
  Block d = Block::Zero();
  const std::uint32_t n = blockNode_[blk];
  Block full = Block::Zero();
  if (op_ == Operator::kAssembled) {
    full = diag_[blk];
  } else if (held_[n]) {
    for (int i = 0; i < m; ++i) d(i, i) = diagonal_[first + i];
    return d;
  } else {
    for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
      const std::uint32_t r = nodeRods_[i];
      if (state_[r] != kAlive) continue;
      const int side = rods_[r][0] == n ? 0 : 1;
      full += rodStiffness(r).block<6, 6>(6 * side, 6 * side);
    }
  }
  std::array<int, 6> local{};
  int cnt = 0;
  for (int k = 0; k < 6; ++k)
    if (dofMap_[6 * n + static_cast<std::size_t>(k)] >= 0) local[static_cast<std::size_t>(cnt++)] = k;
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) d(i, j) = full(local[static_cast<std::size_t>(i)], local[static_cast<std::size_t>(j)]);
  return d;
}

std::size_t Model::upperIndex(std::uint32_t i, std::uint32_t j) const {
  const auto begin = upCol_.begin() + upStart_[i], end = upCol_.begin() + upStart_[i + 1];
  const auto it = std::lower_bound(begin, end, j);
  COSIM_ASSERT(it != end && *it == j, "K has no block ({}, {})", i, j);
  return static_cast<std::size_t>(it - upCol_.begin());
}

void Model::applyBlocks(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  const std::size_t nb = blockNode_.size();
  xPad_.resize(static_cast<Eigen::Index>(6 * nb));
  yPad_.resize(static_cast<Eigen::Index>(6 * nb));
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < nb; ++i) xPad_.segment<6>(static_cast<Eigen::Index>(6 * i)) = gather(blockNode_[i], x);
  // One pass over the stored (upper) blocks, each used for (i, j) and (j, i): half the memory traffic
  // of a full matrix, and K x is memory bound. With threads, each scatters its rows' products into its
  // own vector (the transposed updates would collide), summed in thread order: deterministic for a
  // given thread count, and still one pass over the matrix (gathering the lower blocks per row instead
  // read it twice and made 2 threads slower than one).
  auto rows = [&](std::size_t begin, std::size_t end, Eigen::VectorXd& out) {
    out.setZero();
    for (std::size_t i = begin; i < end; ++i) {
      const auto xi = xPad_.segment<6>(static_cast<Eigen::Index>(6 * i));
      Vec6 yi = diag_[i] * xi;
      for (auto p = upStart_[i]; p < upStart_[i + 1]; ++p) {
        const auto j = static_cast<Eigen::Index>(6 * upCol_[p]);
        yi.noalias() += upper_[p] * xPad_.segment<6>(j);
        out.segment<6>(j).noalias() += upper_[p].transpose() * xi;
      }
      out.segment<6>(static_cast<Eigen::Index>(6 * i)) += yi;
    }
  };
  sumOverThreads(yPad_, yThread_, [&](std::size_t t, std::size_t team, Eigen::VectorXd& out) {
    // Equal shares of stored blocks, not of rows: the upper rows of a block profile are longer.
    const std::size_t total = upStart_[nb];
    auto rowAt = [&](std::size_t share) {
      const auto last = upStart_.begin() + static_cast<std::ptrdiff_t>(nb);
      return static_cast<std::size_t>(std::lower_bound(upStart_.begin(), last, total * share / team) - upStart_.begin());
    };
    rows(rowAt(t), t + 1 == team ? nb : rowAt(t + 1), out);
  });
  y.resize(x.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < nb; ++i) {
    const std::uint32_t n = blockNode_[i];
    int k = static_cast<int>(blockStart_[i]);
    for (int c = 0; c < 6; ++c)
      if (freeMask_[n] & (1u << c)) y[k++] = yPad_[static_cast<Eigen::Index>(6 * i + static_cast<std::size_t>(c))];
  }
}

void Model::addRodRows(std::size_t r, int side, const Mat12& k, double sign) {
  const std::uint32_t n = rods_[r][static_cast<std::size_t>(side)];
  const std::uint32_t m = rods_[r][static_cast<std::size_t>(1 - side)];
  if (blockOf_[n] < 0) return;  // a node without free dofs has no rows
  if (op_ == Operator::kAssembled) {
    // Node n owns its diagonal block and the off-diagonal block when it is the smaller block index;
    // rows and columns of dofs that are not free are never read.
    const auto i = static_cast<std::uint32_t>(blockOf_[n]);
    diag_[i] += sign * k.block<6, 6>(6 * side, 6 * side);
    if (blockOf_[m] > blockOf_[n]) upper_[upperIndex(i, static_cast<std::uint32_t>(blockOf_[m]))] += sign * k.block<6, 6>(6 * side, 6 * (1 - side));
  }
  for (int a = 0; a < 6; ++a) {
    const std::int32_t row = dofMap_[6 * n + static_cast<std::size_t>(a)];
    if (row < 0) continue;
    for (int q = 0; q < 2; ++q) {
      const std::uint32_t node = rods_[r][static_cast<std::size_t>(q)];
      for (int c = 0; c < 6; ++c) {
        const std::size_t dof = 6 * node + static_cast<std::size_t>(c);
        if (dofMap_[dof] < 0 && prescribed_[dof] != 0.0) b_[row] -= sign * k(6 * side + a, 6 * q + c) * prescribed_[dof];
      }
    }
  }
}

Eigen::VectorXd Model::rhs(double strain) const { return strain * b_ + h_; }

Eigen::VectorXd Model::heldValues() const { return h_.cwiseQuotient(diagonal_); }

void Model::fullDisplacement(const Eigen::VectorXd& x, double strain, std::vector<double>& u) const {
  u.resize(dofMap_.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < dofMap_.size(); ++i)
    u[i] = dofMap_[i] >= 0 ? x[dofMap_[i]] : strain * prescribed_[i];
}

double Model::rodStrain(std::size_t r, std::span<const double> u) const {
  const auto [a, b] = rods_[r];
  const Vec3 d(u[6 * b] - u[6 * a], u[6 * b + 1] - u[6 * a + 1], u[6 * b + 2] - u[6 * a + 2]);
  return d.dot(nodes_[b] - nodes_[a]) / (length_[r] * length_[r]);
}

Model::Vec6 Model::nodeForce(std::uint32_t n, std::span<const double> u) const {
  Vec6 f = Vec6::Zero();
  for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
    const std::uint32_t r = nodeRods_[i];
    if (state_[r] != kAlive) continue;
    const Mat12 k = rodStiffness(r);
    Eigen::Matrix<double, 12, 1> ur;
    for (int q = 0; q < 2; ++q)
      for (int c = 0; c < 6; ++c) ur[6 * q + c] = u[6 * rods_[r][static_cast<std::size_t>(q)] + static_cast<std::size_t>(c)];
    const int side = rods_[r][0] == n ? 0 : 1;
    f += k.middleRows<6>(6 * side) * ur;
  }
  return f;
}

double Model::reaction(std::span<const double> u) const {
  double sum = 0.0;
  for (std::uint32_t n = 0; n < nodes_.size(); ++n)
    if (movingFace_[n]) sum += nodeForce(n, u)[supports_.axis];
  return sum;
}

Eigen::VectorXd Model::rhs(std::span<const double> g, std::span<const double> f) const {
  COSIM_ASSERT(g.size() == dofMap_.size() && f.size() == dofMap_.size(), "{} and {} values for {} dofs", g.size(), f.size(),
               dofMap_.size());
  Eigen::VectorXd r = h_;
  for (std::size_t i = 0; i < dofMap_.size(); ++i)
    if (dofMap_[i] >= 0 && !held_[i / 6]) r[dofMap_[i]] += f[i];
  // −K_fc g over the rods that touch a constrained dof (the rows of their free, non-held ends).
  for (auto rod : boundaryRods_) {
    if (state_[rod] != kAlive) continue;
    Eigen::Matrix<double, 12, 1> ug = Eigen::Matrix<double, 12, 1>::Zero();
    for (std::size_t q = 0; q < 2; ++q)
      for (std::size_t c = 0; c < 6; ++c) {
        const std::size_t dof = 6 * rods_[rod][q] + c;
        if (constrained_[dof]) ug[static_cast<Eigen::Index>(6 * q + c)] = g[dof];
      }
    const Eigen::Matrix<double, 12, 1> load = rodStiffness(rod) * ug;
    for (std::size_t q = 0; q < 2; ++q) {
      const std::uint32_t n = rods_[rod][q];
      if (held_[n]) continue;
      for (std::size_t c = 0; c < 6; ++c)
        if (dofMap_[6 * n + c] >= 0) r[dofMap_[6 * n + c]] -= load[static_cast<Eigen::Index>(6 * q + c)];
    }
  }
  return r;
}

void Model::fullDisplacement(const Eigen::VectorXd& x, std::span<const double> g, std::vector<double>& u) const {
  u.resize(dofMap_.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < dofMap_.size(); ++i) u[i] = dofMap_[i] >= 0 ? x[dofMap_[i]] : constrained_[i] ? g[i] : 0.0;
}

Model::Checkpoint Model::checkpoint() const {
  return {diag_, upper_, b_, h_, state_, held_, removed_, heldCount_, removalLog_.size()};
}

void Model::restore(const Checkpoint& c) {
  COSIM_ASSERT(c.logSize <= removalLog_.size() && c.state.size() == state_.size(), "checkpoint of another model ({} of {} removals)",
               c.logSize, removalLog_.size());
  if (c.logSize == removalLog_.size() && c.heldCount == heldCount_) return;
  diag_ = c.diag;
  upper_ = c.upper;
  b_ = c.b;
  h_ = c.h;
  state_ = c.state;
  held_ = c.held;
  removed_ = c.removed;
  heldCount_ = c.heldCount;
  removalLog_.resize(c.logSize);
  if (op_ == Operator::kMatrixFree) {
    buildStream();
    buildFixNodes();
  }
  ++restores_;
}

std::size_t Model::removeRods(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x) {
  for (auto r : rods) {
    COSIM_ASSERT(active(r), "rod {} is not active", r);
    state_[r] = kRemoved;
    ++removed_;
    removalLog_.push_back(r);
    if (op_ == Operator::kMatrixFree && streamOf_[r] >= 0) clearRecord(streamOf_[r]);
    const Mat12 k = rodStiffness(r);
    addRodRows(r, 0, k, -1.0);
    addRodRows(r, 1, k, -1.0);
  }
  return endsStillConnected(rods) ? 0 : holdDetached(x);
}

bool Model::endsStillConnected(std::span<const std::uint32_t> rods) const {
  // Removing rods leaves the lattice's pieces as they were exactly when the two ends of every removed
  // rod are still connected. A search of a few hundred nodes from one end nearly always meets the other
  // (the two usually share a neighbour); the whole lattice is searched (holdDetached) only when it
  // does not.
  constexpr std::size_t kBudget = 256;
  if (reached_.size() != nodes_.size()) reached_.assign(nodes_.size(), 0);
  std::vector<std::uint32_t> visited;
  for (const std::uint32_t r : rods) {
    const std::uint32_t from = rods_[r][0], to = rods_[r][1];
    visited.assign(1, from);
    reached_[from] = 1;
    bool found = false;
    for (std::size_t head = 0; head < visited.size() && visited.size() < kBudget && !found; ++head) {
      const std::uint32_t n = visited[head];
      for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
        const std::uint32_t q = nodeRods_[i];
        if (state_[q] != kAlive) continue;
        const std::uint32_t m = rods_[q][0] == n ? rods_[q][1] : rods_[q][0];
        if (m == to) {
          found = true;
          break;
        }
        if (!reached_[m]) {
          reached_[m] = 1;
          visited.push_back(m);
        }
      }
    }
    for (const std::uint32_t n : visited) reached_[n] = 0;
    if (!found) return false;
  }
  return true;
}

std::size_t Model::holdDetached(const Eigen::VectorXd& x) {
  const std::size_t N = nodes_.size();
  std::vector<std::uint32_t> parent(N);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<std::uint8_t> hasRod(N, 0);
  for (std::size_t r = 0; r < rods_.size(); ++r)
    if (state_[r] == kAlive) {
      hasRod[rods_[r][0]] = hasRod[rods_[r][1]] = 1;
      const auto a = find(rods_[r][0]), b = find(rods_[r][1]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  // A node with no rod left is held even on a support: its free dofs (rotations, lateral translations)
  // have no stiffness at all.
  std::vector<std::uint8_t> supported(N, 0);
  for (std::size_t n = 0; n < N; ++n)
    for (int k = 0; k < 6; ++k)
      if (constrained_[6 * n + static_cast<std::size_t>(k)] && hasRod[n]) supported[find(static_cast<std::uint32_t>(n))] = 1;
  std::size_t fresh = 0;
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    if (held_[n] || supported[find(n)]) continue;
    held_[n] = 1;
    ++fresh;
    // Rows (and the matching columns) become the original diagonal: the dofs keep the value of x.
    for (auto row = blockStart_[blk]; row < blockStart_[blk + 1]; ++row) {
      b_[row] = 0.0;
      h_[row] = diagonal_[row] * x[row];
    }
    if (op_ != Operator::kAssembled) {
      for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i)
        if (const std::int32_t s = streamOf_[nodeRods_[i]]; s >= 0) clearRecord(s);
      continue;
    }
    for (auto p = upStart_[blk]; p < upStart_[blk + 1]; ++p) upper_[p].setZero();
    for (auto q = loStart_[blk]; q < loStart_[blk + 1]; ++q) upper_[loRef_[q]].setZero();
    diag_[blk].setZero();
    int i = 0;
    for (int k = 0; k < 6; ++k)
      if (freeMask_[n] & (1u << k)) {
        diag_[blk](k, k) = diagonal_[blockStart_[blk] + static_cast<std::uint32_t>(i)];
        ++i;
      }
  }
  heldCount_ += fresh;
  if (fresh > 0 && op_ == Operator::kMatrixFree) buildFixNodes();
  return fresh;
}

}  // namespace lattice
