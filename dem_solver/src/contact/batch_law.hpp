#pragma once
// The batch loop every contact law shares. A law supplies `blockLoop<friction>`, the forces of a block
// of touching contacts held as structure of arrays (ContactBlock); this loop gathers the touching
// candidates into blocks, calls the law, and writes forces and histories back (and, for sphere pairs,
// computes the geometry first and scatters the forces to the spheres after). The law's loop over a
// block has no branches (selects), so the compiler vectorises it: one contact is a long chain of square
// roots and divisions, and several contacts in lock-step hide their latency.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <numeric>
#include <string_view>
#include <vector>

#include <omp.h>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include <Eigen/Geometry>

#include "dem/contact_law.hpp"
#include "per_thread.hpp"

namespace dem::detail {

inline constexpr int kBlock = 64;
// Arrays that a vectorised filter appends to four lanes at a time (spherePairs) have room for the
// three lanes that may be written past the block's count.
inline constexpr int kBlockPadded = kBlock + 4;

// The laws compile their block loop three times, for the x86-64 baseline (2 doubles per vector), AVX2
// (4) and AVX-512 (8), and pick the widest the CPU has at run time. Not FMA (AVX-512F has it, hence
// -ffp-contract=off for libdem and its users): with it the widths would round differently, and a run's
// bits would depend on the machine. COSIM_DEM_SIMD=avx2 or =baseline in the environment picks the
// narrower loops on any CPU (a test checks that all give the same bits).
#if defined(__x86_64__) && defined(__GNUC__)
#define DEM_TARGET_AVX2 __attribute__((target("avx2")))
#define DEM_TARGET_AVX512 __attribute__((target("avx512f")))
inline bool useAvx2() {
  static const bool yes = [] {
    const char* simd = std::getenv("COSIM_DEM_SIMD");
    return __builtin_cpu_supports("avx2") && !(simd && std::string_view(simd) == "baseline");
  }();
  return yes;
}
inline bool useAvx512() {
  static const bool yes = [] {
    const char* simd = std::getenv("COSIM_DEM_SIMD");
    return useAvx2() && __builtin_cpu_supports("avx512f") && !(simd && std::string_view(simd) == "avx2");
  }();
  return yes;
}
#else
#define DEM_TARGET_AVX2
#define DEM_TARGET_AVX512
inline bool useAvx2() { return false; }
inline bool useAvx512() { return false; }
#endif

/// Candidates [begin, end) sorted by side a, shared among `threads` threads in runs cut where a changes:
/// thread t takes [cut[t], cut[t+1]), and only it adds to its a spheres. The runs are of about equal
/// length, or, given the overlaps of the last pass (`overlap`: > 0 touching), of about equal work: a
/// touching candidate costs its law besides the distance test (kTouchingWork tests), and the work is
/// estimated from every kWorkStride-th candidate. A settled bed under falling grains touches where the
/// falling part does not: equal lengths left one thread waiting 11 % of the pass (N = 10⁵ pour, two
/// threads). The cuts depend on the state and the thread count only.
inline constexpr double kTouchingWork = 4.0;
inline constexpr std::size_t kWorkStride = 64;
inline std::vector<std::size_t> runsBySideA(const std::uint32_t* a, std::size_t begin, std::size_t end, int threads,
                                            const double* overlap = nullptr) {
  std::vector<std::size_t> cut(static_cast<std::size_t>(threads) + 1, end);
  cut[0] = begin;
  std::vector<double> work;  // work of the samples up to and with sample s (candidate begin + s·kWorkStride)
  if (overlap && threads > 1) {
    // Each sample is a cache miss, once per step: read on all threads, summed after.
    const auto samples = static_cast<std::ptrdiff_t>((end - begin + kWorkStride - 1) / kWorkStride);
    work.resize(static_cast<std::size_t>(samples));
#pragma omp parallel for schedule(static) num_threads(threads) if (samples > kParallelMin)
    for (std::ptrdiff_t s = 0; s < samples; ++s) {
      const double touching = overlap[begin + static_cast<std::size_t>(s) * kWorkStride];
      work[static_cast<std::size_t>(s)] = touching > 0.0 ? kTouchingWork : 1.0;
    }
    std::partial_sum(work.begin(), work.end(), work.begin());
  }
  for (std::size_t t = 1; t < cut.size() - 1; ++t) {
    std::size_t even = begin + (end - begin) * t / static_cast<std::size_t>(threads);
    if (!work.empty()) {
      const double share = work.back() * static_cast<double>(t) / static_cast<double>(threads);
      const auto s = static_cast<std::size_t>(std::lower_bound(work.begin(), work.end(), share) - work.begin());
      even = std::min(end, begin + s * kWorkStride);
    }
    std::size_t c = std::max(cut[t - 1], even);
    while (c < end && c > begin && a[c] == a[c - 1]) ++c;
    cut[t] = c;
  }
  return cut;
}

/// Runs part(t) for t = 0 .. parts − 1 on the OpenMP threads, part t on thread t. A team smaller than
/// asked for (OMP_DYNAMIC, OMP_THREAD_LIMIT) takes the parts in turn, so the work of each part, and the
/// results, depend only on `parts` (threads skipping the parts past the team lost them until 2026-11-25).
template <class Part>
void forEachPart(int parts, Part&& part) {
#pragma omp parallel num_threads(parts) if (parts > 1)
  for (int t = omp_get_thread_num(); t < parts; t += omp_get_num_threads()) part(static_cast<std::size_t>(t));
}

/// Touching contacts (δ > 0), structure of arrays, at most kBlock.
struct ContactBlock {
  int n = 0;
  std::array<std::size_t, kBlockPadded> index;  ///< candidate index in the batch
  // Inputs: ContactPoint.
  alignas(64) double nx[kBlock], ny[kBlock], nz[kBlock];  ///< normal, b → a
  alignas(64) double vx[kBlock], vy[kBlock], vz[kBlock];  ///< v_a − v_b at the contact point
  alignas(64) double overlap[kBlock], effRadius[kBlock], effMass[kBlock];
  // History, read and updated (ContactHistory; lastOverlap is read only: the loop stores δ after).
  alignas(64) double sx[kBlock], sy[kBlock], sz[kBlock], lastOverlap[kBlock];
  // Outputs: ContactForce.
  alignas(64) double fx[kBlock], fy[kBlock], fz[kBlock], fn[kBlock];
  alignas(64) double elastic[kBlock], damping[kBlock], friction[kBlock];

