#include "neighbour_list.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

#include "avx2_rows.hpp"
#include "common/errors.hpp"
#include "common/geometry.hpp"
#include "contact/batch_law.hpp"
#include "per_thread.hpp"

namespace dem {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
using detail::CellOrdered;
#if defined(__x86_64__) && defined(__GNUC__)
using detail::loadRows, detail::rowDots;
#endif

// What needsRebuildLone's first pass finds: the box of the displacements since the pair build, the
// largest of them and the largest since the plane build (squared).
struct Displacements {
  double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  double absolute2 = 0.0, plane2 = 0.0;
};

// Bodies [b0, b1) into `d`. (Each maximum and minimum is exact, so the order of the bodies does not
// matter: four at a time below, any thread split.)
void displacementsScalar(const Vec3* x, const Vec3* atPairs, const Vec3* atPlanes, std::ptrdiff_t b0, std::ptrdiff_t b1,
                         Displacements& d) {
  for (std::ptrdiff_t b = b0; b < b1; ++b) {
    const Vec3 e = x[b] - atPairs[b];
    for (int c = 0; c < 3; ++c) d.lo[c] = std::min(d.lo[c], e[c]), d.hi[c] = std::max(d.hi[c], e[c]);
    d.absolute2 = std::max(d.absolute2, e.x() * e.x() + e.y() * e.y() + e.z() * e.z());  // as rowDots
    if (atPlanes) {
      const Vec3 f = x[b] - atPlanes[b];
      d.plane2 = std::max(d.plane2, f.x() * f.x() + f.y() * f.y() + f.z() * f.z());
    }
  }
}
#if defined(__x86_64__) && defined(__GNUC__)
// The same four bodies at a time, on their Vec3 rows as they lie in memory (integrateLoneFourAvx2).
// Returns where it stopped (fewer than four left).
DEM_TARGET_AVX2 std::ptrdiff_t displacementsAvx2(const Vec3* x, const Vec3* atPairs, const Vec3* atPlanes,
                                                 std::ptrdiff_t b0, std::ptrdiff_t b1, Displacements& d) {
  __m256d lo[3], hi[3];
  for (int r = 0; r < 3; ++r) lo[r] = _mm256_set1_pd(kInf), hi[r] = _mm256_set1_pd(-kInf);
  __m256d absolute2 = _mm256_setzero_pd(), plane2 = _mm256_setzero_pd();
  std::ptrdiff_t b = b0;
  for (; b + 4 <= b1; b += 4) {
    __m256d xr[3], pr[3], e[3];
    loadRows(x[b].data(), xr), loadRows(atPairs[b].data(), pr);
    for (int r = 0; r < 3; ++r) {
      e[r] = _mm256_sub_pd(xr[r], pr[r]);
      lo[r] = _mm256_min_pd(lo[r], e[r]), hi[r] = _mm256_max_pd(hi[r], e[r]);
    }
    absolute2 = _mm256_max_pd(absolute2, rowDots(e, e));
    if (atPlanes) {
      loadRows(atPlanes[b].data(), pr);
      for (int r = 0; r < 3; ++r) e[r] = _mm256_sub_pd(xr[r], pr[r]);
      plane2 = _mm256_max_pd(plane2, rowDots(e, e));
    }
  }
  // Lane j of row r holds component (4r + j) mod 3.
  alignas(32) double l[3][4], h[3][4], a[4], p[4];
  for (int r = 0; r < 3; ++r) _mm256_store_pd(l[r], lo[r]), _mm256_store_pd(h[r], hi[r]);
  _mm256_store_pd(a, absolute2), _mm256_store_pd(p, plane2);
  for (int r = 0; r < 3; ++r)
    for (int j = 0; j < 4; ++j) {
      const int c = (4 * r + j) % 3;
      d.lo[c] = std::min(d.lo[c], l[r][j]), d.hi[c] = std::max(d.hi[c], h[r][j]);
    }
  for (int j = 0; j < 4; ++j) d.absolute2 = std::max(d.absolute2, a[j]), d.plane2 = std::max(d.plane2, p[j]);
  return b;
}
#endif

// The partners j > i of sphere i (centre xi, radius ri) among the cell-ordered spheres [k0, k1): those
// within ri + r_j + skin, appended to out[n ..] in the order met. Returns the new count. Every sphere is
// tested and written, and the count advanced only for a partner: a fifth of the tests pass, in no pattern
// the branch predictor learns.
std::size_t partnersScalar(const CellOrdered& c, std::uint32_t k0, std::uint32_t k1, std::uint32_t i, const Vec3& xi,
                           double ri, double skin, std::uint32_t* out, std::size_t n) {
  for (std::uint32_t k = k0; k < k1; ++k) {
    const std::uint32_t j = c.index[k];
    const double reach = ri + c.r[k] + skin;
    const double dx = xi.x() - c.x[k], dy = xi.y() - c.y[k], dz = xi.z() - c.z[k];
    out[n] = j;
    n += static_cast<std::size_t>((j > i) & (dx * dx + dy * dy + dz * dz < reach * reach));
  }
  return n;
}
#if defined(__x86_64__) && defined(__GNUC__)
// partnersScalar's test for four spheres from k (`left` of the run from there; lanes past it are unused):
// the partners' lanes packed to the front with a permutation and stored whole at out + n (room for four
// past the last partner).
struct PartnersFour {
  const CellOrdered& c;
  __m256d x, y, z, r, skin;
  __m128i sign, i;  // j > i unsigned, as a signed comparison of both with the sign bit flipped
  std::uint32_t* out;
  std::size_t n = 0;

