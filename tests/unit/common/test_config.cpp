#include "common/config.hpp"

#include <fstream>

#include <fmt/format.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "temp_dir.hpp"

using common::Config;
using common::ConfigError;
using common::Interval;
using testing::HasSubstr;

namespace {

// Runs `f`, which must throw ConfigError, and returns the message.
template <class F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ConfigError";
  return {};
}

const char* kScene = R"(dem:
  dt: 1.0e-5
  steps: 200
  gravity: [0, 0, -9.81]
  verbose: true
  law: hertz_mindlin
  materials:
    rock: {density: 2500, poisson_ratio: 0.62}
    steel: {density: 7800, poisson_ratio: 0.3}
  walls:
    - {type: plane, normal: [0, 0, 1]}
    - {type: mesh, file: floor.msh}
)";

}  // namespace

TEST(Config, TypedGettersAndDefaults) {
  Config c = Config::parse(kScene, "scene.yaml");
  Config dem = c.at("dem");
  EXPECT_DOUBLE_EQ(dem.get<double>("dt"), 1e-5);
  EXPECT_EQ(dem.get<int>("steps"), 200);
  EXPECT_EQ(dem.get<std::size_t>("steps"), 200u);
  EXPECT_TRUE(dem.get<bool>("verbose"));
  EXPECT_EQ(dem.get<std::string>("law"), "hertz_mindlin");
  EXPECT_EQ(dem.get<Eigen::Vector3d>("gravity"), Eigen::Vector3d(0, 0, -9.81));
  EXPECT_EQ(dem.get<double>("end_time", 0.3), 0.3);
  EXPECT_FALSE(dem.find<double>("damping").has_value());
  EXPECT_EQ(dem.at("walls").elements().size(), 2u);
  EXPECT_EQ(dem.at("walls").elements()[1].path(), "dem.walls[1]");
  auto mats = dem.at("materials").entries();
  ASSERT_EQ(mats.size(), 2u);
  EXPECT_EQ(mats[0].first, "rock");  // file order kept
  EXPECT_EQ(mats[1].second.get<double>("density"), 7800);
}

TEST(Config, TypeErrorNamesFileKeyPathLineAndColumn) {
  Config c = Config::parse("dem:\n  dt: abc\n", "configs/dem/bounce.yaml");
  EXPECT_EQ(errorOf([&] { c.at("dem").get<double>("dt"); }),
            "dem.dt = abc (configs/dem/bounce.yaml:2:7): expected a number.");
  EXPECT_EQ(errorOf([&] { c.at("dem").get<Eigen::Vector3d>("dt"); }),
            "dem.dt = abc (configs/dem/bounce.yaml:2:7): expected a 3-vector [x, y, z], found a scalar.");
  Config v = Config::parse("g: [0, 1]\nn: -3\n", "s.yaml");
  EXPECT_EQ(errorOf([&] { v.get<Eigen::Vector3d>("g"); }),
            "g (s.yaml:1:4): expected a 3-vector [x, y, z], found a list of 2 values.");
  EXPECT_EQ(errorOf([&] { v.get<std::size_t>("n"); }), "n = -3 (s.yaml:2:4): expected a whole number >= 0.");
}

TEST(Config, RangeErrorShowsValueLocationAndInterval) {
  Config c = Config::parse(kScene, "configs/dem/pour.yaml");
  Config rock = c.at("dem").at("materials").at("rock");
  EXPECT_EQ(errorOf([&] { rock.get("poisson_ratio", Interval::open(-1, 0.5)); }),
            "dem.materials.rock.poisson_ratio = 0.62 (configs/dem/pour.yaml:8:42): is outside (-1, 0.5).");
  EXPECT_DOUBLE_EQ(rock.get("density", Interval::positive()), 2500);
  EXPECT_DOUBLE_EQ(rock.get("young", 1e9, Interval::positive()), 1e9);
}

TEST(Config, MissingKeyIsNamedWithItsParent) {
  Config c = Config::parse("dem:\n  dtt: 1\n", "a.yaml");
  EXPECT_EQ(errorOf([&] { c.at("dem").get<double>("dt"); }),
            "Missing required key \"dem.dt\" in dem (a.yaml:2:3). Found \"dtt\": did you mean \"dt\"?");
}

