#include "common/app.hpp"

#include <yaml-cpp/yaml.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/log.hpp"
#include "temp_dir.hpp"

using common::RunContext;

namespace {

struct Outcome {
  int code;
  YAML::Node summary;
};

Outcome runWith(const TempDir& dir, std::vector<std::string> extra, const std::function<void(RunContext&)>& body) {
  const auto scene = dir.write("bounce.yaml", "dt: 1e-5\nend_time: 0.3\n");
  std::vector<std::string> args{"tester", scene.string(), "--out", (dir.path() / "out").string(), "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<const char*> argv;
  for (const auto& a : args) argv.push_back(a.c_str());
  const int code = common::runApp(static_cast<int>(argv.size()), argv.data(), {"tester", "test app", "0.1"}, nullptr, body);
  const auto summaryFile = dir.path() / "out/summary.yaml";
  return {code, std::filesystem::exists(summaryFile) ? YAML::LoadFile(summaryFile.string()) : YAML::Node()};
}

}  // namespace

TEST(App, SuccessfulRunWritesSummaryWithResults) {
  TempDir dir;
  const Outcome r = runWith(dir, {"--set", "end_time=0.1"}, [](RunContext& ctx) {
    const double dt = ctx.scene.get<double>("dt");
    const double end = ctx.scene.get<double>("end_time");
    ctx.scene.checkUnknownKeys();
    ctx.summary.setSteps(static_cast<std::int64_t>(std::llround(end / dt)));
    ctx.summary.set("end_time", end);
    ctx.summary.set("history", std::vector<double>{1.0, 2.0});
  });
  EXPECT_EQ(r.code, 0);
  ASSERT_TRUE(r.summary.IsMap());
  EXPECT_EQ(r.summary["scene"].as<std::string>(), "bounce");
  EXPECT_EQ(r.summary["status"].as<std::string>(), "ok");
  EXPECT_EQ(r.summary["exit_code"].as<int>(), 0);
  EXPECT_EQ(r.summary["steps"].as<long>(), 10000);
  EXPECT_DOUBLE_EQ(r.summary["results"]["end_time"].as<double>(), 0.1);  // the --set value reached the run
  EXPECT_EQ(r.summary["results"]["history"].as<std::vector<double>>(), (std::vector<double>{1.0, 2.0}));
  EXPECT_GE(r.summary["wall_time_s"].as<double>(), 0.0);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "out/tester.log"));
}

TEST(App, ConfigErrorExitsTwoAndSummaryCarriesTheMessage) {
  TempDir dir;
  const Outcome r = runWith(dir, {"--set", "dtt=3"}, [](RunContext& ctx) {
    ctx.scene.get<double>("dt");
    ctx.scene.get<double>("end_time");
    ctx.scene.checkUnknownKeys();
  });
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.summary["exit_code"].as<int>(), 2);
  EXPECT_EQ(r.summary["status"].as<std::string>(),
            "Unknown key \"dtt\" (--set dtt=3): this scene does not use it. Did you mean \"dt\"?");
}

TEST(App, SimulationErrorsMapToTheirExitCodes) {
  TempDir dir;
  Outcome r = runWith(dir, {}, [](RunContext&) { throw common::SimulationError("energy grew"); });
  EXPECT_EQ(r.code, 3);
  EXPECT_EQ(r.summary["status"].as<std::string>(), "energy grew");
  r = runWith(dir, {}, [](RunContext&) {
    throw common::SimulationError("participant fem died", common::ExitCode::kCoupling);
  });
  EXPECT_EQ(r.code, 4);
  EXPECT_EQ(r.summary["exit_code"].as<int>(), 4);
}

TEST(App, CheckModeWritesNoResults) {
  TempDir dir;
  bool sawCheck = false;
  const Outcome r = runWith(dir, {"--check"}, [&](RunContext& ctx) { sawCheck = ctx.options.check; });
  EXPECT_EQ(r.code, 0);
  EXPECT_TRUE(sawCheck);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "out"));
}

TEST(App, BadCommandLineExitsTwo) {
  TempDir dir;
  std::vector<const char*> argv{"tester", "/no/such/scene.yaml"};
  EXPECT_EQ(common::runApp(2, argv.data(), {"tester", "t", "0"}, nullptr, [](RunContext&) {}), 2);
}

TEST(Progress, FormatsRateAndEta) {
  EXPECT_EQ(common::Progress::format(0.15, 0.3, 2000, 2.0),
            "t = 0.15 / 0.3 s (50.0 %), 2000 steps, 1e+03 steps/s, ETA 2 s");
  EXPECT_EQ(common::Progress::format(0.1, 1.0, 10, 500.0),
            "t = 0.1 / 1 s (10.0 %), 10 steps, 0.02 steps/s, ETA 1 h 15 min");
}

TEST(Logging, RunLogReceivesNamedLoggers) {
  TempDir dir;
  const auto log = dir.path() / "run.log";
  common::setupLogging(log, true);
  common::logger("dem.contact")->info("hello {}", 42);
  common::logger("dem.contact")->flush();
  std::ifstream in(log);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, ::testing::HasSubstr("[dem.contact] info: hello 42"));
  common::setupLogging({}, true);
}

// What a peer or a file sent may be quoted in the summary: bytes that are not UTF-8 are written as \xNN,
// so summary.yaml stays valid YAML (a field name "force\xff" used to make it unreadable to PyYAML and
// yaml-cpp alike). Well-formed text, multi-byte characters included, passes unchanged.
TEST(App, SummaryQuotesBytesThatAreNotUtf8AsEscapes) {
  EXPECT_EQ(common::cleanUtf8("force\xff/x"), "force\\xFF/x");
  EXPECT_EQ(common::cleanUtf8("\xc3\xa9t\xc3\xa9 \xe2\x80\x94 \xf0\x9f\x99\x82"), "\xc3\xa9t\xc3\xa9 \xe2\x80\x94 \xf0\x9f\x99\x82");
  EXPECT_EQ(common::cleanUtf8("\xc0\xaf"), "\\xC0\\xAF");           // an overlong '/'
  EXPECT_EQ(common::cleanUtf8("\xed\xa0\x80"), "\\xED\\xA0\\x80");  // a UTF-16 surrogate
  EXPECT_EQ(common::cleanUtf8("\xe2\x80"), "\\xE2\\x80");           // cut short
  TempDir dir;
  const Outcome r = runWith(dir, {}, [](RunContext& ctx) {
    ctx.summary.set("label", std::string("peer \xfe\xff"));
    throw common::SimulationError("participant \"left\" sent the field interface/force\xff in RESULT",
                                  common::ExitCode::kCoupling);
  });
  ASSERT_TRUE(r.summary.IsMap());  // YAML::LoadFile read it
  EXPECT_EQ(r.summary["status"].as<std::string>(), "participant \"left\" sent the field interface/force\\xFF in RESULT");
  EXPECT_EQ(r.summary["results"]["label"].as<std::string>(), "peer \\xFE\\xFF");
}
