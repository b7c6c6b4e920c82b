// configs/dem/bonded_block.yaml (issue 27): the rockfall block as 6³ bonded spheres dropped on a rigid
// floor at 6.26 m/s. Strong bonds keep it whole; weak ones break at every layer (the reflected
// compression wave pulls the layers apart), the bonded mass falls into its six layers and the breaking
// takes energy; the ledger closes either way.
#include <gtest/gtest.h>

#include "scene_run.hpp"

using testsupport::runScene;

TEST(BondedBlock, StrongBondsKeepItWhole) {
  const auto r = runScene("dem_solver", "configs/dem/bonded_block.yaml", {"output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.result("bonds_created"), 540);  // 3 · 6 · 6 · 5 lattice neighbours
  EXPECT_EQ(r.result("broken_bonds"), 0);
  EXPECT_EQ(r.result("fragments"), 1);
  EXPECT_EQ(r.result("bond_fracture_energy"), 0.0);
  EXPECT_LT(r.result("energy_balance_error"), 0.01);
}

TEST(BondedBlock, WeakBondsBreakItIntoItsLayers) {
  const auto r = runScene("dem_solver", "configs/dem/bonded_block.yaml",
                          {"output.interval=0", "interactions[0].tensile_strength=1e4", "interactions[0].cohesion=1e4"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.result("broken_bonds"), 180);  // every vertical bond: 5 interfaces of 36
  EXPECT_EQ(r.result("fragments"), 6);
  EXPECT_NEAR(r.result("largest_fragment_mass_fraction"), 1.0 / 6.0, 1e-12);
  EXPECT_GT(r.result("bond_fracture_energy"), 0.0);
  EXPECT_LT(r.result("energy_balance_error"), 0.01);
}

TEST(BondedBlock, OverlappingMembersAreALocatedError) {
  // The rigid rockfall clusters overlap their spheres (their union has the cube's volume): not bondable.
  const auto r = runScene("dem_solver", "configs/dem/bonded_block.yaml",
                          {"clusters[0].cube=null",
                           "clusters[0].file=" + testsupport::sourcePath("configs/dem/clusters/cube_c3.yaml").string()},
                          {"--check"});
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("clusters[0]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("must not overlap"), std::string::npos) << r.output;
}
