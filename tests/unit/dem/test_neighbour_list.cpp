// The sphere-pair neighbour list (linked cells of edge 2 r_max + skin, Verlet skin, rebuilt when a body
// moved half the skin) against brute force over every pair (issue 28), on random polydisperse packings:
// right after the build the candidates are exactly the pairs within r_a + r_b + skin; after hundreds of
// steps of random motion, through rebuilds, every pair that touches at the last force pass was a
// candidate.
#include <random>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "dem/contact_law.hpp"
#include "dem/contact_queries.hpp"
#include "dem/simulation.hpp"

using dem::Vec3;

namespace {

std::int64_t bruteForcePairs(const std::vector<Vec3>& x, const std::vector<double>& r, double extra) {
  std::int64_t n = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j) {
      const double reach = r[i] + r[j] + extra;
      n += (x[i] - x[j]).squaredNorm() < reach * reach;
    }
  return n;
}

}  // namespace

TEST(DemNeighbourList, CandidatesAndContactsMatchBruteForce) {
  for (unsigned seed : {1u, 2u, 3u}) {
    dem::Simulation sim;
    const dem::Material soft{"soft", 2500, 1e6, 0.3};
    const auto m = sim.interactions().addMaterial(soft);
    const auto law = common::Config::parse("{law: hertz_mindlin, restitution: 0.5, friction: 0.3}", "test.yaml");
    sim.interactions().set(m, m, dem::makeContactLaw("hertz_mindlin", law, soft, soft));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> box(0.0, 0.03), radius(0.5e-3, 1.5e-3), speed(-0.2, 0.2);
    for (int i = 0; i < 1500; ++i)
      addSphere(sim, Vec3(box(rng), box(rng), box(rng)), radius(rng), m, Vec3(speed(rng), speed(rng), speed(rng)),
                    Vec3::Zero(), false);
    sim.settings().dt = 2e-6;
    sim.settings().gravity = Vec3::Zero();
    sim.initialize();
    const double skin = sim.settings().skin;
    ASSERT_GT(skin, 0.0);
    const std::vector<double> r = sim.spheres().radius;
    std::vector<Vec3> before = sim.spheres().position;
    sim.step();
    const std::int64_t candidates = bruteForcePairs(before, r, skin);
    EXPECT_EQ(contactCounts(sim).pairCandidates, candidates) << "seed " << seed;
    EXPECT_EQ(contactCounts(sim).pairs, bruteForcePairs(before, r, 0.0)) << "seed " << seed;
    ASSERT_GT(candidates, 1000) << "a packing dense enough to test";
    const std::int64_t rebuilds0 = sim.profile().neighbourRebuilds;
    for (int k = 0; k < 600; ++k) sim.step();
    before = sim.spheres().position;
    sim.step();
    EXPECT_GT(sim.profile().neighbourRebuilds, rebuilds0 + 2) << "the motion crossed the skin: the list was rebuilt";
    EXPECT_EQ(contactCounts(sim).pairs, bruteForcePairs(before, r, 0.0)) << "seed " << seed;
  }
}