  [[gnu::always_inline]] DEM_TARGET_AVX2 inline void operator()(std::uint32_t k, std::int64_t left) {
    static constexpr auto kPack = [] {  // per 4-bit mask of partner lanes, the lanes in order
      std::array<std::array<int, 4>, 16> p{};
      for (int m = 0; m < 16; ++m)
        for (int l = 0, o = 0; l < 4; ++l)
          if (m & (1 << l)) p[m][o++] = l;
      return p;
    }();
    const __m256d dx = _mm256_sub_pd(x, _mm256_loadu_pd(c.x.data() + k));
    const __m256d dy = _mm256_sub_pd(y, _mm256_loadu_pd(c.y.data() + k));
    const __m256d dz = _mm256_sub_pd(z, _mm256_loadu_pd(c.z.data() + k));
    const __m256d d2 =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
    const __m256d reach = _mm256_add_pd(_mm256_add_pd(r, _mm256_loadu_pd(c.r.data() + k)), skin);
    const __m128i j = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c.index.data() + k));
    const int after = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_xor_si128(j, sign), i)));
    const int near = _mm256_movemask_pd(_mm256_cmp_pd(d2, _mm256_mul_pd(reach, reach), _CMP_LT_OQ));
    const int mask = near & after & (0xf >> (4 - std::clamp<std::int64_t>(left, 0, 4)));
    const __m128i lanes = _mm_loadu_si128(reinterpret_cast<const __m128i*>(kPack[mask].data()));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + n),
                     _mm_castps_si128(_mm_permutevar_ps(_mm_castsi128_ps(j), lanes)));
    n += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(mask)));
  }
};

// partnersScalar for the 9 runs [k0[r], k1[r]) around a sphere, four spheres at a time. Each run takes
// two steps of four whatever its length: a run holds about 4.5 spheres, and a loop leaving after one or
// two steps mispredicted its exit at most runs, which cost more than the tests. Returns the count.
DEM_TARGET_AVX2 std::size_t partnersAvx2(const CellOrdered& c, const std::uint32_t* k0, const std::uint32_t* k1,
                                         std::uint32_t i, const Vec3& xi, double ri, double skin, std::uint32_t* out) {
  const __m128i sign = _mm_set1_epi32(static_cast<int>(0x80000000u));
  PartnersFour four{c,
                    _mm256_set1_pd(xi.x()),
                    _mm256_set1_pd(xi.y()),
                    _mm256_set1_pd(xi.z()),
                    _mm256_set1_pd(ri),
                    _mm256_set1_pd(skin),
                    sign,
                    _mm_xor_si128(_mm_set1_epi32(static_cast<int>(i)), sign),
                    out};
  for (int r = 0; r < 9; ++r) {
    const std::uint32_t k = k0[r];
    const auto left = static_cast<std::int64_t>(k1[r]) - k;
    four(k, left);
    four(k + 4, left - 4);
    for (std::int64_t more = 8; more < left; more += 4) four(k + static_cast<std::uint32_t>(more), left - more);
  }
  return four.n;
}
#endif
}  // namespace

