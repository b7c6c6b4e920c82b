// Bad input to lattice_solver: exit code 2 and a message naming the key path, the file and line, what
// was found and what is allowed.
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "scene_run.hpp"

using testing::HasSubstr;
using testsupport::runScene;
using testsupport::writeScene;

namespace {

const char* kBase = R"(specimen:
  size: [0.02, 0.02, 0.02]
  rod_length: 0.004
aggregates:
  volume_fraction: 0.2
  sieve:
    type: table
    table:
      - [0.004, 0.0]
      - [0.006, 0.5]
      - [0.008, 1.0]
phases:
  interface: {tensile_strain: 5.0e-5}
rod:
  young_modulus: 3.0e10
loading:
  strain_increment: 1.0e-5
  max_strain: 1.0e-5
)";

testsupport::SceneRun runBase(const std::vector<std::string>& sets, std::string text = kBase) {
  return runScene("lattice_solver", writeScene("bad.yaml", text).string(), sets, {"--threads", "1"});
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  return text.replace(text.find(from), from.size(), to);
}

}  // namespace

TEST(LatticeBadInput, BaseSceneRuns) {
  const auto r = runBase({});
  EXPECT_EQ(r.exitCode, 0) << r.output;
}

TEST(LatticeBadInput, AggregateFractionThatCannotBePacked) {
  const auto r = runBase({}, replace(kBase, "volume_fraction: 0.2", "volume_fraction: 0.6"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("aggregates.volume_fraction = 0.6 ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:5:20): cannot be packed: aggregate "));
  EXPECT_THAT(r.status(), HasSubstr("found no free place in 20000 random positions"));
  EXPECT_THAT(r.status(), HasSubstr("Lower volume_fraction, widen the sieve curve"));
}

TEST(LatticeBadInput, SieveCurveNotMonotone) {
  const auto r = runBase({}, replace(kBase, "[0.008, 1.0]", "[0.008, 0.4]"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("aggregates.sieve.table[2] ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:11:9): the sieve curve is not monotone: passing 0.4 is below the 0.5 of the "
                                    "row above (a smaller sieve cannot pass more)."));
}

// A rod length that would need more rods than the machine can hold is refused before anything is
// generated (it used to climb past 4 GB without output and never return, issue 30).
TEST(LatticeBadInput, RodLengthTooSmallForThisMachineIsRefusedAtOnce) {
  const auto r = runBase({}, replace(kBase, "rod_length: 0.004", "rod_length: 1.0e-7"));
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_THAT(r.status(), HasSubstr("specimen.rod_length = 1.0e-7 ("));
  EXPECT_THAT(r.status(), HasSubstr("in a 0.02 × 0.02 × 0.02 m specimen needs 6.4e+10 GB for about 1.28e+17 rods, this "
                                    "machine has"));
  EXPECT_THAT(r.status(), HasSubstr("Raise rod_length."));
}

// The same for a specimen from a gmsh volume: refused from the volume's bounding box, before gmsh meshes
// its surfaces at half that rod length (which alone would not return).
TEST(LatticeBadInput, RodLengthTooSmallForAGmshVolumeIsRefusedBeforeMeshing) {
  const auto r = runScene("lattice_solver", "configs/lattice/cylinder_tension.yaml", {"specimen.rod_length=1.0e-7"},
                          {"--threads", "1"});
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_THAT(r.status(), HasSubstr("specimen.geometry.file = cylinder.geo ("));
  EXPECT_THAT(r.status(), HasSubstr("rods, this machine has"));
  EXPECT_THAT(r.status(), HasSubstr("raise specimen.rod_length"));
}

TEST(LatticeBadInput, RodLengthLargerThanTheSpecimen) {
  const auto r = runBase({}, replace(kBase, "rod_length: 0.004", "rod_length: 0.03"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("specimen.rod_length = 0.03 ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:3:15): is not below the smallest specimen side 0.02 m (specimen.size)"));
}

TEST(LatticeBadInput, CriticalStrainNotPositive) {
  const auto r = runBase({}, replace(kBase, "tensile_strain: 5.0e-5", "tensile_strain: 0"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("phases.interface.tensile_strain = 0 ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:13:31): is outside (0, inf)."));
  const auto c = runBase({"phases.matrix.compressive_strain=-2e-3"});
  EXPECT_EQ(c.exitCode, 2);
  EXPECT_THAT(c.status(), HasSubstr("phases.matrix.compressive_strain = -2e-3 (--set phases.matrix.compressive_strain=-2e-3): "
                                    "is outside (0, inf)."));
}

TEST(LatticeBadInput, UnknownKeysAndNames) {
  const auto r = runBase({"loading.max_stain=1e-4"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("Did you mean \"max_strain\"?"));
  const auto s = runBase({"solver.type=cgg"});
  EXPECT_EQ(s.exitCode, 2);
  EXPECT_THAT(s.status(), HasSubstr("solver.type = cgg (--set solver.type=cgg): unknown name; expected one of: cg, averaging."));
}

TEST(LatticeBadInput, MixedPrecisionNeedsTheMatrixFreeOperator) {
  const auto r = runBase({"solver.precision=mixed", "solver.operator=assembled"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("solver.precision = mixed (--set solver.precision=mixed): `mixed` needs solver.type cg "
                                    "with solver.operator matrix_free"));
  const auto p = runBase({"solver.precision=half"});
  EXPECT_EQ(p.exitCode, 2);
  EXPECT_THAT(p.status(), HasSubstr("unknown name; expected one of: double, mixed."));
  // Each solver reads its own keys: cg's precision under the averaging solver is an unknown key.
  const auto a = runBase({"solver.type=averaging", "solver.precision=mixed"});
  EXPECT_EQ(a.exitCode, 2);
  EXPECT_THAT(a.status(), HasSubstr("Unknown key \"solver.precision\""));
}

// Participant mode (`interface`): located errors for the new keys.
namespace {
const char* kCoupled = R"(specimen:
  size: [0.02, 0.02, 0.02]
  rod_length: 0.004
rod:
  young_modulus: 3.0e10
interface:
  - {face: z_min, mode: dirichlet}
  - {face: z_max, mode: neumann}
)";
}  // namespace

TEST(LatticeBadInput, InterfaceChecksWithoutRunning) {
  const auto r = runBase({}, kCoupled);
  // --check passes, but a standalone run needs `loading`.
  const auto check = runScene("lattice_solver", writeScene("bad.yaml", kCoupled).string(), {}, {"--check"});
  EXPECT_EQ(check.exitCode, 0) << check.output;
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("a standalone lattice_solver run needs a `loading` section"));
}

TEST(LatticeBadInput, InterfaceFaceUnknown) {
  const auto r = runBase({}, replace(kCoupled, "face: z_max", "face: z_mid"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("interface[1].face = z_mid ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:8:12): unknown name; expected one of: x_min, x_max, "
                                    "y_min, y_max, z_min, z_max."));
}

TEST(LatticeBadInput, InterfaceModeUnknownAndFaceTwice) {
  const auto r = runBase({}, replace(kCoupled, "mode: neumann", "mode: robin"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("interface[1].mode = robin ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:8:25): unknown name; expected one of: dirichlet, neumann."));
  const auto t = runBase({}, replace(kCoupled, "face: z_max", "face: z_min"));
  EXPECT_EQ(t.exitCode, 2);
  EXPECT_THAT(t.status(), HasSubstr("interface[1].face = z_min ("));
  EXPECT_THAT(t.status(), HasSubstr("bad.yaml:8:12): \"z_min\" is listed twice."));
}

TEST(LatticeBadInput, InterfaceWithoutDirichletFace) {
  const auto r = runBase({}, replace(kCoupled, "mode: dirichlet", "mode: neumann"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("interface (/tmp/"));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:7:3): has no dirichlet face: with only neumann faces nothing holds the lattice"));
  EXPECT_THAT(r.status(), HasSubstr("Make at least one face `mode: dirichlet`."));
}

// specimen.geometry: a missing file, a file without a volume, a volume tag that does not exist, a box
// size beside it, an axis along which the volume has no flat end faces.
namespace {

std::string geometryScene(const std::string& geometry, const std::string& extra = "", const std::string& axis = "z") {
  return "specimen:\n  geometry: " + geometry + "\n" + extra + "  rod_length: 0.008\nrod:\n  young_modulus: 3.0e10\nloading:\n  axis: " +
         axis + "\n  strain_increment: 1.0e-5\n  max_strain: 1.0e-5\n";
}

std::string cylinder() { return testsupport::sourcePath("configs/lattice/cylinder.geo").string(); }

}  // namespace

TEST(LatticeBadInput, GeometryFileMissing) {
  const auto r = runBase({}, geometryScene("{file: no_such.geo}"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("specimen.geometry.file = no_such.geo ("));
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:2:20): the file \""));
  EXPECT_THAT(r.status(), HasSubstr("no_such.geo\" does not exist."));
}

TEST(LatticeBadInput, GeometryWithoutVolume) {
  const auto scene = writeScene("bad.yaml", geometryScene("{file: flat.geo}"));
  std::ofstream(scene.parent_path() / "flat.geo") << "SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 0.05, 0.05};\n";
  const auto r = runScene("lattice_solver", scene.string(), {}, {"--threads", "1"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("specimen.geometry.file = flat.geo (" + scene.string() + ":2:20): \""));
  EXPECT_THAT(r.status(), HasSubstr("flat.geo\" defines no volume (3-D entity); the specimen needs a closed volume"));
}

TEST(LatticeBadInput, GeometryVolumeTagUnknown) {
  const auto r = runBase({}, geometryScene("{file: " + cylinder() + ", volume: 7}"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("specimen.geometry.volume = 7 ("));
  EXPECT_THAT(r.status(), HasSubstr("cylinder.geo\" has no volume 7 (its volumes: 1)."));
}

TEST(LatticeBadInput, GeometryWithBoxSizeOrNoFlatEnds) {
  const auto r = runBase({}, geometryScene("{file: " + cylinder() + "}", "  size: [0.05, 0.05, 0.1]\n"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.status(), HasSubstr("specimen.size (")) << r.status();
  EXPECT_THAT(r.status(), HasSubstr("bad.yaml:3:9): cannot be combined with specimen.geometry"));
  const auto x = runBase({}, geometryScene("{file: " + cylinder() + "}", "", "x"));
  EXPECT_EQ(x.exitCode, 2);
  EXPECT_THAT(x.status(), HasSubstr("loading.axis = x ("));
  EXPECT_THAT(x.status(), HasSubstr("but it has no face in the plane x = -0.025 m. Choose the axis along which the volume ends in "
                                    "flat faces."));
}
