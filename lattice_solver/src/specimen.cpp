#include "lattice/specimen.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include <fmt/format.h>

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

std::vector<Vec3> randomNodes(const Box& box, double spacing, double minGap, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> nodes;
  CellGrid grid(box, std::max(minGap, 1e-3 * box.size.minCoeff()));
  const double gap2 = minGap * minGap;
  auto tryAdd = [&](const Vec3& p) {
    const bool free = grid.forNeighbours(p, [&](std::size_t j) { return (nodes[j] - p).squaredNorm() >= gap2; });
    if (!free) return false;
    grid.insert(p, static_cast<std::int32_t>(nodes.size()));
    nodes.push_back(p);
    return true;
  };
  // Dart throwing into one manifold (an edge, a face or the volume) given as origin + t·axes.
  auto fill = [&](const Vec3& o, const std::vector<Vec3>& axes, double target, const char* what) {
    const auto want = static_cast<std::size_t>(std::llround(target));
    std::size_t placed = 0, attempts = 0;
    const std::size_t maxAttempts = 100 * want + 1000;
    while (placed < want && attempts < maxAttempts) {
      ++attempts;
      Vec3 p = o;
      for (const auto& a : axes) p += unit(rng) * a;
      if (tryAdd(p)) ++placed;
    }
    if (placed < want)
      throw std::invalid_argument(fmt::format("only {} of {} nodes fit on/in the specimen {} at a minimum distance of {:.4g} m; "
                                              "lower the minimum distance",
                                              placed, want, what, minGap));
  };
  const Vec3& o = box.origin;
  const Vec3& s = box.size;
  const Vec3 ex(s.x(), 0, 0), ey(0, s.y(), 0), ez(0, 0, s.z());
  const std::array<Vec3, 3> axis{ex, ey, ez};
  for (int c = 0; c < 8; ++c) tryAdd(o + ((c & 1) ? ex : Vec3::Zero()) + ((c & 2) ? ey : Vec3::Zero()) + ((c & 4) ? ez : Vec3::Zero()));
  // Edges at 0.9 of the bulk line density: 1-D random sequential addition jams at 0.75 of the hard-core
  // length, which the full density would approach for min_distance near 0.7.
  for (int k = 0; k < 3; ++k) {
    const Vec3& a = axis[static_cast<std::size_t>(k)];
    const Vec3& b = axis[static_cast<std::size_t>((k + 1) % 3)];
    const Vec3& c = axis[static_cast<std::size_t>((k + 2) % 3)];
    for (int e = 0; e < 4; ++e)
      fill(o + ((e & 1) ? b : Vec3::Zero()) + ((e & 2) ? c : Vec3::Zero()), {a}, 0.9 * a.norm() / spacing - 1.0, "edges");
  }
  for (int k = 0; k < 3; ++k) {
    const Vec3& b = axis[static_cast<std::size_t>((k + 1) % 3)];
    const Vec3& c = axis[static_cast<std::size_t>((k + 2) % 3)];
    const double area = b.norm() * c.norm();
    for (int side = 0; side < 2; ++side)
      fill(o + (side ? axis[static_cast<std::size_t>(k)] : Vec3::Zero()), {b, c}, area / (spacing * spacing), "faces");
  }
  fill(o, {ex, ey, ez}, box.volume() / (spacing * spacing * spacing), "volume");
  return nodes;
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

std::vector<Aggregate> placeAggregates(const Box& box, const SieveCurve& sieve, const AggregateSettings& s) {
  std::vector<Aggregate> placed;
  if (s.volumeFraction <= 0.0) return placed;
  std::mt19937_64 rng(s.seed);
  const double target = s.volumeFraction * box.volume();
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
                                     i + 1, diameters.size(), diameters[i], s.attempts, 100.0 * volume / box.volume(),
                                     100.0 * s.volumeFraction),
                         volume / box.volume());
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
