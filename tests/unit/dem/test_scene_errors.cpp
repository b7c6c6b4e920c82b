// Bad input to dem_solver: exit code 2 and a message naming the file, key path and line.
#include <fstream>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "scene_run.hpp"

using testing::HasSubstr;
using testsupport::runScene;
using testsupport::writeScene;

namespace {

const char* kBase = R"(materials:
  rock: {density: 2500, young_modulus: 1.0e8}
  steel: {density: 7800, young_modulus: 2.0e11}
interactions:
  - {materials: [rock, rock], law: hertz_mindlin, restitution: 0.5}
spheres:
  - {material: rock, radius: 0.05, position: [0, 0, 0.1]}
  - {material: rock, radius: 0.05, position: [0.2, 0, 0.1]}
end_time: 0.01
)";

testsupport::SceneRun runBase(const std::vector<std::string>& sets, const std::string& extra = "") {
  return runScene("dem_solver", writeScene("bad.yaml", std::string(kBase) + extra).string(), sets);
}

}  // namespace

TEST(DemBadInput, NegativeRadius) {
  const auto r = runBase({"spheres[1].radius=-0.05"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("spheres[1].radius = -0.05 (--set spheres[1].radius=-0.05): is outside (0, inf)."));
}

TEST(DemBadInput, ZeroRadiusInFileIsLocated) {
  const auto scene = writeScene("bad.yaml", std::string(kBase).replace(std::string(kBase).find("radius: 0.05"), 12, "radius: 0.0"));
  const auto r = runScene("dem_solver", scene.string());
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("spheres[0].radius = 0.0 (" + scene.string() + ":7:30): is outside (0, inf)."));
}

TEST(DemBadInput, MissingMaterialPair) {
  const auto r = runBase({}, "walls:\n  - {type: plane, material: steel, point: [0, 0, 0], normal: [0, 0, 1]}\n");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("walls[0] ("));
  EXPECT_THAT(r.status(), HasSubstr(":11:5): no interaction is defined for the material pair (rock, steel); add it "
                                    "under interactions."));
}

TEST(DemBadInput, UnknownMaterialName) {
  const auto r = runBase({"spheres[0].material=rok"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("spheres[0].material = rok (--set spheres[0].material=rok): unknown name; expected "
                                    "one of: rock, steel. Did you mean \"rock\"?"));
}

TEST(DemBadInput, DtAboveCriticalGivesBothNumbers) {
  const auto r = runBase({"dt=0.01"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("dt = 0.01 (--set dt=0.01): is above the safe step 0.0006768 s: dt_safety 0.5 × "
                                    "the critical step 0.001354 s (Rayleigh, smallest sphere, stiffest law)."));
  // The scene may ask for a warning instead.
  const auto warned = runBase({"dt=0.001", "dt_check=warn"});
  EXPECT_EQ(warned.exitCode, 0) << warned.output;
  EXPECT_THAT(warned.output, HasSubstr("is above the safe step"));
}

TEST(DemBadInput, OverlappingSpheresAtStart) {
  const auto r = runBase({"spheres[1].position=[0.05, 0, 0.1]"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("spheres[1] ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:8:5): this body overlaps body 0 by 0.05 m at the start (tolerance "
                                    "5e-05 m = 0.1 % of the smaller sphere radius); move them apart."));
}

TEST(DemBadInput, UnknownKeyWithSuggestion) {
  const auto r = runBase({"end_tme=0.1"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_EQ(r.status(), "Unknown key \"end_tme\" (--set end_tme=0.1): this scene does not use it. Did you mean \"end_time\"?");
}

TEST(DemBadInput, CheckModeValidatesWithoutRunning) {
  const auto ok = runScene("dem_solver", "configs/dem/hertz_bounce.yaml", {}, {"--check"});
  EXPECT_EQ(ok.exitCode, 0) << ok.output;
  EXPECT_FALSE(std::filesystem::exists(ok.outDir / "dem.h5"));
  const auto bad = runScene("dem_solver", "configs/dem/hertz_bounce.yaml", {"interactions[0].restitution=1.5"}, {"--check"});
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_THAT(bad.output, HasSubstr("interactions[0].restitution = 1.5 (--set interactions[0].restitution=1.5): is "
                                    "outside (0, 1]."));
}

TEST(DemBadInput, GeneratedSpheresThatDoNotFit) {
  const auto r = runScene("dem_solver", "configs/dem/pour.yaml", {"generate[0].count=5000"}, {"--check"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.output, HasSubstr("generate[0].count = 5000 (--set generate[0].count=5000): the box holds only 1024 "
                                  "spheres of radius 0.011 on the generation lattice (spacing 0.0231 m); enlarge the "
                                  "box or lower the count."));
  // 10⁹ spheres in a box that holds them: about 1 KB each, refused before any is made (it used to end in
  // std::bad_alloc after 30 s and 6.7 GB).
  const auto many = runScene("dem_solver", "configs/dem/pour.yaml",
                             {"generate[0].count=1000000000", "generate[0].box={min: [0, 0, 0], max: [1000, 1000, 1000]}"},
                             {"--check"});
  EXPECT_EQ(many.exitCode, 2);
  EXPECT_THAT(many.output, HasSubstr("needs 1100.0 GB for 1000000"));
}

// A wall triangle whose corners lie on one line has no normal: it used to be accepted silently.
TEST(DemBadInput, ZeroAreaWallTriangle) {
  const auto scene = writeScene("bad.yaml", std::string(kBase) + "walls:\n  - {type: mesh, file: flat.msh}\n");
  std::ofstream(scene.parent_path() / "flat.msh")
      << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n"
         "$EndNodes\n$Elements\n1 2 1 2\n2 1 2 2\n1 1 2 3\n2 1 2 4\n$EndElements\n";
  const auto r = runScene("dem_solver", scene.string(), {}, {"--check"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.output, HasSubstr("walls[0].file = flat.msh"));
  EXPECT_THAT(r.output, HasSubstr("triangle 1 (nodes 0, 1, 3) has zero area: its corners are on one line."));
}