  void pullHistory(int i, ContactHistory& h) const {
    h.shearForce = Vec3(sx[i], sy[i], sz[i]);
    h.lastOverlap = overlap[i];
  }
  /// Appends candidate k: its geometry and history.
  void push(std::size_t k, const ContactPoint& p, const ContactHistory& h) {
    const int i = n;
    pushState(k, p.effRadius, p.effMass, h);
    nx[i] = p.normal.x(), ny[i] = p.normal.y(), nz[i] = p.normal.z();
    vx[i] = p.relVelocity.x(), vy[i] = p.relVelocity.y(), vz[i] = p.relVelocity.z();
    overlap[i] = p.overlap;
  }
  /// Appends candidate k without its geometry (overlap, normal, relative velocity: set by the caller).
  void pushState(std::size_t k, double radius, double mass, const ContactHistory& h) {
    const int i = n++;
    index[static_cast<std::size_t>(i)] = k;
    setState(i, radius, mass, h);
  }
  /// Lane i's R*, m* and history.
  void setState(int i, double radius, double mass, const ContactHistory& h) {
    effRadius[i] = radius, effMass[i] = mass;
    sx[i] = h.shearForce.x(), sy[i] = h.shearForce.y(), sz[i] = h.shearForce.z();
    lastOverlap[i] = h.lastOverlap;
  }
  /// Lane i's results into the candidate's history and force.
  void pull(int i, ContactHistory& h, ContactForce& f) const {
    pullHistory(i, h);
    f.force = Vec3(fx[i], fy[i], fz[i]);
    f.normalForce = fn[i];
    f.elasticEnergy = elastic[i];
    f.dampingEnergy = damping[i];
    f.frictionEnergy = friction[i];
  }
};

template <class Derived>
class BatchLaw : public ContactLaw {
 public:
  void compute(std::span<const ContactPoint> points, std::span<ContactHistory> history, std::span<ContactForce> out,
               double dt) const final {
    const auto n = static_cast<std::ptrdiff_t>(points.size());
    const std::ptrdiff_t chunks = (n + kChunk - 1) / kChunk;
#pragma omp parallel if (n > kParallelMin)
    {
      ContactBlock block;
      auto flush = [&] {
        runBlock(block, dt);
        for (int i = 0; i < block.n; ++i) {
          const std::size_t k = block.index[static_cast<std::size_t>(i)];
          block.pull(i, history[k], out[k]);
        }
        block.n = 0;
      };
#pragma omp for schedule(static)
      for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        for (std::ptrdiff_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k) {
          const auto kk = static_cast<std::size_t>(k);
          if (points[kk].overlap <= 0.0) {
            clearIfJustOpened(history[kk], out[kk]);
            continue;
          }
          block.push(kk, points[kk], history[kk]);
          if (block.n == kBlock) flush();
        }
        if (block.n > 0) flush();
      }
    }
  }

  void computeBlock(ContactBlock& block, double dt) const final { runBlock(block, dt); }

  void computeSpherePairs(const SpherePairView& v, std::size_t begin, std::size_t end, double dt) const final {
    if (v.loneSpheres) spherePairs<true>(v, begin, end, dt);
    else spherePairs<false>(v, begin, end, dt);
  }

