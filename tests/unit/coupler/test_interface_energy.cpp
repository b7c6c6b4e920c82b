// InterfaceEnergy: the work of the interface forces on both sides of a force/displacement exchange pair.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "interface_energy.hpp"

namespace {

// A mass m on a spring k (side B) pushed by a constant force F from side A: consistent data (A is fed
// the displacement B has now) gives equal work on both sides, F·u; a one-window lag (A fed B's previous
// displacement, as a weak serial scheme does) is short by F·(u_n − u_{n−1}) at every window.
struct Works {
  double workA, workB;
};

Works run(bool lagged) {
  cosim::InterfaceEnergy e;
  const double F = 2.0;
  std::vector<double> u{0.0}, previous{0.0};
  for (int n = 0; n <= 100; ++n) {
    const double un = 1e-3 * n * n;  // B's displacement at the end of window n (any history will do)
    const std::vector<double> uB{un}, f{F};
    const std::vector<double> uA = lagged ? previous : uB;
    e.window(f, uA, f, uB);
    previous = uB;
  }
  return {e.workA(), e.workB()};
}

}  // namespace

TEST(InterfaceEnergy, ConsistentDataDoesEqualWorkOnBothSides) {
  const Works r = run(false);
  EXPECT_DOUBLE_EQ(r.workB, 2.0 * 1e-3 * 100 * 100);  // F (u_100 − u_0)
  EXPECT_DOUBLE_EQ(r.workA, r.workB);
}

TEST(InterfaceEnergy, AOneWindowLagIsEnergyTheCouplingCreates) {
  const Works r = run(true);
  EXPECT_DOUBLE_EQ(r.workB, 20.0);
  EXPECT_NEAR(r.workA, 2.0 * 1e-3 * 99 * 99, 1e-12);  // A saw the wall only up to u_99
  cosim::InterfaceEnergy e;
  e.window(std::vector<double>{1.0}, std::vector<double>{0.0}, std::vector<double>{1.0}, std::vector<double>{0.0});
  e.window(std::vector<double>{1.0}, std::vector<double>{0.0}, std::vector<double>{1.0}, std::vector<double>{0.5});
  EXPECT_DOUBLE_EQ(e.mismatch(), 0.5);  // B moved 0.5 under the force, A saw no motion
  EXPECT_DOUBLE_EQ(e.scale(), 0.5);
}
