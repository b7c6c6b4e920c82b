#include "lattice/specimen.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <random>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "lattice/closed_surface.hpp"
#include "lattice/volume_geometry.hpp"

namespace lattice {

const char* phaseName(Phase p) {
  switch (p) {
    case Phase::kMatrix: return "matrix";
    case Phase::kAggregate: return "aggregate";
    case Phase::kInterface: return "interface";
  }
  return "?";
}

double Specimen::meanRodLength() const {
  if (rods.empty()) return 0.0;
  double sum = 0.0;
  for (const auto& [a, b] : rods) sum += (nodes[b] - nodes[a]).norm();
  return sum / static_cast<double>(rods.size());
}

namespace {

// Uniform cells over a box with a linked list per cell (head per cell, next per item): 4 bytes per cell,
// so fine grids of large specimens stay small.
class CellGrid {
 public:
  CellGrid(const Box& box, double cell) : origin_(box.origin), cell_(cell) {
    for (int k = 0; k < 3; ++k) dims_[k] = std::max<long>(1, static_cast<long>(std::ceil(box.size[k] / cell)));
    head_.assign(static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]), -1);
  }
  std::array<long, 3> cellOf(const Vec3& p) const {
    std::array<long, 3> c{};
    for (int k = 0; k < 3; ++k)
      c[k] = std::clamp(static_cast<long>(std::floor((p[k] - origin_[k]) / cell_)), 0L, dims_[k] - 1);
    return c;
  }
  void insert(const Vec3& p, std::int32_t item) {
    const auto c = cellOf(p);
    const std::size_t i = index(c);
    if (next_.size() <= static_cast<std::size_t>(item)) next_.resize(static_cast<std::size_t>(item) + 1, -1);
    next_[static_cast<std::size_t>(item)] = head_[i];
    head_[i] = item;
  }
  /// Calls f(item) for the items of the 27 cells around p; stops early when f returns false.
  template <class F>
  bool forNeighbours(const Vec3& p, F&& f) const {
    const auto c = cellOf(p);
    for (long x = std::max(0L, c[0] - 1); x <= std::min(dims_[0] - 1, c[0] + 1); ++x)
      for (long y = std::max(0L, c[1] - 1); y <= std::min(dims_[1] - 1, c[1] + 1); ++y)
        for (long z = std::max(0L, c[2] - 1); z <= std::min(dims_[2] - 1, c[2] + 1); ++z)
          for (std::int32_t i = head_[index({x, y, z})]; i >= 0; i = next_[static_cast<std::size_t>(i)])
            if (!f(static_cast<std::size_t>(i))) return false;
    return true;
  }

 private:
  std::size_t index(const std::array<long, 3>& c) const {
    return static_cast<std::size_t>((c[2] * dims_[1] + c[1]) * dims_[0] + c[0]);
  }
  Vec3 origin_;
  double cell_;
  std::array<long, 3> dims_{};
  std::vector<std::int32_t> head_, next_;
};

}  // namespace

namespace {

// Random sequential addition of nodes at least `minGap` apart (dart throwing on a cell grid), one
// manifold at a time (a corner, an edge or curve, a face or surface, the volume).
class DartThrower {
 public:
  DartThrower(const Box& bounds, double minGap, std::uint64_t seed)
      : rng_(seed), grid_(bounds, std::max(minGap, 1e-3 * bounds.size.minCoeff())), gap2_(minGap * minGap), minGap_(minGap) {}
  bool tryAdd(const Vec3& p) {
    const bool free = grid_.forNeighbours(p, [&](std::size_t j) { return (nodes_[j] - p).squaredNorm() >= gap2_; });
    if (!free) return false;
    grid_.insert(p, static_cast<std::int32_t>(nodes_.size()));
    nodes_.push_back(p);
    return true;
  }
  double uniform() { return unit_(rng_); }
  /// Places round(target) nodes drawn by `sample()` (an std::optional<Vec3>: empty = outside, not
  /// counted as an attempt); throws when the hard core leaves no room for them.
  template <class Sample>
  void fill(Sample&& sample, double target, const char* what) {
    const auto want = static_cast<std::size_t>(std::max(0LL, std::llround(target)));
    std::size_t placed = 0, attempts = 0, draws = 0;
    const std::size_t maxAttempts = 100 * want + 1000;
    while (placed < want && attempts < maxAttempts && draws < 1000 * maxAttempts) {
      ++draws;
      const auto p = sample();
      if (!p) continue;
      ++attempts;
      if (tryAdd(*p)) ++placed;
    }
    if (placed < want)
      throw std::invalid_argument(fmt::format("only {} of {} nodes fit on/in the specimen {} at a minimum distance of {:.4g} m; "
                                              "lower the minimum distance",
                                              placed, want, what, minGap_));
  }
  std::vector<Vec3> take() { return std::move(nodes_); }