NeighbourList::Rebuild NeighbourList::needsRebuild(const Bodies& bodies, bool lone,
                                                  const SimulationSettings& settings,
                                                  const std::vector<PlaneWall>& planes,
                                                  const std::vector<MeshWall>& meshes) const {
  const std::vector<double>& bodyReach = prepared_.bodyReach;
  COSIM_ASSERT(lone || bodyReach.size() == bodies.size(), "NeighbourList: {} bodies, the reach of {} (addBody)",
               bodies.size(), bodyReach.size());
  // A member of a rigid body moved by its body's Δx plus at most chord(Δθ) · reach since a build.
  const auto nb = static_cast<std::ptrdiff_t>(bodies.size());
  auto turned = [&](std::ptrdiff_t b, const Poses& at) {
    if (bodyReach[b] == 0.0) return 0.0;
    const double c = std::min(1.0, std::abs(bodies.orientation[b].dot(at.orientation[b])));
    return 2.0 * std::sqrt(std::max(0.0, 1.0 - c * c)) * bodyReach[b];  // 2 sin(θ/2) reach
  };
  Rebuild what = lone ? needsRebuildLone(bodies, settings, planes) : Rebuild{};
  if (prepared_.pairsPossible && !lone) {
    // A pair's gap changes by at most |Δx_a − u| + |Δx_b − u| for any common shift u, so motion shared by
    // all (a falling sample) uses up no skin. u: the middle of the box of the bodies' displacements.
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies.position[b] - atPairs_.position[b];
      lo = lo.cwiseMin(d);
      hi = hi.cwiseMax(d);
    }
    const Vec3 u = 0.5 * (lo + hi);
    // Bodies that did not turn (every lone sphere) compare squared lengths: one square root at the end
    // instead of two per body, and the same maximum (the square root is monotonic and correctly rounded).
    double relative = 0.0, absolute = 0.0, relative2 = 0.0, absolute2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : relative, absolute, relative2, absolute2) if (nb > kParallelMin)
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies.position[b] - atPairs_.position[b];
      const double r = turned(b, atPairs_);
      if (r == 0.0) {
        relative2 = std::max(relative2, (d - u).squaredNorm());
        absolute2 = std::max(absolute2, d.squaredNorm());
      } else {
        relative = std::max(relative, (d - u).norm() + r);
        absolute = std::max(absolute, d.norm() + r);
      }
    }
    relative = std::max(relative, std::sqrt(relative2));
    absolute = std::max(absolute, std::sqrt(absolute2));
    what.pairs = 2.0 * std::min(relative, absolute) > settings.skin;
  }
  auto movedSince = [&](const Poses& at) {
    double moved = 0.0, moved2 = 0.0;  // squared, as above, for bodies that did not turn
#pragma omp parallel for schedule(static) reduction(max : moved, moved2) if (nb > kParallelMin)
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies.position[b] - at.position[b];
      const double r = turned(b, at);
      if (r == 0.0) moved2 = std::max(moved2, d.squaredNorm());
      else moved = std::max(moved, d.norm() + r);
    }
    return std::max(moved, std::sqrt(moved2));
  };
  // A sphere–wall candidate stays valid while both sides together moved less than the skin (a point of a
  // triangle moves no more than its farthest node).
  if (!planes.empty() && !lone) {
    what.planes = movedSince(atPlanes_) + planesMoved(planes) > settings.skin;
  }
  if (!meshes.empty()) {
    double maxNode = 0.0;
    for (std::size_t m = 0; m < meshes.size(); ++m)
      for (std::size_t n = 0; n < meshes[m].nodes.size(); ++n)
        maxNode = std::max(maxNode, (meshes[m].nodes[n] - meshNodesAtBuild_[m][n]).squaredNorm());
    what.mesh = movedSince(atMesh_) + std::sqrt(maxNode) > settings.meshSkin;
  }
  return what;
}

