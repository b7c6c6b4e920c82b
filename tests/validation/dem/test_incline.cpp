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

// Rolling resistance μ_r = 0.1 (constant directional torque μ_r R F_n, capped so a ball stops):
// rolling down the incline, a = 5/7 g (sin θ − μ_r cos θ) (1 %), its dissipation booked as friction.
TEST(Incline, RollingResistanceSlowsTheRoll) {
  const auto r = runScene("dem_solver", "configs/dem/incline.yaml", {"interactions[0].rolling_friction=0.1", "output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const double a = 5.0 / 7.0 * 9.81 * (kSin - 0.1 * kCos);
  EXPECT_NEAR(r.result("acceleration"), a, 0.01 * a);
  EXPECT_NEAR(r.result("rolling_ratio"), 1.0, 0.01);
  EXPECT_LT(r.result("energy_balance_error"), 1e-3);
}

namespace {
// A ball rolling at 1 m/s (ω = v/R) on level ground: a plane, or a jittered triangle mesh.
std::vector<std::string> levelRoll(const std::string& floor, double endTime) {
  return {"interactions[0].rolling_friction=0.1", "output.interval=0", "walls[0]=" + floor,
          "spheres[0].position=[0, 0, 0.05]", "spheres[0].velocity=[1, 0, 0]", "spheres[0].angular_velocity=[0, 20, 0]",
          "end_time=" + std::to_string(endTime), "probe={type: acceleration, body: 0, direction: [-1, 0, 0], from: 0.1}"};
}
const std::string kPlane = "{type: plane, name: floor, material: rock, point: [0, 0, 0], normal: [0, 0, 1]}";
const std::string kMesh =
    "{type: mesh, name: floor, material: rock, grid: {origin: [-0.5, -0.5, 0], size: [3.0, 2.0], divisions: [30, 20], "
    "pattern: random, jitter: 0.3, seed: 7}}";
}  // namespace

// On level ground the ball decelerates at 5/7 μ_r g whatever the floor is made of (1 %) ...
TEST(Incline, RollingResistanceOnLevelGroundPlaneAndMesh) {
  const double a = 5.0 / 7.0 * 0.1 * 9.81;
  for (const auto& floor : {kPlane, kMesh}) {
    const auto r = runScene("dem_solver", "configs/dem/incline.yaml", levelRoll(floor, 1.0));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NEAR(r.result("acceleration"), a, 0.01 * a) << floor;
  }
}

// ... and comes to rest at t = v / (5/7 μ_r g) = 1.46 s instead of rocking about zero spin.
TEST(Incline, RollingResistanceBringsTheBallToRest) {
  const auto r = runScene("dem_solver", "configs/dem/incline.yaml", levelRoll(kPlane, 2.0));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto v = r.summary["results"]["velocity_final"].as<std::vector<double>>();
  EXPECT_LT(std::hypot(v[0], v[1]), 1e-9);
  EXPECT_LT(r.result("spin_final"), 1e-9);
}
