// The lattice–FEM prism of configs/verification/lattice_prism.yaml (issue 7 item 6) through cosim: three
// processes (two fem_solver tet4 ends, one lattice_solver middle) coupled Dirichlet–Neumann on the two
// lattice faces. The elastic test runs the scene's lattice (4 mm rods); the fracture test a coarser one
// (8 mm) to stay fast. Full-run numbers: docs/validation/lattice.md.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "h5_read.hpp"
#include "scene_run.hpp"

using testsupport::runScene;

namespace {

const std::string kScene = "configs/verification/lattice_prism.yaml";
const std::string kLatticeScene = "configs/verification/lattice_prism_lattice.yaml";

// From the scene files: the FEM ends (E = 30 GPa, ν = 0, 5 cm long), the lattice zone (5 cm), the
// section 5 × 5 cm, and the end displacement 45 µm reached at t = ramp_time = 60 s.
constexpr double kFemModulus = 3.0e10, kFemLength = 0.05, kLatticeLength = 0.05, kArea = 0.05 * 0.05;
constexpr double kEndDisplacement = 4.5e-5, kRampTime = 60.0;

}  // namespace

// Elastic range: the coupled stiffness (end force / end displacement) against series springs — the two
// FEM ends E A / L (exact for linear tets in uniaxial stress with ν = 0) and the lattice alone, E_lat A / L
// with E_lat from a standalone lattice_solver run of the same specimen between glued plates. The coupled
// faces are not rigid plates (they follow the FEM face, which the random lattice loads unevenly), so the
// match is not exact: measured −0.60 % (docs/validation/lattice.md; −1.3 % with 6 mm rods, fewer lattice
// nodes per FEM face triangle); the issue asks 1 %.
TEST(LatticePrism, ElasticStiffnessMatchesSeriesSprings) {
  const auto alone = runScene("lattice_solver", kLatticeScene, {}, {"--threads", "1"});
  ASSERT_EQ(alone.exitCode, 0) << alone.output;
  const double latticeModulus = alone.result("youngs_modulus");

  const auto coupled = runScene("cosim", kScene, {"coupling.end_time=2"});
  ASSERT_EQ(coupled.exitCode, 0) << coupled.output;
  EXPECT_EQ(coupled.summary["results"]["unconverged_windows"].as<int>(), 0);
  const auto high = YAML::LoadFile((coupled.outDir / "fem_high/summary.yaml").string());
  const double force = high["results"]["reaction_zmax"][2].as<double>();
  const double displacement = kEndDisplacement * 2.0 / kRampTime;
  const double compliance = 2 * kFemLength / (kFemModulus * kArea) + kLatticeLength / (latticeModulus * kArea);
  const double reference = 1.0 / compliance;
  EXPECT_NEAR(force / displacement / reference, 1.0, 0.01)
      << "coupled " << force / displacement << " N/m, series springs " << reference << " N/m";
  const auto lattice = YAML::LoadFile((coupled.outDir / "lattice/summary.yaml").string());
  EXPECT_EQ(lattice["results"]["rods_removed"].as<int>(), 0);
  // The force the lattice writes is the force the FEM end carries (conservative mapping, converged).
  EXPECT_NEAR(-lattice["results"]["force_z_max"][2].as<double>(), force, 1e-5 * force);
}

// Past the peak (coarser: 8 mm rods, 30 windows of 1.5 µm): the end force rises, peaks and softens; the
// macro-crack (rods removed after the peak window) lies in one band of ±2 rod lengths (measured 96 % of
// them; a uniform spread would put about 64 % there); every window converges with Aitken (measured 25
// iterations per window on average; the limit is 100).
TEST(LatticePrism, CrackLocalisesAndTheCurveSoftens) {
  const auto r = runScene("cosim", kScene,
                          {"participants.lattice.command=[lattice_solver, lattice_prism_lattice.yaml, --set, "
                           "specimen.rod_length=0.008]",
                           "participants.fem_high.command=[fem_solver, lattice_prism_fem_high.yaml, --set, static.ramp_time=30]",
                           "coupling.end_time=30"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.summary["results"]["unconverged_windows"].as<int>(), 0);
  EXPECT_LE(r.result("mean_coupling_iterations"), 40.0);

  const auto force = testsupport::readH5(r.outDir / "fem_high/fem.h5", "/timeseries/reactions/zmax_fz");
  ASSERT_EQ(force.size(), 30u);
  const auto peak = std::max_element(force.begin(), force.end());
  EXPECT_GT(peak - force.begin(), 2);    // a rising elastic branch first
  EXPECT_LT(peak - force.begin(), 25);   // the peak is inside the run …
  EXPECT_LT(force.back(), 0.5 * *peak);  // … and followed by softening

  const auto lattice = YAML::LoadFile((r.outDir / "lattice/summary.yaml").string())["results"];
  EXPECT_GT(lattice["rods_removed_post_peak"].as<int>(), 50);
  EXPECT_GT(lattice["crack_band_fraction_post_peak"].as<double>(), 0.85);
  const double plane = lattice["crack_plane_post_peak"].as<double>();
  EXPECT_GT(plane, 0.05);  // inside the lattice zone 0.05 ≤ z ≤ 0.10 m
  EXPECT_LT(plane, 0.10);
  EXPECT_EQ(lattice["late_removals"].as<int>(), 0);
}