 private:
  // kLone: sphere i is body i, at its centre (SpherePairView::loneSpheres).
  template <bool kLone>
  void spherePairs(const SpherePairView& v, std::size_t begin, std::size_t end, double dt) const {
    // Threads take runs of candidates cut where side a changes, so each adds to the sums of its own a
    // spheres; a side-b sphere past its run's last a may also be another thread's, and its terms are
    // kept and added after, thread by thread. The results depend only on the number of threads.
    const int nt = end - begin > static_cast<std::size_t>(kParallelMin) ? omp_get_max_threads() : 1;
    const std::vector<std::size_t> cut = runsBySideA(v.a, begin, end, nt, v.overlap);
    PerThread<std::vector<Deferred>> deferred(static_cast<std::size_t>(nt));
    std::vector<std::array<double, 3>> energy(static_cast<std::size_t>(nt), std::array<double, 3>{});
    if (v.energy) energy[0] = {v.energy[0], v.energy[1], v.energy[2]};
    forEachPart(nt, [&](std::size_t t) {
      const double start = v.threadSeconds ? omp_get_wtime() : 0.0;
      // Side-b spheres from here on may be another thread's.
      const std::uint32_t mine = cut[t + 1] < end ? v.a[cut[t + 1]] : ~std::uint32_t{0};
      std::vector<Deferred>& later = deferred[t];
      ContactBlock block;
      PairGeometry g;
      double elastic = energy[t][0], damping = energy[t][1], friction = energy[t][2];  // in registers
      auto flush = [&] {
        if constexpr (kLone) g.gatherLone(block, v);
        g.template compute<kLone>(block);
        runBlock(block, dt);
        constexpr bool kLaneTorques = kLone;  // about the sphere centres, which lone spheres have in the lanes
        if (kLaneTorques && v.sphereTorque) g.torques(block);
        if (kLone && !v.keepGeometry && !v.force && v.energy && v.sphereTorque) {
          scatterLone(block, g, v, mine, later, elastic, damping, friction);
          block.n = 0;
          return;
        }
        for (int i = 0; i < block.n; ++i) {
          const std::size_t k = block.index[static_cast<std::size_t>(i)];
          // d² < (r_a + r_b)², yet the rounded distance may not be below r_a + r_b: then it is open.
          const double overlap = std::max(block.overlap[i], 0.0);
          v.overlap[k] = overlap;
          if (v.keepGeometry) {
            ContactPoint& p = v.point[k];
            p.overlap = overlap;
            p.normal = Vec3(block.nx[i], block.ny[i], block.nz[i]);
            p.point = Vec3(g.px[i], g.py[i], g.pz[i]);
            p.relVelocity = Vec3(block.vx[i], block.vy[i], block.vz[i]);
          }
          if (overlap == 0.0) {
            if (v.force) v.force[k] = ContactForce{};
            v.history[k] = ContactHistory{};
            continue;
          }
          if (v.energy) {
            block.pullHistory(i, v.history[k]);
            if (v.force) {
              ContactForce& f = v.force[k];
              f.force = Vec3(block.fx[i], block.fy[i], block.fz[i]);
              f.normalForce = block.fn[i];
            }
            elastic += block.elastic[i], damping += block.damping[i], friction += block.friction[i];
          } else {
            block.pull(i, v.history[k], v.force[k]);
          }
          // From the block, not read back from v.force[k]: a vector load of what was just stored as
          // scalars cannot be forwarded from the store buffer and waits (40 % of this loop's time).
          const Vec3 force(block.fx[i], block.fy[i], block.fz[i]);
          const auto a = v.a[k], b = v.b[k];
          v.sphereForce[a] += force;
          Vec3 torqueB = Vec3::Zero();
          if (kLaneTorques && v.sphereTorque) {
            v.sphereTorque[a] += Vec3(g.tax[i], g.tay[i], g.taz[i]);
            torqueB = Vec3(g.tbx[i], g.tby[i], g.tbz[i]);
          } else if (v.sphereTorque) {
            const Vec3 x(g.px[i], g.py[i], g.pz[i]);
            v.sphereTorque[a] += (x - v.position[a]).cross(force);
            torqueB = (x - v.position[b]).cross(Vec3(-force));
          }
          if (b >= mine) {
            later.push_back({b, -force, torqueB});
            continue;
          }
          v.sphereForce[b] += -force;
          if (v.sphereTorque) v.sphereTorque[b] += torqueB;
        }
        block.n = 0;
      };
      std::size_t kk = cut[t];
      if constexpr (kLone)
        if (useAvx2()) kk = filterLoneAvx2(v, kk, cut[t + 1], block, g, flush);
      for (; kk < cut[t + 1]; ++kk) {
        const auto i = v.a[kk], j = v.b[kk];
        const Vec3 d = v.position[i] - v.position[j];
        const double ri = v.radius[i], rj = v.radius[j];
        const double reach = ri + rj, d2 = d.squaredNorm();
        if (d2 >= reach * reach || d2 == 0.0) {  // open
          v.overlap[kk] = -d2;  // SpherePairView::overlap: the gap itself would cost a square root
          if (v.keepGeometry) v.point[kk].overlap = -d2;
          if (v.history[kk].lastOverlap != 0.0) {  // just opened
            v.history[kk] = ContactHistory{};
            if (v.force) v.force[kk] = ContactForce{};
          }
          continue;
        }
        if constexpr (kLone) {
          g.pushLone(block.n, v.position[i], v.position[j], ri, rj);
          block.index[static_cast<std::size_t>(block.n++)] = kk;  // the rest: gatherLone() in flush
        } else {
          g.push(block.n, d, ri, rj, v.position[j], v.body[i], v.body[j], v);
          block.pushState(kk, v.effRadius[kk], v.effMass[kk], v.history[kk]);
        }
        if (block.n == kBlock) flush();
      }
      if (block.n > 0) flush();
      energy[t] = {elastic, damping, friction};
      if (v.threadSeconds) v.threadSeconds[t] = omp_get_wtime() - start;
    });
    deferred.forEach([&](const std::vector<Deferred>& later) {
      for (const Deferred& d : later) {
        v.sphereForce[d.sphere] += d.force;
        if (v.sphereTorque) v.sphereTorque[d.sphere] += d.torque;
      }
    });
    if (v.energy) {
      std::copy(energy[0].begin(), energy[0].end(), v.energy);
      for (std::size_t t = 1; t < energy.size(); ++t)
        for (std::size_t e = 0; e < 3; ++e) v.energy[e] += energy[t][e];
    }
  }

