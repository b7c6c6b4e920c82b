// Specimen generation: sieve curves, random nodes with a hard core, Delaunay rods, aggregates and the
// phase of every rod.
#include <cmath>
#include <numbers>
#include <set>

#include <gtest/gtest.h>

#include "lattice/specimen.hpp"

using namespace lattice;

TEST(SieveCurve, FullerPassingAndSampledVolume) {
  const auto c = SieveCurve::fuller(0.004, 0.016);
  // Normalised Fuller: (√(d/16) − √(4/16)) / (1 − √(4/16)) at d = 9 mm: (0.75 − 0.5)/0.5 = 0.5.
  EXPECT_NEAR(c.passing(0.009), 0.5, 0.01);  // geometric classes interpolate linearly in between
  EXPECT_EQ(c.passing(0.003), 0.0);
  EXPECT_EQ(c.passing(0.02), 1.0);
  std::mt19937_64 rng(7);
  const double volume = 1e-5;
  const auto d = c.sample(volume, rng);
  double v = 0.0;
  for (double x : d) v += std::numbers::pi / 6 * x * x * x;
  // The carry rule keeps the total within half of the smallest sphere.
  EXPECT_NEAR(v, volume, 0.5 * std::numbers::pi / 6 * std::pow(0.004, 3) + 1e-12);
  EXPECT_TRUE(std::is_sorted(d.begin(), d.end(), std::greater<>()));
  EXPECT_GE(d.back(), 0.004);
  EXPECT_LE(d.front(), 0.016);
}

TEST(SieveCurve, TableRejectsANonMonotoneCurve) {
  EXPECT_NO_THROW(SieveCurve::table({0.002, 0.004, 0.008}, {0.0, 0.4, 1.0}));
  try {
    SieveCurve::table({0.002, 0.004, 0.008}, {0.0, 0.6, 0.5});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "row 2: passing 0.5 is below the previous row's 0.6; a sieve curve never decreases");
  }
}

TEST(RandomSpecimen, HardCoreFacesAndMeanRodLength) {
  const Box box{Vec3::Zero(), Vec3(0.02, 0.03, 0.025)};
  const Specimen sp = randomSpecimen(box, 0.003, 0.5, 11);
  // The count is calibrated so the mean Delaunay rod is the one asked for, within 3 %.
  EXPECT_NEAR(sp.meanRodLength(), 0.003, 0.03 * 0.003);
  // Hard core: no two nodes closer than 0.5 spacing; spacing ≈ rod length / 1.2 or more.
  double closest = 1.0;
  for (const auto& [a, b] : sp.rods) closest = std::min(closest, (sp.nodes[a] - sp.nodes[b]).norm());
  EXPECT_GT(closest, 0.5 * 0.003 / 1.4);
  // Every node lies in the box and every one of the six faces carries nodes.
  int onFace[6] = {};
  for (const auto& p : sp.nodes) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(p[k], -1e-15);
      EXPECT_LE(p[k], box.size[k] + 1e-15);
      onFace[2 * k] += p[k] == 0.0;
      onFace[2 * k + 1] += p[k] == box.size[k];
    }
  }
  for (int f = 0; f < 6; ++f) EXPECT_GT(onFace[f], 10) << "face " << f;
  // Rods are unique and every node has one (gmsh tetrahedralises every point).
  std::set<std::pair<std::uint32_t, std::uint32_t>> unique;
  std::vector<int> degree(sp.nodes.size(), 0);
  for (const auto& [a, b] : sp.rods) {
    EXPECT_LT(a, b);
    unique.insert({a, b});
    ++degree[a];
    ++degree[b];
  }
  EXPECT_EQ(unique.size(), sp.rods.size());
  EXPECT_GE(*std::min_element(degree.begin(), degree.end()), 3);
  // A Delaunay tetrahedralisation of random points has ≈ 7.7 edges per point far from the hull.
  const double perNode = static_cast<double>(sp.rods.size()) / static_cast<double>(sp.nodes.size());
  EXPECT_GT(perNode, 6.0);
  EXPECT_LT(perNode, 7.8);
}

