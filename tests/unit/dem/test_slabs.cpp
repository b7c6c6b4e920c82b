// How a run on several ranks cuts space (dem_solver/src/slabs.hpp): equal counts per slab, and the ranks
// that need a sphere as a ghost.
#include <gtest/gtest.h>

#include <vector>

#include "slabs.hpp"

using dem::Slabs;

// 1,000 centres spread evenly over [0, 1] in 100 bins: four slabs cut at 0.25, 0.5, 0.75 exactly.
TEST(Slabs, EvenCountsCutAtTheQuarters) {
  const Slabs s = Slabs::fromHistogram(2, 0.0, 1.0, std::vector<double>(100, 10.0), 4);
  ASSERT_EQ(s.ranks(), 4);
  EXPECT_EQ(s.axis, 2);
  EXPECT_NEAR(s.cuts[0], 0.25, 1e-12);
  EXPECT_NEAR(s.cuts[1], 0.50, 1e-12);
  EXPECT_NEAR(s.cuts[2], 0.75, 1e-12);
  EXPECT_EQ(s.owner(0.1), 0);
  EXPECT_EQ(s.owner(0.25), 1);  // on a cut: the upper slab
  EXPECT_EQ(s.owner(-5.0), 0);  // beyond the ends: the end slabs
  EXPECT_EQ(s.owner(7.0), 3);
}

// Most centres at one end (a settled bed under its pour): the cut follows the count, not the extent.
// 900 centres in the first tenth, 100 spread over the rest: half of all, 500, lies at 5/9 of the first
// tenth.
TEST(Slabs, UnevenCountsCutAtTheMedian) {
  std::vector<double> counts(10, 100.0 / 9.0);
  counts[0] = 900.0;
  const Slabs s = Slabs::fromHistogram(0, 0.0, 1.0, counts, 2);
  ASSERT_EQ(s.cuts.size(), 1u);
  EXPECT_NEAR(s.cuts[0], 0.1 * 500.0 / 900.0, 1e-12);
}

// A sphere is a ghost of every other slab within the width, also of a slab beyond a thinner one.
TEST(Slabs, GhostsGoToEverySlabWithinTheWidth) {
  Slabs s;
  s.cuts = {1.0, 1.1, 3.0};
  std::vector<int> to;
  s.near(0.95, 0.2, 0, [&](int r) { to.push_back(r); });
  EXPECT_EQ(to, (std::vector<int>{1, 2}));  // 1.15 reaches into slab 2, past slab 1 of width 0.1
  to.clear();
  s.near(2.0, 0.2, 2, [&](int r) { to.push_back(r); });
  EXPECT_TRUE(to.empty());  // deep inside its own slab
}