  struct PairGeometry;
#if defined(__x86_64__) && defined(__GNUC__)
  // spherePairs' candidate test for lone spheres, four candidates at a time: centres loaded whole and
  // transposed, radii loaded, the same arithmetic as the scalar test (same bits); the touching lanes'
  // index, centres and radii are packed to the front with a permutation and appended to the block (no
  // branch per candidate: a third of the candidates are open, in no pattern a predictor learns). Returns
  // where it stopped (fewer than four left); the caller's scalar loop does the rest.
  template <class Flush>
  DEM_TARGET_AVX2 static std::size_t filterLoneAvx2(const SpherePairView& v, std::size_t begin, std::size_t end,
                                                    ContactBlock& block, PairGeometry& g, Flush& flush) {
    // For each 4-bit mask of touching lanes, the 32-bit lane permutation moving them (64 bits each) to
    // the front, in order.
    static constexpr auto kPack = [] {
      std::array<std::array<int, 8>, 16> p{};
      for (int m = 0; m < 16; ++m) {
        int o = 0;
        for (int l = 0; l < 4; ++l)
          if (m & (1 << l)) p[m][2 * o] = 2 * l, p[m][2 * o + 1] = 2 * l + 1, ++o;
      }
      return p;
    }();
    const Vec3* x = v.position;
    const std::uint32_t* A = v.a;
    const std::uint32_t* B = v.b;
    double* overlapOut = v.overlap;
    const __m256d zero = _mm256_setzero_pd(), negZero = _mm256_set1_pd(-0.0);
    std::size_t k = begin;
    // Side b's centres, 64 candidates ahead (every other one: a line holds 2.7 centres, and side b runs
    // in a few strided streams): at 50,000 spheres −5 % of the pass (docs/performance.md). With them the
    // candidates' histories, R* and m*, which the flush gathers for the touching ones: the hardware
    // prefetcher missed these streams, and their loads were half the gather's time (−4 to −6 %).
    constexpr std::size_t kAhead = 64;
    for (; k + 4 <= end; k += 4) {
      if (v.prefetch && k + kAhead + 2 < end) {
        _mm_prefetch(reinterpret_cast<const char*>(x + B[k + kAhead]), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(x + B[k + kAhead + 2]), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(v.history + k + kAhead), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(v.history + k + kAhead + 2), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(v.effRadius + k + kAhead), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(v.effMass + k + kAhead), _MM_HINT_T0);
      }
      const __m128i ia = _mm_loadu_si128(reinterpret_cast<const __m128i*>(A + k));
      const __m128i ib = _mm_loadu_si128(reinterpret_cast<const __m128i*>(B + k));
      std::uint32_t sa[4], sb[4];
      _mm_storeu_si128(reinterpret_cast<__m128i*>(sa), ia);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(sb), ib);
      __m256d xa, ya, za, xb, yb, zb;
      PairGeometry::transpose3(x, sa, xa, ya, za);
      PairGeometry::transpose3(x, sb, xb, yb, zb);
      // Scalar loads, not vgatherdpd: slower on AMD Zen.
      const double* r = v.radius;
      const __m256d ra = _mm256_set_pd(r[sa[3]], r[sa[2]], r[sa[1]], r[sa[0]]);
      const __m256d rb = _mm256_set_pd(r[sb[3]], r[sb[2]], r[sb[1]], r[sb[0]]);
      const __m256d dx = _mm256_sub_pd(xa, xb), dy = _mm256_sub_pd(ya, yb), dz = _mm256_sub_pd(za, zb);
      const __m256d d2 =
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
      const __m256d reach = _mm256_add_pd(ra, rb);
      const __m256d open =
          _mm256_or_pd(_mm256_cmp_pd(d2, _mm256_mul_pd(reach, reach), _CMP_GE_OQ), _mm256_cmp_pd(d2, zero, _CMP_EQ_OQ));
      // Open lanes: −d², and the history cleared if the pair was touching at the last pass (δ > 0 there,
      // SpherePairView::overlap). Touching lanes' δ is written by the flush.
      // (Touching lanes are stored unchanged: a masked store is slow on AMD Zen.)
      const __m256d was = _mm256_loadu_pd(overlapOut + k);
      _mm256_storeu_pd(overlapOut + k, _mm256_blendv_pd(was, _mm256_xor_pd(d2, negZero), open));
      const int opened = _mm256_movemask_pd(_mm256_and_pd(open, _mm256_cmp_pd(was, zero, _CMP_GT_OQ)));
      if (opened != 0) [[unlikely]]
        for (int l = 0; l < 4; ++l) {
          if (!(opened & (1 << l))) continue;
          v.history[k + l] = ContactHistory{};
          if (v.force) v.force[k + l] = ContactForce{};
        }
      if (v.keepGeometry) [[unlikely]]
        for (int l = 0; l < 4; ++l) v.point[k + l].overlap = overlapOut[k + l];
      const int touching = ~_mm256_movemask_pd(open) & 0xf;
      if (touching == 0) continue;
      if (v.prefetch)  // side b's velocities and sums, read and added to when the block is flushed
        for (int l = 0; l < 4; ++l) {
          _mm_prefetch(reinterpret_cast<const char*>(v.velocity + sb[l]), _MM_HINT_T0);
          _mm_prefetch(reinterpret_cast<const char*>(v.angularVelocity + sb[l]), _MM_HINT_T0);
          _mm_prefetch(reinterpret_cast<const char*>(v.sphereForce + sb[l]), _MM_HINT_T0);
          if (v.sphereTorque) _mm_prefetch(reinterpret_cast<const char*>(v.sphereTorque + sb[l]), _MM_HINT_T0);
        }
      const int n = block.n;
      const __m256i perm = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kPack[touching].data()));
      pack(xa, perm, g.xa[0] + n), pack(ya, perm, g.xa[1] + n), pack(za, perm, g.xa[2] + n);
      pack(xb, perm, g.bx + n), pack(yb, perm, g.by + n), pack(zb, perm, g.bz + n);
      pack(ra, perm, g.ra + n), pack(rb, perm, g.rb + n);
      const __m256i index =
          _mm256_add_epi64(_mm256_set1_epi64x(static_cast<long long>(k)), _mm256_set_epi64x(3, 2, 1, 0));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(block.index.data() + n), _mm256_permutevar8x32_epi32(index, perm));
      block.n = n + __builtin_popcount(static_cast<unsigned>(touching));
      if (block.n > kBlock - 4) flush();
    }
    return k;
  }
  [[gnu::always_inline]] DEM_TARGET_AVX2 static inline void pack(__m256d value, __m256i perm, double* to) {
    _mm256_storeu_pd(to, _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(value), perm)));
  }