NeighbourList::Rebuild NeighbourList::needsRebuildLone(const Bodies& bodies, const SimulationSettings& settings,
                                                      const std::vector<PlaneWall>& planes) const {
  // The pair and plane tests of needsRebuild() for bodies that never turn a member: the same tests on
  // squared lengths. One pass finds the box of the displacements and the largest displacement since
  // each build; the second, for the displacements relative to the box centre, runs only when the
  // absolute ones alone call for a pair rebuild (the relative ones can only avoid it): a settled
  // sample skips it.
  const auto nb = static_cast<std::ptrdiff_t>(bodies.size());
  const Vec3* x = bodies.position.data();
  const Vec3* atPairs = atPairs_.position.data();
  const bool pairs = prepared_.pairsPossible, anyPlane = !planes.empty();
  const Vec3* atPlanes = anyPlane ? atPlanes_.position.data() : nullptr;
  const int nt = nb > kParallelMin ? omp_get_max_threads() : 1;
  detail::PerThread<Displacements> partial(static_cast<std::size_t>(nt));
  detail::forEachPart(nt, [&](std::size_t part) {
    const auto t = static_cast<std::ptrdiff_t>(part);
    const std::ptrdiff_t chunk = (nb + nt - 1) / nt, b1 = std::min(nb, (t + 1) * chunk);
    std::ptrdiff_t b0 = std::min(nb, t * chunk);
    Displacements d;
#if defined(__x86_64__) && defined(__GNUC__)
    if (detail::useAvx2()) b0 = displacementsAvx2(x, atPairs, atPlanes, b0, b1, d);
#endif
    displacementsScalar(x, atPairs, atPlanes, b0, b1, d);
    partial[part] = d;
  });
  Displacements d;
  partial.forEach([&](const Displacements& p) {
    for (int c = 0; c < 3; ++c) d.lo[c] = std::min(d.lo[c], p.lo[c]), d.hi[c] = std::max(d.hi[c], p.hi[c]);
    d.absolute2 = std::max(d.absolute2, p.absolute2), d.plane2 = std::max(d.plane2, p.plane2);
  });
  Rebuild what;
  what.planes = anyPlane && std::sqrt(d.plane2) + planesMoved(planes) > settings.skin;
  if (!pairs || 2.0 * std::sqrt(d.absolute2) <= settings.skin) return what;
  const Vec3 u = 0.5 * (Vec3(d.lo[0], d.lo[1], d.lo[2]) + Vec3(d.hi[0], d.hi[1], d.hi[2]));
  double relative2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : relative2) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) relative2 = std::max(relative2, (x[b] - atPairs[b] - u).squaredNorm());
  what.pairs = 2.0 * std::min(std::sqrt(relative2), std::sqrt(d.absolute2)) > settings.skin;
  return what;
}

double NeighbourList::planesMoved(const std::vector<PlaneWall>& planes) const {
  double moved = 0.0;
  for (std::size_t w = 0; w < planes.size(); ++w)
    moved = std::max(moved, (planes[w].point - planePointsAtBuild_[w]).norm());
  return moved;
}

void NeighbourList::keepPoses(Poses& at, const Bodies& bodies, bool lone) {
  // Into the arrays of the last build: no allocation. Lone spheres never turn a member (bodyReach is
  // 0): the rebuild tests read no orientation.
  at.position.resize(bodies.size());
  const auto nb = static_cast<std::ptrdiff_t>(bodies.size());
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) at.position[b] = bodies.position[b];
  if (lone)
    at.orientation.clear();
  else
    at.orientation = bodies.orientation;
}

void NeighbourList::planesBuilt(const Bodies& bodies, bool lone, const std::vector<PlaneWall>& planes) {
  planePointsAtBuild_.clear();
  for (const auto& p : planes) planePointsAtBuild_.push_back(p.point);
  keepPoses(atPlanes_, bodies, lone);
}

void NeighbourList::meshBuilt(const Bodies& bodies, bool lone, const std::vector<MeshWall>& meshes) {
  meshNodesAtBuild_.clear();
  for (const auto& w : meshes) meshNodesAtBuild_.push_back(w.nodes);
  if (meshes.empty()) {  // needsRebuild() reads no poses then
    atMesh_ = Poses{};
    return;
  }
  keepPoses(atMesh_, bodies, lone);
}

void NeighbourList::findActive(const StepContext& ctx, const ContactSet& pairs, const ContactSet& walls,
                               const MeshContacts& mesh, const BondSet& bonds) {
  // The active spheres: those in a candidate of any kind, and per body its run of them. Only these get
  // forces computed; the others' stay zero.
  const std::size_t ns = ctx.spheres.size();
  const auto count = static_cast<std::ptrdiff_t>(ns);
  const int nt = count > kParallelMin ? omp_get_max_threads() : 1;
  Vec3* force = ctx.force;
  Vec3* torque = ctx.torque;
  auto& in = work_->inCandidate;
  in.resize(ns);
  auto& threadCount = work_->threadCount;
  threadCount.assign(static_cast<std::size_t>(nt) + 1, 0);
  const auto np = static_cast<std::ptrdiff_t>(pairs.size()), nw = static_cast<std::ptrdiff_t>(walls.size());
  // Lone spheres: sphere s is body s, so its run starts after the active spheres before it.
  const bool lone = ctx.loneSpheres;
  if (lone) activeStart_.resize(ns + 1);
#pragma omp parallel num_threads(nt) if (nt > 1)
  {
    const auto t = static_cast<std::size_t>(omp_get_thread_num());
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) in[s] = 0, force[s].setZero(), torque[s].setZero();
    // Several threads may mark one sphere, all with the same value.
    auto mark = [&](std::uint32_t s) { std::atomic_ref<unsigned char>(in[s]).store(1, std::memory_order_relaxed); };
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < np; ++k) mark(pairs.a[k]), mark(pairs.b[k]);
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < nw; ++k) mark(walls.a[k]);
#pragma omp single
    {
      for (const auto& c : mesh.candidates) mark(c.sphere);
      bonds.forEachBondedSphere(mark);
    }
    // The active spheres in order: each thread counts its run of spheres, then writes them after the
    // runs before it (the same static split in both loops).
    std::uint32_t mine = 0;
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) mine += in[s];
    threadCount[t + 1] = mine;