TEST(Config, UnknownKeysAreErrorsWithSuggestions) {
  Config c = Config::parse("dem:\n  dt: 1e-5\n  end_tme: 0.3\n  colour: red\n", "configs/dem/x.yaml");
  Config dem = c.at("dem");
  dem.get<double>("dt");
  dem.get<double>("end_time", 1.0);
  EXPECT_EQ(errorOf([&] { c.checkUnknownKeys(); }),
            "Unknown key \"dem.end_tme\" (configs/dem/x.yaml:3:3): this scene does not use it. Did you mean "
            "\"end_time\"?\n"
            "Unknown key \"dem.colour\" (configs/dem/x.yaml:4:3): this scene does not use it.");
}

TEST(Config, UnknownKeysInsideListsAreFound) {
  Config c = Config::parse("walls:\n  - {type: plane, normall: [0, 0, 1]}\n", "w.yaml");
  for (const auto& w : c.at("walls").elements()) {
    w.get<std::string>("type");
    w.find<Eigen::Vector3d>("normal");
  }
  EXPECT_EQ(errorOf([&] { c.checkUnknownKeys(); }),
            "Unknown key \"walls[0].normall\" (w.yaml:2:19): this scene does not use it. Did you mean \"normal\"?");
}

TEST(Config, ChoiceSuggestsTheClosestName) {
  Config c = Config::parse("mapping: nearest_neigbor\n", "configs/rockfall/c5.yaml");
  EXPECT_EQ(errorOf([&] { c.choice("mapping", {"identity", "nearest_neighbor", "nearest_projection"}); }),
            "mapping = nearest_neigbor (configs/rockfall/c5.yaml:1:10): unknown name; expected one of: identity, "
            "nearest_neighbor, nearest_projection. Did you mean \"nearest_neighbor\"?");
  EXPECT_EQ(c.choice("scheme", {"explicit", "implicit"}, "implicit"), "implicit");
}

TEST(Config, SyntaxAndStructureErrorsAreLocated) {
  EXPECT_THAT(errorOf([] { Config::parse("a: [1, 2\nb: 3\n", "bad.yaml"); }), HasSubstr("bad.yaml:"));
  EXPECT_THAT(errorOf([] { Config::parse("a: [1, 2\nb: 3\n", "bad.yaml"); }), HasSubstr("YAML syntax error"));
  EXPECT_EQ(errorOf([] { Config::parse("a: 1\nb: 2\na: 3\n", "dup.yaml"); }),
            "dup.yaml:3:1: key \"a\" appears twice in the same map.");
  EXPECT_THAT(errorOf([] { Config::load("/nonexistent/scene.yaml"); }),
              HasSubstr("cannot open scene file \"/nonexistent/scene.yaml\""));
}

TEST(Config, SetOverridesScalarsListsAndCreatesKeys) {
  Config c = Config::parse(kScene, "scene.yaml", ".",
                           {"dem.dt=2e-5", "dem.gravity=[0, -9.81, 0]", "dem.walls[1].file=other.stl",
                            "dem.output.interval=0.01"});
  Config dem = c.at("dem");
  EXPECT_DOUBLE_EQ(dem.get<double>("dt"), 2e-5);
  EXPECT_EQ(dem.get<Eigen::Vector3d>("gravity"), Eigen::Vector3d(0, -9.81, 0));
  EXPECT_EQ(dem.at("walls").elements()[1].get<std::string>("file"), "other.stl");
  EXPECT_DOUBLE_EQ(dem.at("output").get<double>("interval"), 0.01);
  // A bad value from --set is located at the --set argument.
  Config bad = Config::parse(kScene, "scene.yaml", ".", {"dem.dt=fast"});
  EXPECT_EQ(errorOf([&] { bad.at("dem").get<double>("dt"); }), "dem.dt = fast (--set dem.dt=fast): expected a number.");
}