#else
  template <class Flush>
  static std::size_t filterLoneAvx2(const SpherePairView&, std::size_t begin, std::size_t, ContactBlock&, PairGeometry&,
                                    Flush&) {
    return begin;
  }
#endif

  /// A side-b sphere's terms from a thread that does not own it (spherePairs).
  struct Deferred {
    std::uint32_t sphere;
    Vec3 force, torque;
  };

  // The write-back of spherePairs' flush for lone spheres when nothing but the histories, the overlaps,
  // the spheres' sums and the energy sums is kept (a granular sample without rolling resistance): the
  // same arithmetic in the same order, with the arrays held in local pointers — through the view and
  // the closure the compiler reloaded each of them for every contact, in twice the instructions.
  static void scatterLone(const ContactBlock& block, const PairGeometry& g, const SpherePairView& v, std::uint32_t mine,
                          std::vector<Deferred>& later, double& elastic, double& damping, double& friction) {
    const std::uint32_t* __restrict A = v.a;
    const std::uint32_t* __restrict B = v.b;
    double* __restrict overlapOut = v.overlap;
    double* __restrict hist = &v.history[0].shearForce.x();
    double* __restrict F = v.sphereForce->data();
    double* __restrict T = v.sphereTorque->data();
    static_assert(sizeof(ContactHistory) == 4 * sizeof(double) && sizeof(Vec3) == 3 * sizeof(double));
    double e0 = elastic, e1 = damping, e2 = friction;
    const int n = block.n;
    for (int i = 0; i < n; ++i) {
      const std::size_t k = block.index[static_cast<std::size_t>(i)];
      // d² < (r_a + r_b)², yet the rounded distance may not be below r_a + r_b: then it is open.
      const double overlap = std::max(block.overlap[i], 0.0);
      overlapOut[k] = overlap;
      double* h = hist + 4 * k;
      if (overlap == 0.0) {
        h[0] = h[1] = h[2] = h[3] = 0.0;
        continue;
      }
      h[0] = block.sx[i], h[1] = block.sy[i], h[2] = block.sz[i], h[3] = overlap;
      e0 += block.elastic[i], e1 += block.damping[i], e2 += block.friction[i];
      const double fx = block.fx[i], fy = block.fy[i], fz = block.fz[i];
      const std::uint32_t a = A[k], b = B[k];
      double* fa = F + 3 * std::size_t{a};
      double* ta = T + 3 * std::size_t{a};
      fa[0] += fx, fa[1] += fy, fa[2] += fz;
      ta[0] += g.tax[i], ta[1] += g.tay[i], ta[2] += g.taz[i];
      if (b >= mine) {
        later.push_back({b, Vec3(-fx, -fy, -fz), Vec3(g.tbx[i], g.tby[i], g.tbz[i])});
        continue;
      }
      double* fb = F + 3 * std::size_t{b};
      double* tb = T + 3 * std::size_t{b};
      fb[0] += -fx, fb[1] += -fy, fb[2] += -fz;
      tb[0] += g.tbx[i], tb[1] += g.tby[i], tb[2] += g.tbz[i];
    }
    elastic = e0, damping = e1, friction = e2;
  }

  // An open candidate has zero force and history. They were zeroed when it opened (or when the candidate
  // list was built): a third of the candidates are open, and rewriting them each step is memory traffic.
  static void clearIfJustOpened(ContactHistory& h, ContactForce& f) {
    if (h.lastOverlap == 0.0) return;
    h = ContactHistory{};
    f = ContactForce{};
  }
  // Derived::blockLoop<friction?>(block, dt) computes the forces of a block; compiled here once per width.
  void runBlock(ContactBlock& b, double dt) const {
    if (useAvx512()) runBlockAvx512(b, dt);
    else if (useAvx2()) runBlockAvx2(b, dt);
    else runLanes(b, dt);
  }
  DEM_TARGET_AVX2 void runBlockAvx2(ContactBlock& b, double dt) const { runLanes(b, dt); }
  DEM_TARGET_AVX512 void runBlockAvx512(ContactBlock& b, double dt) const { runLanes(b, dt); }
  [[gnu::always_inline]] inline void runLanes(ContactBlock& b, double dt) const {
    const auto& law = static_cast<const Derived&>(*this);
    if (law.friction() > 0.0) law.template blockLoop<true>(b, dt);
    else law.template blockLoop<false>(b, dt);
  }

  /// What a block of sphere pairs needs to compute its contact geometry lane by lane: the centres'
  /// difference, radii, the second centre, and both bodies' motion.
  struct PairGeometry {
    alignas(64) double dx[kBlock], dy[kBlock], dz[kBlock], ra[kBlockPadded], rb[kBlockPadded];
    alignas(64) double bx[kBlockPadded], by[kBlockPadded], bz[kBlockPadded];  // centre of b
    // Per side (a, b): body centre X, velocity u, angular velocity w.
    alignas(64) double xa[3][kBlockPadded], xb[3][kBlock], ua[3][kBlock], ub[3][kBlock], wa[3][kBlock], wb[3][kBlock];
    alignas(64) double px[kBlock], py[kBlock], pz[kBlock];  // contact point (output)
    alignas(64) double tax[kBlock], tay[kBlock], taz[kBlock], tbx[kBlock], tby[kBlock], tbz[kBlock];  // torques()

    /// Lone spheres: the torques of the lanes' forces about a's and b's centres, (p − x_a) × F and
    /// (p − x_b) × (−F) (as the scalar write-back computes them for clusters).
    void torques(const ContactBlock& b) {
      if (useAvx512()) torquesAvx512(b);
      else if (useAvx2()) torquesAvx2(b);
      else torqueLanes(b);
    }
    DEM_TARGET_AVX2 void torquesAvx2(const ContactBlock& b) { torqueLanes(b); }
    DEM_TARGET_AVX512 void torquesAvx512(const ContactBlock& b) { torqueLanes(b); }
    [[gnu::always_inline]] inline void torqueLanes(const ContactBlock& b) {
      const int n = b.n;
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        const double fx = b.fx[i], fy = b.fy[i], fz = b.fz[i];
        const double ax = px[i] - xa[0][i], ay = py[i] - xa[1][i], az = pz[i] - xa[2][i];
        const double cx = px[i] - bx[i], cy = py[i] - by[i], cz = pz[i] - bz[i];
        tax[i] = ay * fz - az * fy, tay[i] = az * fx - ax * fz, taz[i] = ax * fy - ay * fx;
        tbx[i] = cy * -fz - cz * -fy, tby[i] = cz * -fx - cx * -fz, tbz[i] = cx * -fy - cy * -fx;
      }
    }

    /// Lone spheres: a lane's centres and radii, appended by the candidate filter.
    void pushLone(int i, const Vec3& centreA, const Vec3& centreB, double radiusA, double radiusB) {
      xa[0][i] = centreA.x(), xa[1][i] = centreA.y(), xa[2][i] = centreA.z();
      bx[i] = centreB.x(), by[i] = centreB.y(), bz[i] = centreB.z();
      ra[i] = radiusA, rb[i] = radiusB;
    }
    /// Lone spheres: the rest of each lane's spheres (velocities) and state (R*, m*, history) from its
    /// candidate index; the centres and radii are in (pushLone or the filter). The body centres are the
    /// sphere centres (xa, and b's centre bx for xb); the centres' difference is taken in the lanes (the
    /// same subtraction).
    void gatherLone(ContactBlock& b, const SpherePairView& v) {
      if (useAvx2()) gatherLoneAvx2(b, v);
      else gatherLoneScalar(b, v, 0);
    }
    void gatherLoneScalar(ContactBlock& b, const SpherePairView& v, int from) {
      for (int i = from; i < b.n; ++i) {
        const std::size_t k = b.index[static_cast<std::size_t>(i)];
        const std::uint32_t sa = v.a[k], sb = v.b[k];
        for (int c = 0; c < 3; ++c) {
          ua[c][i] = v.velocity[sa][c], ub[c][i] = v.velocity[sb][c];
          wa[c][i] = v.angularVelocity[sa][c], wb[c][i] = v.angularVelocity[sb][c];
        }
        b.setState(i, v.effRadius[k], v.effMass[k], v.history[k]);
      }
    }