#pragma omp barrier
#pragma omp single
    {
      std::partial_sum(threadCount.begin(), threadCount.end(), threadCount.begin());
      active_.resize(threadCount.back());
    }
    std::uint32_t next = threadCount[t];
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) {
      if (lone) activeStart_[s] = next;
      if (in[s]) active_[next++] = static_cast<std::uint32_t>(s);
    }
  }
  if (lone) {
    activeStart_[ns] = static_cast<std::uint32_t>(active_.size());
    return;
  }
  activeStart_.assign(ctx.bodies.size() + 1, 0);
  for (auto s : active_) ++activeStart_[ctx.spheres.body[s] + 1];
  std::partial_sum(activeStart_.begin(), activeStart_.end(), activeStart_.begin());
}

std::vector<Triple>& NeighbourList::findPairs(const StepContext& ctx, const BondSet& bonds) {
  std::vector<Triple>& pairs = work_->lists.joined;
  pairs.clear();
  if (ctx.spheres.size() > 1 && prepared_.pairsPossible) {
    // Sorted by (a, b); by law too when all pairs share one (the other laws are with walls). Several
    // laws: ContactSet::assign sorts them by (law, a, b), after testing the order on all threads.
    collectPairs(ctx, bonds, sortIntoCells(ctx.spheres, ctx.settings.skin), pairs);
  }
  return pairs;
}

std::array<std::ptrdiff_t, 9> NeighbourList::sortIntoCells(const Spheres& spheres, double skin) {
  const std::size_t ns = spheres.size();
  double lx = kInf, ly = kInf, lz = kInf, hx = -kInf, hy = -kInf, hz = -kInf;
  const Vec3* position = spheres.position.data();
  const auto count = static_cast<std::ptrdiff_t>(ns);
  // clang-format off
#pragma omp parallel for schedule(static) reduction(min : lx, ly, lz) reduction(max : hx, hy, hz) if (count > kParallelMin)
  // clang-format on
  for (std::ptrdiff_t s = 0; s < count; ++s) {
    lx = std::min(lx, position[s].x()), ly = std::min(ly, position[s].y()), lz = std::min(lz, position[s].z());
    hx = std::max(hx, position[s].x()), hy = std::max(hy, position[s].y()), hz = std::max(hz, position[s].z());
  }
  common::Aabb box;
  box.expand(Vec3(lx, ly, lz));
  box.expand(Vec3(hx, hy, hz));
  const double rmax = *std::max_element(spheres.radius.begin(), spheres.radius.end());
  double cell = 2.0 * rmax + skin;
  const Vec3 extent = box.extent();
  // Keep the grid at most ~2 cells per sphere so sparse scenes do not allocate huge grids.
  while ((extent / cell).array().floor().matrix().prod() > 2.0 * static_cast<double>(ns) + 27) cell *= 1.5;
  Eigen::Array3i dims = ((extent / cell).array().floor() + 1).cast<int>();
  // A layer of empty cells around the grid: the 27 neighbours of any cell are at fixed index offsets,
  // with no bounds to check.
  const Eigen::Array3i padded = dims + 2;
  auto cellOf = [&](const Vec3& p) -> std::uint32_t {
    const Eigen::Array3i c = ((p - box.min) / cell).array().floor().cast<int>().min(dims - 1) + 1;
    return static_cast<std::uint32_t>((c.z() * padded.y() + c.y()) * padded.x() + c.x());
  };
  // The 27 cells around as 9 runs of three cells along x, which are consecutive in the grid and so
  // their spheres in cell order.
  std::array<std::ptrdiff_t, 9> row{};
  for (int dz = -1, n = 0; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy) row[n++] = (dz * padded.y() + dy) * padded.x() - 1;
  const std::size_t ncells = static_cast<std::size_t>(padded.prod());
  std::vector<std::uint32_t>& start = work_->cellStart;
  std::vector<std::uint32_t>& cellIndex = work_->cellIndex;
  start.assign(ncells + 1, 0);
  cellIndex.resize(ns);
  detail::CellOrdered& sorted = work_->cellOrdered;
  sorted.resize(ns);
  std::uint32_t* order = sorted.index.data();
#pragma omp parallel for schedule(static) if (count > kParallelMin)
  for (std::ptrdiff_t s = 0; s < count; ++s) cellIndex[s] = cellOf(position[s]);
  for (std::size_t s = 0; s < ns; ++s) ++start[cellIndex[s] + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t s = 0; s < ns; ++s) order[fill[cellIndex[s]]++] = static_cast<std::uint32_t>(s);
  }
  // Centres and radii in cell order: a cell's spheres are read one after the other.
