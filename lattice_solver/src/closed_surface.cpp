#include "lattice/closed_surface.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <tuple>

#include <fmt/format.h>

#include "common/geometry.hpp"

namespace lattice {

namespace {

// Ray directions: unit vectors far from the axes and the diagonals, so that a ray from a point of a
// box- or prism-shaped specimen neither runs along a face nor through a row of edges.
const std::array<Vec3, 3> kRayDirections{Vec3(0.3612, 0.4851, 0.7964).normalized(), Vec3(-0.7071, 0.2113, 0.6751).normalized(),
                                         Vec3(0.5402, -0.8017, 0.2561).normalized()};
constexpr double kEdgeMargin = 1e-9;  // barycentric distance from an edge below which a crossing is ambiguous

// Fills a CSR bin table: `count(emit)` calls emit(bin, item) for every item and bin it overlaps.
template <class Emit>
void binItems(std::size_t bins, Emit&& forEach, std::vector<std::uint32_t>& start, std::vector<std::uint32_t>& items) {
  start.assign(bins + 1, 0);
  forEach([&](std::size_t bin, std::uint32_t) { ++start[bin + 1]; });
  std::partial_sum(start.begin(), start.end(), start.begin());
  items.resize(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  forEach([&](std::size_t bin, std::uint32_t item) { items[fill[bin]++] = item; });
}

}  // namespace

ClosedSurface::ClosedSurface(std::vector<Vec3> vertices, std::vector<Triangle> triangles)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  if (triangles_.empty()) throw std::invalid_argument("the surface has no triangles");
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& t : triangles_)
    for (auto i : t) {
      lo = lo.cwiseMin(vertices_[i]);
      hi = hi.cwiseMax(vertices_[i]);
    }
  bounds_.origin = lo;
  bounds_.size = hi - lo;
  tolerance_ = 1e-9 * std::max(bounds_.size.norm(), (0.5 * (lo + hi)).norm());

