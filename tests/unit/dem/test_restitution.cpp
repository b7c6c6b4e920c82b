#include "dem/restitution.hpp"

#include <cmath>

#include <gtest/gtest.h>

using dem::NormalModel;

// The scaled linear collision against the closed form of Schwager & Pöschel (2007) for the clamped
// dashpot, across the under- and over-damped regimes. RK4 at h = 2e-4 is accurate to ~1e-8 here.
TEST(Restitution, LinearClampedMatchesSchwagerPoeschel) {
  for (double zeta : {0.05, 0.2, 0.5, 0.69, 0.72, 0.9, 1.2, 2.0}) {
    const double e = dem::solveImpact(NormalModel::kLinear, 2 * zeta).restitution;
    EXPECT_NEAR(e, dem::linearRestitutionClamped(zeta), 2e-6) << "zeta = " << zeta;
  }
}

// Undamped: the linear collision lasts π and reaches s = 1; Hertz lasts 2 ∫₀^{s_max} ds/√(1 − 0.8 s^{5/2})
// = 2 (5/4)^{2/5} · 1.47164 and reaches s_max = (5/4)^{2/5} (energy ½ = (2/5) s^{5/2}).
TEST(Restitution, UndampedCollisionsMatchTheory) {
  const auto lin = dem::solveImpact(NormalModel::kLinear, 0.0);
  EXPECT_NEAR(lin.restitution, 1.0, 1e-8);
  EXPECT_NEAR(lin.duration, 3.14159265358979, 1e-6);
  EXPECT_NEAR(lin.maxOverlap, 1.0, 1e-7);
  const auto hz = dem::solveImpact(NormalModel::kHertz, 0.0);
  const double smax = std::pow(1.25, 0.4);
  const double integral = 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
  EXPECT_NEAR(hz.restitution, 1.0, 1e-7);
  EXPECT_NEAR(hz.maxOverlap, smax, 1e-7);
  EXPECT_NEAR(hz.duration, 2 * smax * integral, 1e-5);
}

TEST(Restitution, InversionRecoversTheRequestedValue) {
  for (auto model : {NormalModel::kLinear, NormalModel::kHertz})
    for (double e : {0.05, 0.2, 0.5, 0.8, 0.99}) {
      const double c = dem::dampingForRestitution(model, e);
      EXPECT_NEAR(dem::solveImpact(model, c).restitution, e, 1e-9) << "e = " << e;
    }
  EXPECT_EQ(dem::dampingForRestitution(NormalModel::kHertz, 1.0), 0.0);
  EXPECT_THROW(dem::dampingForRestitution(NormalModel::kHertz, 0.0), std::invalid_argument);
  EXPECT_THROW(dem::dampingForRestitution(NormalModel::kHertz, 1.2), std::invalid_argument);
}

// The Tsuji β(e) mapping taken from the linear oscillator misses the restitution under Hertz: this is
// why the coefficient is solved instead (dem_solver/README.md). Tsuji: c = −2√(5/6) ln e / √(ln²e + π²).
TEST(Restitution, TsujiMappingWouldMissUnderHertz) {
  const double e = 0.5, l = std::log(e);
  const double cTsuji = -2 * std::sqrt(5.0 / 6.0) * l / std::sqrt(l * l + 3.14159265358979 * 3.14159265358979);
  const double achieved = dem::solveImpact(NormalModel::kHertz, cTsuji).restitution;
  EXPECT_GT(std::abs(achieved - e), 0.01);  // more than 2 % off
}
