// configs/dem/cluster_drop.yaml: the 180 kg cube cluster hitting a rigid floor.
#include <gtest/gtest.h>

#include "scene_run.hpp"

using testsupport::runScene;

// Flat face down, the symmetric cluster must not start rotating nor drift sideways.
TEST(ClusterDrop, FlatImpactDoesNotRotate) {
  const auto r = runScene("dem_solver", "configs/dem/cluster_drop.yaml", {"output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_LT(r.result("spin_final"), 1e-9);
  const auto v = r.summary["results"]["velocity_final"].as<std::vector<double>>();
  EXPECT_LT(std::hypot(v[0], v[1]), 1e-9);
  EXPECT_GT(v[2], 0.0);  // it bounced
  EXPECT_LT(r.result("energy_balance_error"), 0.02);
}

// On a 10° floor the impact is eccentric: the block leaves spinning and moving downhill (+x).
TEST(ClusterDrop, TiltedImpactRotates) {
  const auto r = runScene("dem_solver", "configs/dem/cluster_drop.yaml",
                          {"walls[0].normal=[0.173648178,0,0.984807753]", "output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_GT(r.result("spin_final"), 1.0);
  EXPECT_GT(r.summary["results"]["velocity_final"][0].as<double>(), 0.5);
  EXPECT_LT(r.result("energy_balance_error"), 0.02);
}

// Free flight with spin: the total angular momentum is conserved to 1e-10 relative (issue 3).
TEST(ClusterDrop, FreeFlightConservesAngularMomentum) {
  const auto r = runScene("dem_solver", "configs/dem/cluster_drop.yaml",
                          {"walls=[]", "gravity=[0,0,0]", "clusters[0].angular_velocity=[2,-1,3]",
                           "clusters[0].mass_properties=spheres", "output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_LT(r.result("angular_momentum_drift"), 1e-10);
  EXPECT_NEAR(r.result("spin_final"), std::sqrt(14.0), 1e-9 * std::sqrt(14.0));
  EXPECT_LT(r.result("energy_balance_error"), 1e-10);
}

// The irregular rock (configs/dem/clusters/rock.yaml, 301 spheres filling a gmsh surface) dropped tilted:
// it runs, bounces and the ledger closes.
TEST(ClusterDrop, IrregularRockFromAGmshSurface) {
  const auto r = runScene("dem_solver", "configs/dem/cluster_drop.yaml",
                          {"clusters[0].file=" + testsupport::sourcePath("configs/dem/clusters/rock.yaml").string(), "clusters[0].position=[0, 0, 0.35]",
                           "clusters[0].orientation=[0.9, 0.3, 0.2, 0.1]", "output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.summary["results"]["spheres"].as<int>(), 301);
  EXPECT_GT(r.result("spin_final"), 0.5);  // an eccentric impact spins it
  EXPECT_LT(r.result("energy_balance_error"), 0.02);
}
