// configs/dem/incline.yaml: rolling without slip and sliding with friction on a 20° incline.
#include <cmath>

#include <gtest/gtest.h>

#include "scene_run.hpp"

using testsupport::runScene;

namespace {
const double kSin = std::sin(20 * 3.14159265358979 / 180), kCos = std::cos(20 * 3.14159265358979 / 180);
}

// tan 20° = 0.364 < 3.5 μ = 1.05: rolls, a = 5/7 g sin θ (1 %, issue 3).
TEST(Incline, RollsWithoutSlipBelowTheLimit) {
  const auto r = runScene("dem_solver", "configs/dem/incline.yaml", {"output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const double a = 5.0 / 7.0 * 9.81 * kSin;
  EXPECT_NEAR(r.result("acceleration"), a, 0.01 * a);
  EXPECT_NEAR(r.result("rolling_ratio"), 1.0, 0.01);
}

// μ = 0.05: 3.5 μ = 0.175 < tan θ, slides, a = g (sin θ − μ cos θ); it spins up at a rate 5 μ g cos θ / (2R),
// slower than it slides, so |ω| R / |v| < 1.
TEST(Incline, SlidesWithFrictionAboveTheLimit) {
  const auto r = runScene("dem_solver", "configs/dem/incline.yaml", {"interactions[0].friction=0.05", "output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const double a = 9.81 * (kSin - 0.05 * kCos);
  EXPECT_NEAR(r.result("acceleration"), a, 0.01 * a);
  EXPECT_LT(r.result("rolling_ratio"), 0.9);
  EXPECT_LT(r.result("energy_balance_error"), 1e-2);
}