  // Closedness and orientation: every edge must be used by exactly two triangles; orient each connected
  // part so that neighbours run through their shared edge in opposite directions (breadth first).
  const std::size_t T = triangles_.size();
  std::vector<std::tuple<std::uint64_t, std::uint32_t, bool>> edges;  // (key, triangle, runs a→b with a < b)
  edges.reserve(3 * T);
  for (std::uint32_t t = 0; t < T; ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t a = triangles_[t][static_cast<std::size_t>(k)], b = triangles_[t][static_cast<std::size_t>((k + 1) % 3)];
      edges.emplace_back(std::min(a, b) << 32 | std::max(a, b), t, a < b);
    }
  std::sort(edges.begin(), edges.end());
  std::vector<std::array<std::uint32_t, 3>> neighbour(T, {~0u, ~0u, ~0u});
  std::vector<std::array<bool, 3>> same(T);  // neighbour runs the shared edge the same way (needs a flip)
  std::vector<std::uint8_t> slots(T, 0);
  std::size_t open = 0;
  Vec3 openAt = Vec3::Zero();
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && std::get<0>(edges[j]) == std::get<0>(edges[i])) ++j;
    if (j - i != 2) {
      if (open++ == 0) openAt = vertices_[std::get<0>(edges[i]) >> 32];
    } else {
      const auto [k1, t1, d1] = edges[i];
      const auto [k2, t2, d2] = edges[i + 1];
      neighbour[t1][slots[t1]] = t2;
      same[t1][slots[t1]++] = d1 == d2;
      neighbour[t2][slots[t2]] = t1;
      same[t2][slots[t2]++] = d1 == d2;
    }
    i = j;
  }
  if (open > 0)
    throw std::invalid_argument(fmt::format("the surface is not closed: {} edges are not shared by exactly two triangles "
                                            "(one at ({:.6g}, {:.6g}, {:.6g}))",
                                            open, openAt.x(), openAt.y(), openAt.z()));
  std::vector<std::int8_t> flip(T, -1);
  std::vector<std::uint32_t> queue;
  for (std::uint32_t seed = 0; seed < T; ++seed) {
    if (flip[seed] >= 0) continue;
    flip[seed] = 0;
    queue.assign(1, seed);
    double part = 0.0;
    std::vector<std::uint32_t> members;
    while (!queue.empty()) {
      const std::uint32_t t = queue.back();
      queue.pop_back();
      members.push_back(t);
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t n = neighbour[t][static_cast<std::size_t>(k)];
        if (n == ~0u || flip[n] >= 0) continue;
        flip[n] = static_cast<std::int8_t>(flip[t] ^ (same[t][static_cast<std::size_t>(k)] ? 1 : 0));
        queue.push_back(n);
      }
    }
    for (auto t : members) {
      if (flip[t]) std::swap(triangles_[t][1], triangles_[t][2]);
      const auto& [a, b, c] = triangles_[t];
      part += vertices_[a].dot(vertices_[b].cross(vertices_[c])) / 6.0;
    }
    // Each closed part counts with its own volume (a cavity would add instead of subtract; specimens
    // have none).
    volume_ += std::abs(part);
  }

  // 3-D grid of cells about as large as the mean triangle edge, at most ~2·10⁶ cells.
  double edgeSum = 0.0;
  for (const auto& [a, b, c] : triangles_)
    edgeSum += (vertices_[b] - vertices_[a]).norm() + (vertices_[c] - vertices_[b]).norm() + (vertices_[a] - vertices_[c]).norm();
  cell_ = std::max(edgeSum / (3.0 * static_cast<double>(T)), std::cbrt(bounds_.volume() / 2e6));
  cell_ = std::max(cell_, 1e-6 * bounds_.size.maxCoeff());
  for (int k = 0; k < 3; ++k) dims_[static_cast<std::size_t>(k)] = std::max(1L, static_cast<long>(std::ceil(bounds_.size[k] / cell_)));
  auto cellRange = [&](const Vec3& a, const Vec3& b, int k) {
    const auto lo = std::clamp(static_cast<long>(std::floor((a[k] - bounds_.origin[k]) / cell_)), 0L, dims_[static_cast<std::size_t>(k)] - 1);
    const auto hi = std::clamp(static_cast<long>(std::floor((b[k] - bounds_.origin[k]) / cell_)), 0L, dims_[static_cast<std::size_t>(k)] - 1);
    return std::pair{lo, hi};
  };
  binItems(static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]),
           [&](auto&& emit) {
             for (std::uint32_t t = 0; t < T; ++t) {
               const auto& [a, b, c] = triangles_[t];
               const Vec3 lo = vertices_[a].cwiseMin(vertices_[b]).cwiseMin(vertices_[c]).array() - tolerance_;
               const Vec3 hi = vertices_[a].cwiseMax(vertices_[b]).cwiseMax(vertices_[c]).array() + tolerance_;
               const auto [x0, x1] = cellRange(lo, hi, 0);
               const auto [y0, y1] = cellRange(lo, hi, 1);
               const auto [z0, z1] = cellRange(lo, hi, 2);
               for (long z = z0; z <= z1; ++z)
                 for (long y = y0; y <= y1; ++y)
                   for (long x = x0; x <= x1; ++x) emit(static_cast<std::size_t>((z * dims_[1] + y) * dims_[0] + x), t);
             }
           },
           start_, items_);
  for (std::size_t d = 0; d < kRayDirections.size(); ++d) rays_[d] = buildGrid2(kRayDirections[d]);
}

