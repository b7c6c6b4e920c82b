// configs/dem/triaxial.yaml, small: a dense, bonded sample consolidated to σ3 by servo walls
// and compressed axially. Soil mechanics says what must happen (compression positive): the deviatoric
// stress rises to a peak of a few σ3 and softens after it while bonds break; a dense sample first
// contracts a little, then dilates past its initial volume. The servo holds the walls at σ3 within 1 %
// at the end of the consolidation; the energy ledger closes.
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "common/h5_writer.hpp"

#include "scene_run.hpp"

using testsupport::runScene;

TEST(Triaxial, DenseBondedSampleRisesPeaksSoftensAndDilates) {
  // 800 spheres on one thread: 9 s. (500 are too few: a single bond breaking moves q by 10 %.)
  const auto r = runScene("dem_solver", "configs/dem/triaxial.yaml",
                          {"specimen.count=800", "triaxial.axial_strain_end=0.06", "triaxial.snapshot_strain=0.03"}, {},
                          {"OMP_NUM_THREADS=1"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const double peak = r.result("peak_deviatoric_stress");
  EXPECT_GT(peak, 2.0e5) << "a bonded dense sample at 100 kPa peaks at q above 2 σ3 (measured 2.4 σ3)";
  EXPECT_LT(r.result("axial_strain_at_peak"), r.result("final_axial_strain") - 0.01) << "a peak, not the end";
  EXPECT_LT(r.result("final_deviatoric_stress"), 0.95 * peak) << "softening after the peak";
  // Dilatancy (compression positive): a dense sample contracts first, then dilates past its initial volume.
  EXPECT_GT(r.result("max_compaction_volumetric_strain"), 0.0) << "contracts first";
  EXPECT_LT(r.result("final_volumetric_strain"), 0.0) << "dense: dilates past its initial volume";
  EXPECT_GT(r.result("broken_bonds"), 0.0);
  EXPECT_LE(r.result("broken_bonds"), r.result("bonds_created"));
  EXPECT_GT(r.result("bond_fracture_energy"), 0.0);
  EXPECT_LT(r.result("inertial_number"), 1e-3);
  EXPECT_LT(r.result("energy_balance_error"), 0.005);
  // The side walls hold σ3 while the sample is compressed (a drained test): measured 3.4 %.
  EXPECT_LT(r.result("lateral_stress_error_max"), 0.05);

  // Small-strain modulus against the affine (Voigt) effective-medium estimate for linear springs
  // (Walton 1987; docs/validation/triaxial.md): E_affine = 0.2157 P k_n with P k_n = 3 φ Z E_g / (2π) for
  // k_s = 0.25 k_n. The affine estimate is an upper bound for a packing whose grains relax non-affinely;
  // Makse et al. 1999 find 0.5–0.8 of it near jamming, and the 4,000-sphere samples measured 0.61–0.85
  // (this one 0.61 at Z = 3.9).
  const double phi = 1.0 - r.result("porosity_consolidated"), z = r.result("coordination_consolidated");
  const double affine = 0.2157 * 3.0 * phi * z * 1.0e8 / (2.0 * M_PI);
  const double ratio = r.result("secant_modulus_0_05_percent") / affine;
  EXPECT_GT(ratio, 0.5) << ratio;
  EXPECT_LT(ratio, 1.0) << ratio;
  EXPECT_TRUE(std::filesystem::exists(r.outDir / "peak.xdmf"));
}

TEST(Triaxial, MatchesYadeOnTheSameSample) {
  // The same 800 spheres, bonds and loading in YADE 2023.02a (tests/bench/triaxial_vs_yade.sh build 800
  // 0.06 1: YADE starts from this run's consolidated spheres and bonds the same 1,548 pairs, rigid
  // platens of contact stiffness 2 E r on both sides, ours through the platen pair's modulus at E/2).
  // YADE measured: peak q 210.2 kPa (at ε1 = 1.81 %), at ε1 = 6 %: ε_v = −3.374 %, 496 bonds broken.
  // Ours: 217.0 kPa, −3.401 %, 506. Both curves rise alike to a first peak near 1.9 % (ours 208 kPa),
  // then hold a plateau from 2 % on that wanders by ±9 % (ours 181–217 kPa, YADE's 172–208): the largest
  // q of the run may fall anywhere on it (ours at 4.8 %), and another floating-point order (a sanitizer
  // build) moves it, hence ±10 % on the peak. The dilatancy and the bonds broken by 6 % are sums over the
  // whole sample and agree within 1 % and 2 %, held to 5 %.
  const auto r = runScene("dem_solver", "configs/dem/triaxial.yaml",
                          {"specimen.count=800", "triaxial.axial_strain_end=0.06", "triaxial.snapshot_strain=0.03",
                           "interactions[1].young_modulus=5.0e7"},
                          {}, {"OMP_NUM_THREADS=1"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_EQ(r.result("confining_pressure"), 1.0e5);
  // The pairs it bonded, which the peer bonds: one row (a, b) per bond, a < b, each a sphere of the sample.
  const auto pairs = common::readH5Array(r.outDir / "dem.h5", "/triaxial/bonds");
  const auto spheres = common::readH5Array(r.outDir / "dem.h5", "/triaxial/consolidated_spheres");
  ASSERT_EQ(pairs.size(), 2 * static_cast<std::size_t>(r.result("bonds_created")));
  for (std::size_t i = 0; i < pairs.size(); i += 2) {
    ASSERT_LT(pairs[i], pairs[i + 1]);
    ASSERT_LT(pairs[i + 1], static_cast<double>(spheres.size() / 4));
  }
  EXPECT_NEAR(r.result("peak_deviatoric_stress") / 210.2e3, 1.0, 0.10);
  EXPECT_NEAR(r.result("final_volumetric_strain") / -0.03374, 1.0, 0.05);
  EXPECT_NEAR(r.result("broken_bonds") / 496.0, 1.0, 0.05);
}

TEST(Triaxial, BadInputIsALocatedError) {
  auto check = [](const std::vector<std::string>& sets, const std::string& where) {
    const auto r = runScene("dem_solver", "configs/dem/triaxial.yaml", sets, {"--check"});
    EXPECT_EQ(r.exitCode, 2) << r.output;
    EXPECT_NE(r.output.find(where), std::string::npos) << r.output;
  };
  check({"interactions[0].tensile_strength=-1"}, "interactions[0].tensile_strength");
  check({"specimen.porosity=0.9"}, "specimen.porosity");
  check({"interactions[0].interaction_radius=0.5"}, "interactions[0].interaction_radius");
  check({"triaxial.confining_pressure=0"}, "triaxial.confining_pressure");
  check({"specimen.sieve=[[1e-3, 0.2], [2e-3, 1]]"}, "specimen");
}