TEST(Config, SetNullRemovesAKey) {
  Config c = Config::parse("dem:\n  dt: 1\n  dt_fraction: 0.2\n", "s.yaml", ".", {"dem.dt_fraction=null"});
  EXPECT_FALSE(c.at("dem").has("dt_fraction"));
  EXPECT_DOUBLE_EQ(c.at("dem").get<double>("dt"), 1.0);
  c.checkUnknownKeys();  // nothing left unread
}

TEST(Config, SetTyposAreCaughtAsUnknownKeys) {
  Config c = Config::parse("dem:\n  dt: 1\n", "s.yaml", ".", {"dem.dtt=3"});
  c.at("dem").get<double>("dt");
  EXPECT_EQ(errorOf([&] { c.checkUnknownKeys(); }),
            "Unknown key \"dem.dtt\" (--set dem.dtt=3): this scene does not use it. Did you mean \"dt\"?");
}

TEST(Config, SetErrors) {
  EXPECT_EQ(errorOf([] { Config::parse("a: 1\n", "s.yaml", ".", {"a.b=2"}); }),
            "--set a.b=2: \"a\" is a scalar in s.yaml:1:4, so it has no key \"b\".");
  EXPECT_EQ(errorOf([] { Config::parse("a: [1]\n", "s.yaml", ".", {"a[3]=2"}); }),
            "--set a[3]=2: index 3 is out of range: \"a\" has 1 elements (s.yaml:1:4).");
  EXPECT_EQ(errorOf([] { Config::parse("a: 1\n", "s.yaml", ".", {"a"}); }),
            "--set a: expected KEY.PATH=VALUE, e.g. --set dem.dt=1e-5.");
}

TEST(Config, IncludeMergesAndKeepsTheIncludedFilesLocations) {
  TempDir dir;
  dir.write("dem.yaml", "dt: 1e-5\nend_time: abc\nmesh: floor.msh\nmaterial: {density: 2500, friction: 0.5}\n");
  dir.write("sub/coupled.yaml",
            "dem:\n  include: ../dem.yaml\n  dt: 2e-5\n  material: {friction: 0.3}\nfem: {include: [../fem.yaml]}\n");
  dir.write("fem.yaml", "thickness: 0.008\n");
  Config c = Config::load(dir.path() / "sub/coupled.yaml");
  Config dem = c.at("dem");
  EXPECT_DOUBLE_EQ(dem.get<double>("dt"), 2e-5);  // the including file wins
  EXPECT_DOUBLE_EQ(dem.at("material").get<double>("density"), 2500);
  EXPECT_DOUBLE_EQ(dem.at("material").get<double>("friction"), 0.3);
  EXPECT_DOUBLE_EQ(c.at("fem").get<double>("thickness"), 0.008);
  // Errors in included values point into the included file, with its line.
  const std::string demFile = (dir.path() / "sub/../dem.yaml").string();
  EXPECT_EQ(errorOf([&] { dem.get<double>("end_time"); }),
            "dem.end_time = abc (" + demFile + ":2:11): expected a number.");
  // File paths resolve relative to the file that wrote them.
  EXPECT_EQ(dem.filePath("mesh"), dir.path() / "sub/../floor.msh");
}

// A null in the including file removes the included key, as --set key=null does: a variant scene can
// swap `end_time` for `steps` without an unknown-key error on the leftover.
TEST(Config, IncludeNullRemovesTheIncludedKey) {
  TempDir dir;
  dir.write("base.yaml", "explicit: {end_time: 3.0e-3, dt_fraction: 0.9}\nkeep: 1\n");
  dir.write("variant.yaml", "include: base.yaml\nexplicit: {end_time: null, dt_fraction: null, steps: 400}\n");
  Config c = Config::load(dir.path() / "variant.yaml");
  Config ex = c.at("explicit");
  EXPECT_FALSE(ex.has("end_time"));
  EXPECT_FALSE(ex.has("dt_fraction"));
  EXPECT_EQ(ex.get<int>("steps"), 400);
  EXPECT_EQ(c.get<int>("keep"), 1);
  EXPECT_NO_THROW(c.checkUnknownKeys());
}

