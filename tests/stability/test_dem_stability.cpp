// The DEM at and beyond the edge of its time step (issue 26): a run either stays within its energy
// tolerance or stops with exit 3 and a diagnosis; initial velocities are velocities at t = 0; end_time
// is reached exactly or refused; the summary agrees with the time series it summarises.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "h5_read.hpp"
#include "scene_run.hpp"

using testsupport::runScene;
using testsupport::writeScene;

namespace {

// The issue's case: a 5 cm rock sphere (E = 7e9 Pa, ν = 0.25) hits a floor at 3 m/s. The Rayleigh step
// is 1.618e-4 s; the elastic contact lasts 6.92e-4 s (Johnson 1985 §11.4).
std::string rockBounce(const std::string& dt, const std::string& extra = "") {
  return R"(
materials:
  rock: {density: 2500, young_modulus: 7.0e9, poisson_ratio: 0.25}
interactions:
  - {materials: [rock, rock], law: hertz_mindlin, restitution: 1.0, friction: 0.0}
spheres:
  - {material: rock, radius: 0.05, position: [0, 0, 0.0505], velocity: [0, 0, -3.0]}
walls:
  - {type: plane, name: floor, material: rock, point: [0, 0, 0], normal: [0, 0, 1]}
gravity: [0, 0, 0]
probe: {type: impact, body: 0}
dt: )" + dt + "\n" + extra;
}

double seriesMaxAbs(const std::filesystem::path& h5, const std::string& column) {
  const auto v = testsupport::readH5(h5, column);
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

}  // namespace

// dt = 10 × critical with dt_check: warn ran to the end with `status: ok` and a restitution of 202;
// now the energy check stops it, names the body, and computes a dt that resolves the contact.
TEST(DemStability, TenTimesTheCriticalStepEndsWithExit3AndAFix) {
  const auto scene = writeScene("hertz10.yaml", rockBounce("1.62e-3", "dt_check: warn\nend_time: 0.0324\n"));
  const auto r = runScene("dem_solver", scene.string());
  ASSERT_EQ(r.exitCode, 3) << r.output;
  EXPECT_EQ(r.summary["failure"]["cause"].as<std::string>(), "energy growth");
  EXPECT_EQ(r.summary["failure"]["where"].as<std::string>(), "body 0");
  // The fix is the safe step: the contact duration at 3 m/s (6.924e-4 s) over 20 steps.
  EXPECT_NEAR(r.result("safe_dt"), 6.924e-4 / 20, 1e-7);
  // Printed at most the safe step and reaching end_time = 0.0324 s in whole steps (1,000 of 3.24e-5 s; the
  // safe step rounded to three digits, 3.46e-5 s, would leave 936.4 and be refused), and as a setting that,
  // applied verbatim, runs clean.
  EXPECT_NE(r.summary["failure"]["fix"].as<std::string>().find("dt = 3.24e-05 s"), std::string::npos)
      << r.summary["failure"]["fix"];
  ASSERT_EQ(r.summary["failure"]["fix_settings"].size(), 1u);
  const auto fix = r.summary["failure"]["fix_settings"][0].as<std::string>();
  EXPECT_EQ(fix, "dt=3.24e-05");
  const auto fixed = runScene("dem_solver", scene.string(), {fix});
  EXPECT_EQ(fixed.exitCode, 0) << fixed.output;
  EXPECT_EQ(fixed.summary["steps"].as<long>(), 1000) << fixed.output;
  // The peaks it measured before stopping are in the summary and agree with the series (sampled every step).
  const double seriesForce = seriesMaxAbs(r.outDir / "dem.h5", "/timeseries/body_0/fz");
  EXPECT_GT(seriesForce, 1e5);
  EXPECT_GE(r.result("peak_contact_force"), seriesForce * (1 - 1e-12));
  EXPECT_GT(r.result("max_overlap"), 0.0);
}

// Accepted silently before at 0.5 × critical (8 steps per contact, 0.8 % error): the safe step now
// resolves the impact, and the message gives both limits.
TEST(DemStability, SafeStepAccountsForTheImpactSpeed) {
  const auto scene = writeScene("hertz05.yaml", rockBounce("8.0e-5", "end_time: 0.0016\n"));
  const auto r = runScene("dem_solver", scene.string());
  ASSERT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.status().find("contact duration 0.0006924 s at the fastest approach this scene can reach, 3 m/s"),
            std::string::npos)
      << r.status();
  EXPECT_NE(r.status().find("critical step 0.0001618 s"), std::string::npos) << r.status();
  // At the safe step the same impact is resolved: restitution 1 within 0.1 % and Hertz's duration.
  const auto ok = runScene("dem_solver", scene.string(), {"dt=3.2e-5", "end_time=0.0016"});
  ASSERT_EQ(ok.exitCode, 0) << ok.output;
  EXPECT_NEAR(ok.result("restitution"), 1.0, 1e-3);
  EXPECT_NEAR(ok.result("contact_duration") / ok.result("contact_duration_analytic"), 1.0, 5e-3);
  EXPECT_LT(ok.result("energy_balance_error"), 1e-2);
}