#pragma omp parallel for schedule(static) if (count > kParallelMin)
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    const Vec3& x = position[order[k]];
    sorted.x[k] = x.x(), sorted.y[k] = x.y(), sorted.z[k] = x.z(), sorted.r[k] = spheres.radius[order[k]];
  }
  return row;
}

void NeighbourList::collectPairs(const StepContext& ctx, const BondSet& bonds, const std::array<std::ptrdiff_t, 9>& row,
                                 std::vector<Triple>& pairs) {
  const Spheres& spheres = ctx.spheres;
  const std::size_t ns = spheres.size();
  const double skin = ctx.settings.skin;
  const bool loneSpheres = ctx.loneSpheres;
  const std::vector<std::uint32_t>& start = work_->cellStart;
  const std::vector<std::uint32_t>& cellIndex = work_->cellIndex;
  const detail::CellOrdered& sorted = work_->cellOrdered;
  [[maybe_unused]] const bool avx2 = detail::useAvx2();
  const bool bonded = !bonds.empty();
  // Each sphere's partners sorted as found (a handful), the threads' runs of spheres joined in order:
  // the list comes out sorted by (a, b), so with one law it needs no global sort.
  auto& local = work_->lists.local;
  local.resize(static_cast<std::size_t>(omp_get_max_threads()));
  local.forEach([](std::vector<Triple>& l) { l.clear(); });
#pragma omp parallel if (static_cast<std::ptrdiff_t>(ns) > kParallelMin)
  {
    const auto thread = static_cast<std::size_t>(omp_get_thread_num());
    auto& mine = thread == 0 ? pairs : local[thread];
    std::vector<std::uint32_t> found;  // sphere i's partners j > i within reach
#pragma omp for schedule(static)
    for (std::ptrdiff_t si = 0; si < static_cast<std::ptrdiff_t>(ns); ++si) {
      const auto i = static_cast<std::uint32_t>(si);
      const Vec3 xi = spheres.position[i];
      const double ri = spheres.radius[i];
      std::uint32_t k0[9], k1[9];  // the runs of spheres around, in cell order
      std::size_t around = 0;
      for (int r = 0; r < 9; ++r) {
        const auto ci = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(cellIndex[i]) + row[r]);
        k0[r] = start[ci], k1[r] = start[ci + 3];
        around += k1[r] - k0[r];
      }
      if (found.size() < around + 4) found.resize(around + 4);
      std::uint32_t* out = found.data();
      std::size_t n = 0;
#if defined(__x86_64__) && defined(__GNUC__)
      if (avx2)
        n = partnersAvx2(sorted, k0, k1, i, xi, ri, skin, out);
      else
#endif
        for (int r = 0; r < 9; ++r) n = partnersScalar(sorted, k0[r], k1[r], i, xi, ri, skin, out, n);
      std::sort(out, out + n);
      for (std::size_t p = 0; p < n; ++p) {
        const std::uint32_t j = out[p];
        // After the distance: body[j] is a load from anywhere, and lone spheres need no test.
        if (!loneSpheres && spheres.body[i] == spheres.body[j]) continue;
        if (bonded && bonds.bonded(i, j)) continue;  // the bond acts instead, until it breaks
        if (!computes(i, j)) continue;  // another rank computes it
        const int law = ctx.lawOf[spheres.material[i] * ctx.materials + spheres.material[j]];
        if (law >= 0) mine.emplace_back(law, i, j);
      }
    }
    detail::joinInOrder(local, thread, pairs);
  }
}

}  // namespace dem