TEST(RandomSpecimen, SameSeedSameSpecimen) {
  const Box box{Vec3::Zero(), Vec3::Constant(0.015)};
  const Specimen a = randomSpecimen(box, 0.003, 0.5, 4), b = randomSpecimen(box, 0.003, 0.5, 4),
                 c = randomSpecimen(box, 0.003, 0.5, 5);
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  for (std::size_t i = 0; i < a.nodes.size(); ++i) EXPECT_EQ(a.nodes[i], b.nodes[i]);
  EXPECT_EQ(a.rods, b.rods);
  EXPECT_NE(a.nodes[20], c.nodes[20]);
}

TEST(RandomSpecimen, RodLongerThanTheSpecimenIsRejected) {
  EXPECT_THROW(randomSpecimen({Vec3::Zero(), Vec3::Constant(0.01)}, 0.012, 0.5, 1), std::invalid_argument);
}

TEST(CubicLattice, CountsAndSpacing) {
  const Specimen sp = cubicLattice({Vec3::Zero(), Vec3(0.03, 0.03, 0.06)}, 0.01);
  EXPECT_EQ(sp.nodes.size(), 4u * 4u * 7u);
  EXPECT_EQ(sp.rods.size(), 3u * 4u * 7u + 4u * 3u * 7u + 4u * 4u * 6u);
  EXPECT_NEAR(sp.meanRodLength(), 0.01, 1e-15);
}

TEST(Aggregates, NoOverlapInsideTheBoxAtTheAskedFraction) {
  const Box box{Vec3::Zero(), Vec3::Constant(0.05)};
  AggregateSettings s;
  s.volumeFraction = 0.4;
  s.gap = 2e-4;
  s.seed = 9;
  const auto ag = placeAggregates(box, SieveCurve::fuller(0.004, 0.012), s);
  double v = 0.0;
  for (std::size_t i = 0; i < ag.size(); ++i) {
    v += 4.0 / 3.0 * std::numbers::pi * std::pow(ag[i].radius, 3);
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(ag[i].center[k] - ag[i].radius, -1e-15);
      EXPECT_LE(ag[i].center[k] + ag[i].radius, 0.05 + 1e-15);
    }
    for (std::size_t j = 0; j < i; ++j)
      EXPECT_GE((ag[i].center - ag[j].center).norm(), ag[i].radius + ag[j].radius + s.gap - 1e-15);
  }
  EXPECT_NEAR(v / box.volume(), 0.4, 0.005);
}

TEST(Aggregates, AFractionThatCannotBePackedNamesTheAggregate) {
  AggregateSettings s;
  s.volumeFraction = 0.6;
  s.attempts = 2000;
  try {
    placeAggregates({Vec3::Zero(), Vec3::Constant(0.05)}, SieveCurve::fuller(0.008, 0.012), s);
    FAIL() << "no exception";
  } catch (const PackingError& e) {
    EXPECT_LT(e.packedFraction, 0.6);
    EXPECT_NE(std::string(e.what()).find("found no free place in 2000 random positions"), std::string::npos) << e.what();
  }
}

TEST(Aggregates, RodPhasesFollowTheirEnds) {
  Specimen sp = cubicLattice({Vec3::Zero(), Vec3::Constant(0.04)}, 0.01);
  sp.aggregates = {{Vec3(0.02, 0.02, 0.02), 0.011}, {Vec3(0.0, 0.0, 0.0), 0.001}};
  classifyRods(sp);
  int counts[3] = {};
  for (std::size_t r = 0; r < sp.rods.size(); ++r) {
    const auto [a, b] = sp.rods[r];
    const bool ia = (sp.nodes[a] - Vec3::Constant(0.02)).norm() < 0.011 || sp.nodes[a].norm() < 0.001;
    const bool ib = (sp.nodes[b] - Vec3::Constant(0.02)).norm() < 0.011 || sp.nodes[b].norm() < 0.001;
    // Both aggregates here are far apart: two ends inside means the same aggregate.
    const Phase want = ia && ib ? Phase::kAggregate : ia || ib ? Phase::kInterface : Phase::kMatrix;
    EXPECT_EQ(sp.phases[r], want) << r;
    ++counts[static_cast<int>(sp.phases[r])];
  }
  // The centre node and its 6 neighbours at 1 cm are inside the big aggregate: 6 aggregate rods; the
  // 5 rods from each of those 6 nodes outwards are interface rods; the corner node's 3 rods too.
  EXPECT_EQ(counts[1], 6);
  EXPECT_EQ(counts[2], 6 * 5 + 3);
}