// A rigid cluster in free fall, thrown sideways and up: leapfrog integrates a constant acceleration
// exactly once it starts with the half kick from v(0), so the trajectory is the parabola to round-off.
TEST(DemStability, FreeFallingClusterMatchesTheParabola) {
  const auto scene = writeScene("fall.yaml", R"(
materials:
  concrete: {density: 2600, young_modulus: 1.0e8, poisson_ratio: 0.25}
interactions:
  - {materials: [concrete, concrete], law: hertz_mindlin, restitution: 0.5}
clusters:
  - {cube: {edge: 0.41, n: 2}, material: concrete, position: [0, 0, 2.0], velocity: [1.5, 0, 0.5]}
gravity: [0, 0, -9.81]
dt: 1.0e-4
end_time: 0.1
output: {interval: 0, series_interval: 1.0e-2}
)");
  const auto r = runScene("dem_solver", scene.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto h5 = r.outDir / "dem.h5";
  const auto t = testsupport::readH5(h5, "/timeseries/body_0/time");
  const auto x = testsupport::readH5(h5, "/timeseries/body_0/x");
  const auto z = testsupport::readH5(h5, "/timeseries/body_0/z");
  const auto vz = testsupport::readH5(h5, "/timeseries/body_0/vz");
  ASSERT_EQ(t.size(), 11u);
  EXPECT_DOUBLE_EQ(vz.front(), 0.5);  // the scene's velocity is v(0)
  for (std::size_t i = 1; i < t.size(); ++i) {
    const double zExact = 2.0 + 0.5 * t[i] - 0.5 * 9.81 * t[i] * t[i];
    EXPECT_LT(std::abs(z[i] - zExact) / zExact, 1e-9) << "t = " << t[i];
    EXPECT_LT(std::abs(x[i] - 1.5 * t[i]), 1e-12);
  }
  // Before, the start from v(−dt/2) = v(0) was off by g t dt / 2 = 4.9e-5 m here.
  EXPECT_LT(std::abs(z.back() - (2.0 + 0.05 - 0.5 * 9.81 * 0.01)), 1e-9);
}

// A step so short that the step count overflowed: dt = 1e-300 s wrapped it to −9.2·10¹⁸ and the run ended
// "ok" after no step. Every count derived from the input is bounded (10¹² steps, 10⁹ coupling windows):
// exit 2 at the key, before anything runs.
TEST(DemStability, AStepCountNoRunFinishesIsRefused) {
  const auto scene = writeScene("tiny.yaml", rockBounce("1.0e-300", "end_time: 0.003\n"));
  const auto r = runScene("dem_solver", scene.string());
  ASSERT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.status().find("steps of 1e-300 s to end_time"), std::string::npos) << r.status();
  EXPECT_NE(r.status().find("more than the 1e+12 a run may take"), std::string::npos) << r.status();
  const auto windows = runScene("cosim", "configs/verification/split_bar_dynamic.yaml", {"coupling.time_window=1e-300"},
                                {"--check"});
  ASSERT_EQ(windows.exitCode, 2) << windows.output;
  EXPECT_NE(windows.output.find("coupling.time_window = 1e-300"), std::string::npos) << windows.output;
  EXPECT_NE(windows.output.find("more than the 1e+09 a run may take"), std::string::npos) << windows.output;
}

// end_time 0.03 with dt 2.86e-3 stopped at 0.0286; now it is refused with the nearest valid values,
// and an automatic dt is shortened so the run ends exactly at end_time.
TEST(DemStability, EndTimeIsReachedExactlyOrRefused) {
  const auto scene = writeScene("end.yaml", rockBounce("2.86e-5", "end_time: 0.0030001\n"));
  const auto r = runScene("dem_solver", scene.string());
  ASSERT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.status().find("is not a whole number of steps of dt = 2.86e-05 s (104.8986 steps)"), std::string::npos)
      << r.status();
  EXPECT_NE(r.status().find("end_time = 0.0030001"), std::string::npos) << r.status();
  const auto automatic = runScene("dem_solver", scene.string(), {"dt=null"});
  ASSERT_EQ(automatic.exitCode, 0) << automatic.output;
  EXPECT_DOUBLE_EQ(automatic.result("end_time"), 0.0030001);
  EXPECT_LE(automatic.result("dt"), automatic.result("safe_dt"));
}

// A stable run's summary agrees with the series: the peak force of the steel bounce (series every 5
// steps of a 350-step contact) is the series' largest value to within the sampling.
TEST(DemStability, SummaryPeaksAgreeWithTheSeries) {
  const auto r = runScene("dem_solver", "configs/dem/hertz_bounce.yaml", {"output.interval=0"});
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const double series = seriesMaxAbs(r.outDir / "dem.h5", "/timeseries/body_0/fz");
  EXPECT_GE(r.result("peak_contact_force"), series);
  EXPECT_LT(r.result("peak_contact_force") / series - 1, 1e-3);
}
