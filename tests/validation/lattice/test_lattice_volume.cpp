// Lattice specimens from closed gmsh volumes (configs/lattice/cylinder_tension.yaml,
// notched_prism_tension.yaml; docs/validation/lattice.md "Specimens from gmsh volumes").
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "h5_read.hpp"
#include "scene_run.hpp"

using testsupport::runScene;

namespace {

testsupport::SceneRun run(const std::string& scene, std::vector<std::string> sets) {
  return runScene("lattice_solver", scene, sets, {"--threads", "1"});
}

}  // namespace

// Young's modulus of the homogeneous cylinder Ø 5 × 10 cm against a 5 × 5 × 10 cm box prism of the same
// rod length, law and seed (free lateral faces: uniaxial stress). Measured (seed 1): the cylinder is
// stiffer by +7.4 % at l = 5 mm, +5.8 % at 3.5 mm, +4.0 % at 2.5 mm — a skin effect of the curved
// mantle that shrinks about ∝ l/R (R = 25 mm), while a box read as a gmsh volume matches the box
// generator within 1 % (22.55 vs 22.82 GPa at 5 mm). The test asserts that: 0 < ΔE/E < 9 % at 5 mm, and
// at 3 mm below 6.5 % and below 0.85 × the 5 mm difference (docs/validation/lattice.md).
TEST(VolumeSpecimen, CylinderModulusApproachesTheBoxWithRefinement) {
  double previous = 0.0;
  for (const char* l : {"0.005", "0.003"}) {
    const std::vector<std::string> common{std::string("specimen.rod_length=") + l, "loading.lateral=free", "loading.max_strain=1e-5",
                                          "loading.strain_increment=1e-5", "specimen.seed=1"};
    const auto box = run("configs/lattice/elastic_random.yaml", [&] {
      auto s = common;
      s.push_back("specimen.size=[0.05,0.05,0.1]");
      return s;
    }());
    ASSERT_EQ(box.exitCode, 0) << box.output;
    const auto cyl = run(testsupport::writeScene("cylinder.yaml", "specimen:\n  geometry: {file: " +
                                                                      testsupport::sourcePath("configs/lattice/cylinder.geo").string() +
                                                                      "}\n  rod_length: 0.005\nrod: {young_modulus: 3.0e10}\n"
                                                                      "loading: {axis: z, strain_increment: 1.0e-5, max_strain: 1.0e-5}\n")
                             .string(),
                         common);
    ASSERT_EQ(cyl.exitCode, 0) << cyl.output;
    const double diff = cyl.result("youngs_modulus") / box.result("youngs_modulus") - 1.0;
    if (previous == 0.0) {
      EXPECT_GT(diff, 0.0);
      EXPECT_LT(diff, 0.09);
    } else {
      EXPECT_LT(diff, 0.065);
      EXPECT_LT(diff, 0.85 * previous);
    }
    previous = diff;
    // The end-face area is the mesh polygon's, within 0.2 % of πr².
    EXPECT_NEAR(cyl.result("loaded_area"), M_PI * 0.025 * 0.025, 2e-3 * M_PI * 0.025 * 0.025);
  }
}

// The notched prism in tension: the first rods to break lie at the notch tip (within 2 rod lengths of the
// tip edge x ∈ [48.5, 51.5] mm, z = 10 mm), and the crack band is the notch's plane x = 50 mm.
TEST(VolumeSpecimen, NotchedPrismCrackStartsAtTheNotch) {
  const double l = 0.006;
  const auto r = run("configs/lattice/notched_prism_tension.yaml",
                     {"specimen.rod_length=0.006", "loading.strain_increment=5e-6", "loading.max_strain=1.6e-4"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_GT(r.result("rods_removed"), 10);
  EXPECT_NEAR(r.result("crack_plane"), 0.05, 2 * l);
  const auto h5 = r.outDir / "lattice.h5";
  const auto nodes = testsupport::readH5(h5, "/meshes/cracks/nodes");
  const auto cells = testsupport::readH5(h5, "/meshes/cracks/cells");
  const auto inc = testsupport::readH5(h5, "/meshes/cracks/steps/000000/cell/increment");
  ASSERT_EQ(cells.size(), 2 * inc.size());
  const double first = *std::min_element(inc.begin(), inc.end());
  int firstRods = 0;
  for (std::size_t c = 0; c < inc.size(); ++c) {
    if (inc[c] != first) continue;
    ++firstRods;
    double m[3];
    for (int k = 0; k < 3; ++k)
      m[k] = 0.5 * (nodes[3 * static_cast<std::size_t>(cells[2 * c]) + k] + nodes[3 * static_cast<std::size_t>(cells[2 * c + 1]) + k]);
    const double dx = std::max({0.0485 - m[0], 0.0, m[0] - 0.0515});
    EXPECT_LT(std::hypot(dx, m[2] - 0.01), 2 * l) << "rod at (" << m[0] << ", " << m[1] << ", " << m[2] << ")";
  }
  EXPECT_GT(firstRods, 0);
}