#if defined(__x86_64__) && defined(__GNUC__)
    // Four lanes at a time, each vector field loaded whole and transposed into the lanes: a quarter of
    // the stores of the scalar copy, which were the bottleneck of the gather (same data, same bits).
    DEM_TARGET_AVX2 void gatherLoneAvx2(ContactBlock& b, const SpherePairView& v) {
      int i = 0;
      for (; i + 4 <= b.n; i += 4) {
        std::size_t k[4];
        std::uint32_t sa[4], sb[4];
        for (int j = 0; j < 4; ++j) {
          k[j] = b.index[static_cast<std::size_t>(i + j)];
          sa[j] = v.a[k[j]], sb[j] = v.b[k[j]];
          b.effRadius[i + j] = v.effRadius[k[j]], b.effMass[i + j] = v.effMass[k[j]];
        }
        transpose3(v.velocity, sa, &ua[0][i], &ua[1][i], &ua[2][i]);
        transpose3(v.velocity, sb, &ub[0][i], &ub[1][i], &ub[2][i]);
        transpose3(v.angularVelocity, sa, &wa[0][i], &wa[1][i], &wa[2][i]);
        transpose3(v.angularVelocity, sb, &wb[0][i], &wb[1][i], &wb[2][i]);
        // History rows: shear force x, y, z and the last overlap are its first four doubles.
        static_assert(sizeof(ContactHistory) == 4 * sizeof(double));
        __m256d h[4];
        for (int j = 0; j < 4; ++j) h[j] = _mm256_loadu_pd(&v.history[k[j]].shearForce.x());
        const __m256d t0 = _mm256_unpacklo_pd(h[0], h[1]), t1 = _mm256_unpackhi_pd(h[0], h[1]);
        const __m256d t2 = _mm256_unpacklo_pd(h[2], h[3]), t3 = _mm256_unpackhi_pd(h[2], h[3]);
        _mm256_storeu_pd(&b.sx[i], _mm256_permute2f128_pd(t0, t2, 0x20));
        _mm256_storeu_pd(&b.sy[i], _mm256_permute2f128_pd(t1, t3, 0x20));
        _mm256_storeu_pd(&b.sz[i], _mm256_permute2f128_pd(t0, t2, 0x31));
        _mm256_storeu_pd(&b.lastOverlap[i], _mm256_permute2f128_pd(t1, t3, 0x31));
      }
      gatherLoneScalar(b, v, i);
    }
    /// x, y, z of src[idx[0..3]] into the lanes of x, y, z. Masked loads: the fourth double past a Vec3
    /// may be past the end of the array.
    [[gnu::always_inline]] DEM_TARGET_AVX2 static inline void transpose3(const Vec3* src, const std::uint32_t* idx,
                                                                         __m256d& x, __m256d& y, __m256d& z) {
      const __m256i first3 = _mm256_set_epi64x(0, -1, -1, -1);
      const __m256d r0 = _mm256_maskload_pd(src[idx[0]].data(), first3);
      const __m256d r1 = _mm256_maskload_pd(src[idx[1]].data(), first3);
      const __m256d r2 = _mm256_maskload_pd(src[idx[2]].data(), first3);
      const __m256d r3 = _mm256_maskload_pd(src[idx[3]].data(), first3);
      const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);  // x0 x1 z0 z1, y0 y1 . .
      const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
      x = _mm256_permute2f128_pd(t0, t2, 0x20);
      y = _mm256_permute2f128_pd(t1, t3, 0x20);
      z = _mm256_permute2f128_pd(t0, t2, 0x31);
    }
    /// x, y, z of src[idx[0..3]] into x[0..3], y[0..3], z[0..3].
    DEM_TARGET_AVX2 static void transpose3(const Vec3* src, const std::uint32_t* idx, double* x, double* y, double* z) {
      __m256d vx, vy, vz;
      transpose3(src, idx, vx, vy, vz);
      _mm256_storeu_pd(x, vx);
      _mm256_storeu_pd(y, vy);
      _mm256_storeu_pd(z, vz);
    }