ClosedSurface::Grid2 ClosedSurface::buildGrid2(const Vec3& dir) const {
  Grid2 g;
  g.dir = dir;
  g.u = dir.unitOrthogonal();
  g.v = dir.cross(g.u);
  double hi[2] = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  g.lo[0] = g.lo[1] = std::numeric_limits<double>::infinity();
  for (const auto& x : vertices_) {
    const double c[2] = {x.dot(g.u), x.dot(g.v)};
    for (int k = 0; k < 2; ++k) {
      g.lo[k] = std::min(g.lo[k], c[k]);
      hi[k] = std::max(hi[k], c[k]);
    }
  }
  g.cell = cell_;
  for (int k = 0; k < 2; ++k) g.dims[k] = std::max(1L, static_cast<long>(std::ceil((hi[k] - g.lo[k]) / g.cell)));
  binItems(static_cast<std::size_t>(g.dims[0] * g.dims[1]),
           [&](auto&& emit) {
             for (std::uint32_t t = 0; t < triangles_.size(); ++t) {
               double lo[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
               double up[2] = {-lo[0], -lo[1]};
               for (auto i : triangles_[t]) {
                 const double c[2] = {vertices_[i].dot(g.u), vertices_[i].dot(g.v)};
                 for (int k = 0; k < 2; ++k) {
                   lo[k] = std::min(lo[k], c[k]);
                   up[k] = std::max(up[k], c[k]);
                 }
               }
               long r[2][2];
               for (int k = 0; k < 2; ++k) {
                 r[k][0] = std::clamp(static_cast<long>(std::floor((lo[k] - g.lo[k]) / g.cell)), 0L, g.dims[k] - 1);
                 r[k][1] = std::clamp(static_cast<long>(std::floor((up[k] - g.lo[k]) / g.cell)), 0L, g.dims[k] - 1);
               }
               for (long y = r[1][0]; y <= r[1][1]; ++y)
                 for (long x = r[0][0]; x <= r[0][1]; ++x) emit(static_cast<std::size_t>(y * g.dims[0] + x), t);
             }
           },
           g.start, g.items);
  return g;
}

template <class F>
bool ClosedSurface::forTrianglesNear(const Vec3& lo, const Vec3& hi, F&& f) const {
  long r[3][2];
  for (int k = 0; k < 3; ++k) {
    const long d = dims_[static_cast<std::size_t>(k)];
    r[k][0] = std::clamp(static_cast<long>(std::floor((lo[k] - bounds_.origin[k]) / cell_)), 0L, d - 1);
    r[k][1] = std::clamp(static_cast<long>(std::floor((hi[k] - bounds_.origin[k]) / cell_)), 0L, d - 1);
  }
  for (long z = r[2][0]; z <= r[2][1]; ++z)
    for (long y = r[1][0]; y <= r[1][1]; ++y)
      for (long x = r[0][0]; x <= r[0][1]; ++x) {
        const auto c = static_cast<std::size_t>((z * dims_[1] + y) * dims_[0] + x);
        for (auto i = start_[c]; i < start_[c + 1]; ++i)
          if (!f(items_[i])) return false;
      }
  return true;
}

bool ClosedSurface::clearOf(const Vec3& p, double r) const {
  const Vec3 lo = p.array() - r, hi = p.array() + r;
  return forTrianglesNear(lo, hi, [&](std::uint32_t t) {
    const auto& [a, b, c] = triangles_[t];
    return common::closestPointOnTriangle(p, vertices_[a], vertices_[b], vertices_[c]).distanceSquared >= r * r;
  });
}

int ClosedSurface::crossings(const Grid2& g, const Vec3& p) const {
  const double c[2] = {p.dot(g.u), p.dot(g.v)};
  long idx[2];
  for (int k = 0; k < 2; ++k) {
    const double f = std::floor((c[k] - g.lo[k]) / g.cell);
    if (f < 0 || f >= static_cast<double>(g.dims[k])) return 0;  // the ray misses the surface's shadow
    idx[k] = static_cast<long>(f);
  }
  const auto cell = static_cast<std::size_t>(idx[1] * g.dims[0] + idx[0]);
  int count = 0;
  for (auto i = g.start[cell]; i < g.start[cell + 1]; ++i) {
    // Möller–Trumbore ray–triangle intersection.
    const auto& [ia, ib, ic] = triangles_[g.items[i]];
    const Vec3 &a = vertices_[ia], e1 = vertices_[ib] - a, e2 = vertices_[ic] - a;
    const Vec3 pv = g.dir.cross(e2);
    const double det = e1.dot(pv);
    const Vec3 tv = p - a;
    if (std::abs(det) <= 1e-12 * e1.norm() * e2.norm()) {
      // The ray runs parallel to the triangle: ambiguous only if it lies in its plane.
      if (std::abs(tv.dot(e1.cross(e2))) <= 1e-12 * e1.norm() * e2.norm() * tv.norm()) return -1;
      continue;
    }
    const double u = tv.dot(pv) / det;
    if (u < -kEdgeMargin || u > 1 + kEdgeMargin) continue;
    const Vec3 qv = tv.cross(e1);
    const double v = g.dir.dot(qv) / det;
    if (v < -kEdgeMargin || u + v > 1 + kEdgeMargin) continue;
    if (e2.dot(qv) / det <= 0) continue;
    if (u < kEdgeMargin || v < kEdgeMargin || u + v > 1 - kEdgeMargin) return -1;
    ++count;
  }
  return count;
}

bool ClosedSurface::contains(const Vec3& p, double margin) const {
  margin = std::max(margin, tolerance_);
  const Vec3 lo = bounds_.origin.array() - margin, hi = (bounds_.origin + bounds_.size).array() + margin;
  if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) return false;
  const double tol2 = margin * margin;
  const bool onSurface = !forTrianglesNear(p.array() - margin, p.array() + margin, [&](std::uint32_t t) {
    const auto& [a, b, c] = triangles_[t];
    return common::closestPointOnTriangle(p, vertices_[a], vertices_[b], vertices_[c]).distanceSquared > tol2;
  });
  if (onSurface) return true;
  int n = -1;
  for (const auto& g : rays_)
    if ((n = crossings(g, p)) >= 0) break;
  return n > 0 && n % 2 == 1;
}

}  // namespace lattice