 private:
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
  CellGrid grid_;
  std::vector<Vec3> nodes_;
  double gap2_, minGap_;
};

// Edges and curves get 0.9 of the bulk line density: 1-D random sequential addition jams at 0.75 of the
// hard-core length, which the full density would approach for min_distance near 0.7.
constexpr double kLineDensity = 0.9;

}  // namespace

std::vector<Vec3> randomNodes(const Box& box, double spacing, double minGap, std::uint64_t seed) {
  DartThrower darts(box, minGap, seed);
  // Uniform points of one manifold given as origin + t·axes.
  auto flat = [&](const Vec3& o, const std::vector<Vec3>& axes) {
    return [&darts, o, axes] {
      Vec3 p = o;
      for (const auto& a : axes) p += darts.uniform() * a;
      return std::optional<Vec3>(p);
    };
  };
  const Vec3& o = box.origin;
  const Vec3& s = box.size;
  const Vec3 ex(s.x(), 0, 0), ey(0, s.y(), 0), ez(0, 0, s.z());
  const std::array<Vec3, 3> axis{ex, ey, ez};
  for (int c = 0; c < 8; ++c) darts.tryAdd(o + ((c & 1) ? ex : Vec3::Zero()) + ((c & 2) ? ey : Vec3::Zero()) + ((c & 4) ? ez : Vec3::Zero()));
  for (int k = 0; k < 3; ++k) {
    const Vec3& a = axis[static_cast<std::size_t>(k)];
    const Vec3& b = axis[static_cast<std::size_t>((k + 1) % 3)];
    const Vec3& c = axis[static_cast<std::size_t>((k + 2) % 3)];
    for (int e = 0; e < 4; ++e)
      darts.fill(flat(o + ((e & 1) ? b : Vec3::Zero()) + ((e & 2) ? c : Vec3::Zero()), {a}), kLineDensity * a.norm() / spacing - 1.0,
                 "edges");
  }
  for (int k = 0; k < 3; ++k) {
    const Vec3& b = axis[static_cast<std::size_t>((k + 1) % 3)];
    const Vec3& c = axis[static_cast<std::size_t>((k + 2) % 3)];
    const double area = b.norm() * c.norm();
    for (int side = 0; side < 2; ++side)
      darts.fill(flat(o + (side ? axis[static_cast<std::size_t>(k)] : Vec3::Zero()), {b, c}), area / (spacing * spacing), "faces");
  }
  darts.fill(flat(o, {ex, ey, ez}), box.volume() / (spacing * spacing * spacing), "volume");
  return darts.take();
}