TEST(Config, IncludeCycleAndMissingIncludeAreErrors) {
  TempDir dir;
  dir.write("a.yaml", "include: b.yaml\nx: 1\n");
  dir.write("b.yaml", "include: a.yaml\n");
  EXPECT_THAT(errorOf([&] { Config::load(dir.path() / "a.yaml"); }), HasSubstr("include cycle"));
  dir.write("c.yaml", "x:\n  include: missing.yaml\n");
  EXPECT_THAT(errorOf([&] { Config::load(dir.path() / "c.yaml"); }),
              HasSubstr((dir.path() / "c.yaml").string() + ":2:12: cannot open scene file"));
}

// Found by fuzzing (issue 30): an include whose name the file system refuses ended the program with
// std::filesystem::filesystem_error; an include of a device would read forever.
TEST(Config, IncludeOfAnUnusableNameOrADeviceIsAnError) {
  TempDir dir;
  dir.write("long.yaml", "include: \"" + std::string(5000, 'x') + "\"\n");
  EXPECT_THAT(errorOf([&] { Config::load(dir.path() / "long.yaml"); }), HasSubstr("cannot open scene file"));
  dir.write("dev.yaml", "include: /dev/zero\n");
  EXPECT_THAT(errorOf([&] { Config::load(dir.path() / "dev.yaml"); }), HasSubstr("\"/dev/zero\" is not a regular file."));
}

TEST(Config, SuggestOnlyPlausibleTypos) {
  EXPECT_EQ(common::suggest("dtt", {"dt", "gravity"}), "dt");
  EXPECT_EQ(common::suggest("hertz_mindlim", {"hertz_mindlin", "linear"}), "hertz_mindlin");
  EXPECT_FALSE(common::suggest("colour", {"dt", "end_time"}).has_value());
}

// A whole number too large for its key's type says so, with the range, instead of "expected a whole
// number" (issue 30: `line: {elements: 20000000000}`).
TEST(Config, WholeNumberOutOfRangeNamesTheRange) {
  Config c = Config::parse("n: 20000000000\nm: 12x\n", "s.yaml");
  EXPECT_EQ(errorOf([&] { c.get<int>("n"); }),
            "n = 20000000000 (s.yaml:1:4): is outside the range of whole numbers this key takes, [-2147483648, 2147483647].");
  EXPECT_EQ(c.get<long>("n"), 20000000000L);
  EXPECT_EQ(errorOf([&] { c.get<int>("m"); }), "m = 12x (s.yaml:2:4): expected a whole number.");
}

// "Billion laughs": nine levels of nine aliases stand for 9⁹ ≈ 3.9·10⁸ values in under 1 KB. The tree is
// refused once it passes its budget (50,000 values plus two per character of text), before anything
// large is built: directly, through an include, and through --set. A real scene with aliases loads.
TEST(Config, AliasExpansionIsBounded) {
  std::string bomb = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n";
  for (char level = 'b'; level <= 'i'; ++level) {
    const char below = static_cast<char>(level - 1);
    bomb += fmt::format("{0}: &{0} [*{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}]\n", level, below);
  }
  ASSERT_LT(bomb.size(), 1024u);
  EXPECT_THAT(errorOf([&] { Config::parse(bomb, "bomb.yaml"); }), HasSubstr("the scene expands to more than"));
  TempDir dir;
  dir.write("bomb.yaml", bomb);
  dir.write("scene.yaml", "dem:\n  include: bomb.yaml\n");
  EXPECT_THAT(errorOf([&] { Config::load(dir.path() / "scene.yaml"); }), HasSubstr("bomb.yaml:"));
  std::string flow = "x={a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]";
  for (char level = 'b'; level <= 'i'; ++level) {
    const char below = static_cast<char>(level - 1);
    flow += fmt::format(", {0}: &{0} [*{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}, *{1}]", level, below);
  }
  EXPECT_THAT(errorOf([&] { Config::parse("x: 1\n", "s.yaml", ".", {flow + "}"}); }),
              HasSubstr("the scene expands to more than"));
  const Config ok = Config::parse("m: &m {density: 2500}\na: *m\nb: *m\n");
  EXPECT_EQ(ok.at("b").get<int>("density"), 2500);
}