#else
    void gatherLoneAvx2(ContactBlock& b, const SpherePairView& v) { gatherLoneScalar(b, v, 0); }
#endif
    void push(int i, const Vec3& d, double ri, double rj, const Vec3& centreB, std::uint32_t bodyA,
              std::uint32_t bodyB, const SpherePairView& v) {
      dx[i] = d.x(), dy[i] = d.y(), dz[i] = d.z(), ra[i] = ri, rb[i] = rj;
      bx[i] = centreB.x(), by[i] = centreB.y(), bz[i] = centreB.z();
      for (int c = 0; c < 3; ++c) {
        xa[c][i] = v.bodyPosition[bodyA][c], xb[c][i] = v.bodyPosition[bodyB][c];
        ua[c][i] = v.velocity[bodyA][c], ub[c][i] = v.velocity[bodyB][c];
        wa[c][i] = v.angularVelocity[bodyA][c], wb[c][i] = v.angularVelocity[bodyB][c];
      }
    }
    /// Overlap, normal and relative velocity of every lane into `b` (which push() filled in step), the
    /// contact point here.
    template <bool kLone>
    void compute(ContactBlock& b) {
      if (useAvx512()) computeAvx512<kLone>(b);
      else if (useAvx2()) computeAvx2<kLone>(b);
      else lanes<kLone>(b);
    }
    template <bool kLone>
    DEM_TARGET_AVX2 void computeAvx2(ContactBlock& b) { lanes<kLone>(b); }
    template <bool kLone>
    DEM_TARGET_AVX512 void computeAvx512(ContactBlock& b) { lanes<kLone>(b); }
    template <bool kLone>
    [[gnu::always_inline]] inline void lanes(ContactBlock& b) {
      const int n = b.n;
      // Lone spheres: b's body centre is its sphere centre.
      const double* XB[3] = {kLone ? bx : xb[0], kLone ? by : xb[1], kLone ? bz : xb[2]};
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        const double ddx = kLone ? xa[0][i] - bx[i] : dx[i];
        const double ddy = kLone ? xa[1][i] - by[i] : dy[i];
        const double ddz = kLone ? xa[2][i] - bz[i] : dz[i];
        const double dist = std::sqrt(ddx * ddx + ddy * ddy + ddz * ddz);
        const double overlap = ra[i] + rb[i] - dist;
        const double inv = 1.0 / dist;
        const double nx = ddx * inv, ny = ddy * inv, nz = ddz * inv;
        const double s = rb[i] - 0.5 * overlap;
        const double x = bx[i] + nx * s, y = by[i] + ny * s, z = bz[i] + nz * s;
        // v + w × (p − X) on each side.
        const double ax = x - xa[0][i], ay = y - xa[1][i], az = z - xa[2][i];
        const double cx = x - XB[0][i], cy = y - XB[1][i], cz = z - XB[2][i];
        const double vax = ua[0][i] + (wa[1][i] * az - wa[2][i] * ay);
        const double vay = ua[1][i] + (wa[2][i] * ax - wa[0][i] * az);
        const double vaz = ua[2][i] + (wa[0][i] * ay - wa[1][i] * ax);
        const double vbx = ub[0][i] + (wb[1][i] * cz - wb[2][i] * cy);
        const double vby = ub[1][i] + (wb[2][i] * cx - wb[0][i] * cz);
        const double vbz = ub[2][i] + (wb[0][i] * cy - wb[1][i] * cx);
        b.overlap[i] = overlap;
        b.nx[i] = nx, b.ny[i] = ny, b.nz[i] = nz;
        px[i] = x, py[i] = y, pz[i] = z;
        b.vx[i] = vax - vbx, b.vy[i] = vay - vby, b.vz[i] = vaz - vbz;
      }
    }
  };

  static constexpr std::ptrdiff_t kChunk = 1024;  // candidates per OpenMP work item
};

}  // namespace dem::detail