std::vector<Vec3> randomNodes(const VolumeGeometry& g, const ClosedSurface& surface, double spacing, double minGap,
                              std::uint64_t seed) {
  DartThrower darts(surface.bounds(), minGap, seed);
  const auto& X = g.vertices;
  // Picks an item with probability proportional to its weight (cumulative weights, binary search).
  auto picker = [&darts](const std::vector<double>& cumulative) {
    const double r = darts.uniform() * cumulative.back();
    return static_cast<std::size_t>(std::min<std::ptrdiff_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), r) - cumulative.begin(), static_cast<std::ptrdiff_t>(cumulative.size()) - 1));
  };
  for (auto c : g.corners) darts.tryAdd(X[c]);
  for (const auto& curve : g.curves) {
    std::vector<double> cum;
    for (const auto& [a, b] : curve) cum.push_back((cum.empty() ? 0.0 : cum.back()) + (X[b] - X[a]).norm());
    const auto sample = [&] {
      const auto& [a, b] = curve[picker(cum)];
      return std::optional<Vec3>(X[a] + darts.uniform() * (X[b] - X[a]));
    };
    darts.fill(sample, kLineDensity * cum.back() / spacing - 1.0, "curves");
  }
  for (const auto& s : g.surfaces) {
    std::vector<double> cum;
    for (const auto& [a, b, c] : s.triangles) cum.push_back((cum.empty() ? 0.0 : cum.back()) + 0.5 * (X[b] - X[a]).cross(X[c] - X[a]).norm());
    const auto sample = [&] {
      const auto& [a, b, c] = s.triangles[picker(cum)];
      const double r1 = std::sqrt(darts.uniform()), r2 = darts.uniform();  // uniform on the triangle
      return std::optional<Vec3>(X[a] + r1 * ((1 - r2) * (X[b] - X[a]) + r2 * (X[c] - X[a])));
    };
    darts.fill(sample, cum.back() / (spacing * spacing), "surfaces");
  }
  const Box& bounds = surface.bounds();
  const auto inside = [&]() -> std::optional<Vec3> {
    const Vec3 p = bounds.origin + Vec3(darts.uniform(), darts.uniform(), darts.uniform()).cwiseProduct(bounds.size);
    if (!surface.contains(p)) return std::nullopt;
    return p;
  };
  darts.fill(inside, surface.volume() / (spacing * spacing * spacing), "volume");
  return darts.take();
}

Specimen randomSpecimen(const Box& box, double rodLength, double minDistance, std::uint64_t seed) {
  if (!(rodLength > 0) || rodLength >= box.size.minCoeff())
    throw std::invalid_argument(fmt::format("the rod length {:.4g} m must be positive and below the smallest specimen side {:.4g} m",
                                            rodLength, box.size.minCoeff()));
  if (!(minDistance >= 0 && minDistance < 1))
    throw std::invalid_argument(fmt::format("the minimum distance {} must be in [0, 1) of the node spacing", minDistance));
  // The mean Delaunay edge is ≈ 1.2–1.35 node spacings (1.237 for Poisson points in an unbounded
  // volume, less with a hard core, more near the hull). Start from 1.25 and correct once by the ratio
  // of the measured to the asked length.
  double spacing = rodLength / 1.25;
  Specimen sp;
  sp.box = box;
  for (int pass = 0; pass < 2; ++pass) {
    sp.nodes = randomNodes(box, spacing, minDistance * spacing, seed);
    sp.rods = delaunayRods(sp.nodes);
    spacing *= rodLength / sp.meanRodLength();
  }
  sp.phases.assign(sp.rods.size(), Phase::kMatrix);
  return sp;
}

// Chords between boundary nodes bulge out of the faceted surface by up to h²/8R (facet size h = l/2,
// curvature radius R) where the facets fold inwards; 0.05 l admits that for any R above 0.6 l, and
// still drops every rod across a notch wider than 0.1 l.
constexpr double kInsideMargin = 0.05;

Specimen randomSpecimen(const VolumeGeometry& geometry, double rodLength, double minDistance, std::uint64_t seed) {
  const ClosedSurface surface = geometry.closedSurface();
  const Box& bounds = surface.bounds();
  if (!(rodLength > 0) || rodLength >= bounds.size.minCoeff())
    throw std::invalid_argument(fmt::format("the rod length {:.4g} m must be positive and below the smallest side of the "
                                            "volume's bounding box {:.4g} m",
                                            rodLength, bounds.size.minCoeff()));
  if (!(minDistance >= 0 && minDistance < 1))
    throw std::invalid_argument(fmt::format("the minimum distance {} must be in [0, 1) of the node spacing", minDistance));
  double spacing = rodLength / 1.25;  // as for the box, corrected once by the measured mean rod length
  Specimen sp;
  sp.box = bounds;
  for (int pass = 0; pass < 2; ++pass) {
    sp.nodes = randomNodes(geometry, surface, spacing, minDistance * spacing, seed);
    keepInside(sp, delaunayTetrahedra(sp.nodes), surface, kInsideMargin * rodLength);
    spacing *= rodLength / sp.meanRodLength();
  }
  sp.phases.assign(sp.rods.size(), Phase::kMatrix);
  return sp;
}

