#include <algorithm>
#include <cstring>
#include <type_traits>
#include <utility>

#include <omp.h>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "common/errors.hpp"
#include "stiffness.hpp"

namespace lattice {

using detail::rodLoads;

namespace {

// y += K x over the blocks [begin, end) (MatrixFreeRods::rodPass): the rod law of rodLoads in SIMD across
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

Model::MatrixFreeRods::MatrixFreeRods(const Model& m) {
  buildStream(m);
  buildFixNodes(m);
}

void Model::MatrixFreeRods::buildStream(const Model& m) {
  std::vector<std::uint32_t> order;
  order.reserve(m.rods_.size());
  for (std::uint32_t r = 0; r < m.rods_.size(); ++r) {
    const auto& rod = m.rods_[r];
    if (m.state_[r] == kAlive && !m.held_[rod[0]] && (m.blockOf_[rod[0]] >= 0 || m.blockOf_[rod[1]] >= 0)) order.push_back(r);
  }
  auto key = [&](std::uint32_t r) { return std::minmax(m.slotOf_[m.rods_[r][0]], m.slotOf_[m.rods_[r][1]]); };
  std::sort(order.begin(), order.end(), [&](auto p, auto q) { return key(p) < key(q); });
  fillStream(m, order);
}

void Model::MatrixFreeRods::fillStream(const Model& m, const std::vector<std::uint32_t>& order) {
  constexpr auto L = static_cast<std::size_t>(detail::kRodLanes<double>);
  auto& blocks = stream_.stream;
  blocks.assign((order.size() + L - 1) / L, detail::RodBlock<double>{});
  streamOf_.assign(m.rods_.size(), -1);
  for (std::size_t i = 0; i < order.size(); ++i) {
    // Stored from its end with the smaller slot: the law is the same seen from b with e → −e (Δ, Φ
    // and F, M flip sign, the moments (L/2) F × e do not).
    const std::uint32_t r = order[i];
    const std::uint32_t sa = m.slotOf_[m.rods_[r][0]], sb = m.slotOf_[m.rods_[r][1]];
    const bool flip = sb < sa;
    const Vec3 e = flip ? Vec3(-m.axis_[r]) : m.axis_[r];
    const RodSprings& k = m.springs_[r];
    detail::RodBlock<double>& blk = blocks[i / L];
    const std::size_t l = i % L;
    blk.a[l] = flip ? sb : sa;
    blk.b[l] = flip ? sa : sb;
    for (int c = 0; c < 3; ++c) blk.e[c][l] = e[c];
    blk.halfL[l] = 0.5 * m.length_[r];
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

void Model::MatrixFreeRods::buildFixNodes(const Model& m) {
  fixNodes_.clear();
  for (std::uint32_t n = 0; n < m.nodes_.size(); ++n)
    if (m.freeMask_[n] != 0x3f || m.held_[n]) fixNodes_.push_back(n);
}

void Model::MatrixFreeRods::clearRecord(std::int32_t record) {
  constexpr int Ld = detail::kRodLanes<double>, Lf = detail::kRodLanes<float>;
  stream_.stream[static_cast<std::size_t>(record / Ld)].clear(record % Ld);
  streamSingle_.stream[static_cast<std::size_t>(record / Lf)].clear(record % Lf);
}

template <typename T>
void Model::MatrixFreeRods::rodPass(const RodPass<T>& pass, const Eigen::Matrix<T, Eigen::Dynamic, 1>& x6,
                                    Eigen::Matrix<T, Eigen::Dynamic, 1>& y6) {
  // The rod law of Model::rodEndForce, each rod once for both its ends; each thread sums its share of
  // the records into its own vector.
  const auto& blocks = pass.stream;
  y6.resize(x6.size());
  detail::sumOverThreads(y6, pass.yThread, [&](std::size_t t, std::size_t team, Eigen::Matrix<T, Eigen::Dynamic, 1>& out) {
    out.setZero();
    rodProducts(blocks.data() + blocks.size() * t / team, blocks.data() + blocks.size() * (t + 1) / team, x6.data(), out.data());
  });
}

void Model::MatrixFreeRods::apply(const Model& m, const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  m.pad(x, 1.0, stream_.xPad);
  rodPass(stream_, stream_.xPad, stream_.yPad);
  y.resize(x.size());
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < m.blockNode_.size(); ++blk) {
    const std::uint32_t n = m.blockNode_[blk];
    auto k = static_cast<Eigen::Index>(m.blockStart_[blk]);
    if (m.held_[n]) {  // its rods carry no stiffness: the row is the original diagonal
      for (; k < static_cast<Eigen::Index>(m.blockStart_[blk + 1]); ++k) y[k] = m.diagonal_[k] * x[k];
      continue;
    }
    const auto slot = static_cast<Eigen::Index>(6 * m.slotOf_[n]);
    const std::uint8_t mask = m.freeMask_[n];
    if (mask == 0x3f) {  // an inner node: six consecutive free dofs
      y.segment<6>(k) = stream_.yPad.segment<6>(slot);
      continue;
    }
    for (int c = 0; c < 6; ++c)
      if (mask & (1u << c)) y[k++] = stream_.yPad[slot + c];
  }
}

void Model::MatrixFreeRods::applySingle(const Model& m, const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const {
  rodPass(streamSingle_, x6, y6);
  // The rows the rods do not give: 0 for the dofs that are not free, the original diagonal for held
  // nodes (their rods carry no stiffness).
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < fixNodes_.size(); ++i) {
    const std::uint32_t n = fixNodes_[i];
    const auto base = static_cast<Eigen::Index>(6 * m.slotOf_[n]);
    for (int k = 0; k < 6; ++k) {
      const std::int32_t dof = m.dofMap_[6 * n + static_cast<std::size_t>(k)];
      y6[base + k] = dof < 0 ? 0.0f : m.held_[n] ? static_cast<float>(m.diagonal_[dof]) * x6[base + k] : y6[base + k];
    }
  }
}

Model::Vec6 Model::MatrixFreeRods::nodeProduct(const Model& m, std::size_t blk, const Eigen::VectorXd& x) const {
  const std::uint32_t n = m.blockNode_[blk];
  Vec6 f = Vec6::Zero();
  if (m.held_[n]) {
    int i = 0;
    for (int k = 0; k < 6; ++k)
      if (m.freeMask_[n] & (1u << k)) {
        const auto dof = static_cast<Eigen::Index>(m.blockStart_[blk]) + i++;
        f[k] = m.diagonal_[dof] * x[dof];
      }
    return f;
  }
  for (auto i = m.nodeRodStart_[n]; i < m.nodeRodStart_[n + 1]; ++i) {
    const std::uint32_t r = m.nodeRods_[i];
    if (m.state_[r] == kAlive) f += m.rodEndForce(r, m.rods_[r][0] == n ? 0 : 1, x);
  }
  return f;
}

Model::Block Model::MatrixFreeRods::nodeDiagonal(const Model& m, std::size_t blk) const {
  const std::uint32_t n = m.blockNode_[blk];
  Block full = Block::Zero();
  if (m.held_[n]) {
    int i = 0;
    for (int k = 0; k < 6; ++k)
      if (m.freeMask_[n] & (1u << k)) full(k, k) = m.diagonal_[static_cast<Eigen::Index>(m.blockStart_[blk]) + i++];
    return full;
  }
  for (auto i = m.nodeRodStart_[n]; i < m.nodeRodStart_[n + 1]; ++i) {
    const std::uint32_t r = m.nodeRods_[i];
    if (m.state_[r] != kAlive) continue;
    const int side = m.rods_[r][0] == n ? 0 : 1;
    full += m.rodStiffness(r).block<6, 6>(6 * side, 6 * side);
  }
  return full;
}

void Model::MatrixFreeRods::remove(const Model&, std::uint32_t r, const Mat12&) {
  if (streamOf_[r] >= 0) clearRecord(streamOf_[r]);
}

void Model::MatrixFreeRods::hold(const Model& m, std::size_t blk) {
  const std::uint32_t n = m.blockNode_[blk];
  for (auto i = m.nodeRodStart_[n]; i < m.nodeRodStart_[n + 1]; ++i)
    if (const std::int32_t s = streamOf_[m.nodeRods_[i]]; s >= 0) clearRecord(s);
}

Model::SparseMatrix Model::MatrixFreeRods::matrix(const Model& m) const {
  // The rods that carry stiffness, at their free dofs; a held node's rows are its intact diagonal.
  std::vector<Eigen::Triplet<double>> t;
  for (std::uint32_t r = 0; r < m.rods_.size(); ++r) {
    if (m.state_[r] != kAlive || m.held_[m.rods_[r][0]]) continue;
    const Mat12 k = m.rodStiffness(r);
    for (int p = 0; p < 12; ++p)
      for (int q = 0; q < 12; ++q) {
        const std::int32_t row = m.dofMap_[6 * m.rods_[r][static_cast<std::size_t>(p / 6)] + static_cast<std::size_t>(p % 6)];
        const std::int32_t col = m.dofMap_[6 * m.rods_[r][static_cast<std::size_t>(q / 6)] + static_cast<std::size_t>(q % 6)];
        if (row >= 0 && col >= 0 && k(p, q) != 0.0) t.emplace_back(row, col, k(p, q));
      }
  }
  for (std::size_t blk = 0; blk < m.blockNode_.size(); ++blk)
    if (m.held_[m.blockNode_[blk]])
      for (auto i = m.blockStart_[blk]; i < m.blockStart_[blk + 1]; ++i) t.emplace_back(i, i, m.diagonal_[i]);
  SparseMatrix K(static_cast<Eigen::Index>(m.freeDofs()), static_cast<Eigen::Index>(m.freeDofs()));
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

void Model::MatrixFreeRods::restore(const Model& m, const std::vector<Block>& values, const std::vector<std::int32_t>& layout) {
  COSIM_ASSERT(values.empty(), "{} stored blocks for a matrix-free stiffness", values.size());
  if (layout.empty()) {
    buildStream(m);
  } else {
    // The records where the run that wrote the layout had them: removed and held rods keep theirs, with
    // zero springs, so each thread's share of the pass, and with it the rounding of K x, is the same.
    std::vector<std::uint32_t> order;
    for (std::uint32_t r = 0; r < layout.size(); ++r)
      if (layout[r] >= 0) {
        if (order.size() <= static_cast<std::size_t>(layout[r])) order.resize(static_cast<std::size_t>(layout[r]) + 1);
        order[static_cast<std::size_t>(layout[r])] = r;
      }
    fillStream(m, order);
    for (std::uint32_t r = 0; r < layout.size(); ++r)
      if (layout[r] >= 0 && (m.state_[r] != kAlive || m.held_[m.rods_[r][0]] || m.held_[m.rods_[r][1]])) clearRecord(layout[r]);
  }
  buildFixNodes(m);
}

}  // namespace lattice