void keepInside(Specimen& sp, const std::vector<Tetrahedron>& tets, const ClosedSurface& surface, double margin) {
  const auto& X = sp.nodes;
  const std::vector<Rod> edges = tetrahedronEdges(tets);
  std::vector<std::uint8_t> edgeInside(edges.size());
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::size_t e = 0; e < edges.size(); ++e) edgeInside[e] = surface.contains(0.5 * (X[edges[e][0]] + X[edges[e][1]]), margin);
  std::vector<std::uint8_t> tetInside(tets.size());
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const auto& [a, b, c, d] = tets[t];
    tetInside[t] = surface.contains(0.25 * (X[a] + X[b] + X[c] + X[d]), margin);
  }
  constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  auto edgeIndex = [&](std::uint32_t a, std::uint32_t b) {
    const Rod key{std::min(a, b), std::max(a, b)};
    return static_cast<std::size_t>(std::lower_bound(edges.begin(), edges.end(), key) - edges.begin());
  };
  std::vector<std::uint8_t> edgeUsed(edges.size(), 0), nodeUsed(X.size(), 0);
  double volume = 0.0;
  for (std::size_t t = 0; t < tets.size(); ++t) {
    if (!tetInside[t]) continue;
    const auto& tet = tets[t];
    std::array<std::size_t, 6> ids{};
    bool keep = true;
    for (int k = 0; k < 6 && keep; ++k) {
      ids[static_cast<std::size_t>(k)] = edgeIndex(tet[static_cast<std::size_t>(kEdges[k][0])], tet[static_cast<std::size_t>(kEdges[k][1])]);
      keep = edgeInside[ids[static_cast<std::size_t>(k)]] != 0;
    }
    if (!keep) continue;
    for (auto e : ids) edgeUsed[e] = 1;
    for (auto n : tet) nodeUsed[n] = 1;
    volume += std::abs((X[tet[1]] - X[tet[0]]).dot((X[tet[2]] - X[tet[0]]).cross(X[tet[3]] - X[tet[0]]))) / 6.0;
  }
  // Nodes of no kept tetrahedron go; the others keep their order.
  std::vector<std::uint32_t> renumber(X.size(), ~0u);
  std::vector<Vec3> nodes;
  for (std::size_t n = 0; n < X.size(); ++n)
    if (nodeUsed[n]) {
      renumber[n] = static_cast<std::uint32_t>(nodes.size());
      nodes.push_back(X[n]);
    }
  std::vector<Rod> rods;
  for (std::size_t e = 0; e < edges.size(); ++e)
    if (edgeUsed[e]) rods.push_back({renumber[edges[e][0]], renumber[edges[e][1]]});
  sp.nodes = std::move(nodes);
  sp.rods = std::move(rods);
  sp.solidVolume = volume;
}

Specimen cubicLattice(const Box& box, double rodLength) {
  if (!(rodLength > 0) || rodLength >= box.size.minCoeff())
    throw std::invalid_argument(fmt::format("the rod length {:.4g} m must be positive and below the smallest specimen side {:.4g} m",
                                            rodLength, box.size.minCoeff()));
  Specimen sp;
  sp.box = box;
  std::array<long, 3> n{};
  for (int k = 0; k < 3; ++k) n[k] = std::max(1L, std::lround(box.size[k] / rodLength));
  auto id = [&](long i, long j, long k) { return static_cast<std::uint32_t>((k * (n[1] + 1) + j) * (n[0] + 1) + i); };
  for (long k = 0; k <= n[2]; ++k)
    for (long j = 0; j <= n[1]; ++j)
      for (long i = 0; i <= n[0]; ++i)
        sp.nodes.push_back(box.origin + Vec3(box.size.x() * static_cast<double>(i) / static_cast<double>(n[0]),
                                             box.size.y() * static_cast<double>(j) / static_cast<double>(n[1]),
                                             box.size.z() * static_cast<double>(k) / static_cast<double>(n[2])));
  for (long k = 0; k <= n[2]; ++k)
    for (long j = 0; j <= n[1]; ++j)
      for (long i = 0; i <= n[0]; ++i) {
        if (i < n[0]) sp.rods.push_back({id(i, j, k), id(i + 1, j, k)});
        if (j < n[1]) sp.rods.push_back({id(i, j, k), id(i, j + 1, k)});
        if (k < n[2]) sp.rods.push_back({id(i, j, k), id(i, j, k + 1)});
      }
  sp.phases.assign(sp.rods.size(), Phase::kMatrix);
  return sp;
}

std::vector<Aggregate> placeAggregates(const Box& box, const SieveCurve& sieve, const AggregateSettings& s,
                                       const ClosedSurface* solid) {
  std::vector<Aggregate> placed;
  if (s.volumeFraction <= 0.0) return placed;
  std::mt19937_64 rng(s.seed);
  const double specimenVolume = solid ? solid->volume() : box.volume();
  const double target = s.volumeFraction * specimenVolume;
  const std::vector<double> diameters = sieve.sample(target, rng);
  if (diameters.empty()) return placed;
  if (diameters.front() >= box.size.minCoeff())
    throw PackingError(fmt::format("the largest aggregate (d = {:.4g} m) does not fit in the specimen (smallest side {:.4g} m)",
                                   diameters.front(), box.size.minCoeff()),
                       0.0);
  CellGrid grid(box, diameters.front() + s.gap);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double volume = 0.0;
  for (std::size_t i = 0; i < diameters.size(); ++i) {
    const double r = 0.5 * diameters[i];
    bool done = false;
    for (int attempt = 0; attempt < s.attempts && !done; ++attempt) {
      Vec3 c;
      for (int k = 0; k < 3; ++k) c[k] = box.origin[k] + r + unit(rng) * (box.size[k] - 2 * r);
      if (solid && !(solid->contains(c) && solid->clearOf(c, r))) continue;  // fully inside the volume
      const bool free = grid.forNeighbours(c, [&](std::size_t j) {
        const double d = r + placed[j].radius + s.gap;
        return (placed[j].center - c).squaredNorm() >= d * d;
      });
      if (!free) continue;
      grid.insert(c, static_cast<std::int32_t>(placed.size()));
      placed.push_back({c, r});
      volume += std::numbers::pi / 6.0 * diameters[i] * diameters[i] * diameters[i];
      done = true;
    }
    if (!done)
      throw PackingError(fmt::format("aggregate {} of {} (d = {:.4g} m) found no free place in {} random positions; {:.1f} % of "
                                     "the specimen volume was packed of the {:.1f} % asked",
                                     i + 1, diameters.size(), diameters[i], s.attempts, 100.0 * volume / specimenVolume,
                                     100.0 * s.volumeFraction),
                         volume / specimenVolume);
  }
  return placed;
}

void classifyRods(Specimen& sp) {
  sp.phases.assign(sp.rods.size(), Phase::kMatrix);
  if (sp.aggregates.empty()) return;
  double dMax = 0.0;
  for (const auto& a : sp.aggregates) dMax = std::max(dMax, 2 * a.radius);
  CellGrid grid(sp.box, dMax);
  for (std::size_t i = 0; i < sp.aggregates.size(); ++i) grid.insert(sp.aggregates[i].center, static_cast<std::int32_t>(i));
  std::vector<std::int32_t> inside(sp.nodes.size(), -1);
  for (std::size_t n = 0; n < sp.nodes.size(); ++n)
    grid.forNeighbours(sp.nodes[n], [&](std::size_t j) {
      const auto& a = sp.aggregates[j];
      if ((sp.nodes[n] - a.center).squaredNorm() < a.radius * a.radius) {
        inside[n] = static_cast<std::int32_t>(j);
        return false;
      }
      return true;
    });
  for (std::size_t r = 0; r < sp.rods.size(); ++r) {
    const std::int32_t a = inside[sp.rods[r][0]], b = inside[sp.rods[r][1]];
    sp.phases[r] = a < 0 && b < 0 ? Phase::kMatrix : a == b ? Phase::kAggregate : Phase::kInterface;
  }
}

}  // namespace lattice
