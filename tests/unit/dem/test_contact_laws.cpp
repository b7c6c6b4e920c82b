// Contract tests run over every registered contact law (CONTRIBUTING.md): no force at zero overlap, damping
// never adds energy, the requested restitution is recovered by the law itself, Coulomb is respected.
#include <cmath>
#include <random>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "dem/contact_law.hpp"

using dem::ContactForce;
using dem::ContactHistory;
using dem::ContactPoint;
using dem::Vec3;

namespace {

dem::Material steel() { return {"steel", 7800, 2e11, 0.3}; }

std::unique_ptr<dem::ContactLaw> make(const std::string& law, double e, double mu) {
  const auto cfg = common::Config::parse(
      fmt::format("{{law: {}, restitution: {}, friction: {}, stiffness_normal: 1.0e7}}", law, e, mu), "test.yaml");
  auto l = dem::makeContactLaw(law, cfg, steel(), steel());
  return l;
}

ContactForce evaluate(const dem::ContactLaw& law, const ContactPoint& p, ContactHistory& h, double dt) {
  ContactForce f;
  law.compute(std::span(&p, 1), std::span(&h, 1), std::span(&f, 1), dt);
  return f;
}

// Integrates a head-on collision of mass m on a fixed wall with the law itself (leapfrog, 2000 steps
// per contact) and returns the restitution.
double bounce(const dem::ContactLaw& law, double m, double r, double v0) {
  const auto guess = law.elasticImpact(r, m, v0);
  const double dt = guess.contactDuration / 2000;
  double x = 0.0, v = -v0;  // x = −overlap
  ContactHistory h;
  for (int i = 0; i < 100000; ++i) {
    ContactPoint p;
    p.overlap = -x;
    p.relVelocity = Vec3(0, 0, v);
    p.effRadius = r;
    p.effMass = m;
    const ContactForce f = evaluate(law, p, h, dt);
    v += f.force.z() / m * dt;
    x += v * dt;
    if (x > 0 && v > 0) return v / v0;
  }
  return -1;
}

class EveryLaw : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(EveryLaw, NoForceWithoutOverlapAndHistoryResets) {
  auto law = make(GetParam(), 0.5, 0.5);
  ContactPoint p;
  p.overlap = 0.0;
  p.relVelocity = Vec3(1, 2, -3);
  p.effRadius = 0.01;
  p.effMass = 0.03;
  ContactHistory h;
  h.shearForce = Vec3(1, 0, 0);
  h.lastOverlap = 1e-6;
  const ContactForce f = evaluate(*law, p, h, 1e-7);
  EXPECT_EQ(f.force, Vec3::Zero());
  EXPECT_EQ(f.elasticEnergy, 0.0);
  EXPECT_EQ(h.shearForce, Vec3::Zero());
}

TEST_P(EveryLaw, DampingAndFrictionNeverAddEnergy) {
  auto law = make(GetParam(), 0.3, 0.4);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1), pos(0, 1);
  ContactHistory h;
  for (int i = 0; i < 2000; ++i) {
    ContactPoint p;
    p.overlap = 1e-6 * (1 + pos(rng));
    p.normal = Vec3(u(rng), u(rng), u(rng)).normalized();
    p.relVelocity = Vec3(u(rng), u(rng), u(rng));
    p.effRadius = 0.01;
    p.effMass = 0.03;
    const ContactForce f = evaluate(*law, p, h, 1e-7);
    EXPECT_GE(f.dampingEnergy, -1e-18);
    EXPECT_GE(f.frictionEnergy, -1e-18);
    EXPECT_GE(f.normalForce, 0.0);
    // Coulomb: the tangential part never exceeds μ F_n.
    const Vec3 ft = f.force - f.force.dot(p.normal) * p.normal;
    EXPECT_LE(ft.norm(), 0.4 * f.normalForce * (1 + 1e-12) + 1e-15);
  }
}

TEST_P(EveryLaw, RecoversRequestedRestitution) {
  for (double e : {0.2, 0.5, 0.9, 1.0}) {
    auto law = make(GetParam(), e, 0.0);
    EXPECT_NEAR(bounce(*law, 0.0327, 0.01, 1.0), e, 5e-3 * e) << GetParam() << " e = " << e;
    // Velocity independent: a 10× faster impact gives the same e.
    EXPECT_NEAR(bounce(*law, 0.0327, 0.01, 10.0), e, 5e-3 * e) << GetParam() << " e = " << e;
  }
}

INSTANTIATE_TEST_SUITE_P(ContactLaws, EveryLaw, ::testing::ValuesIn(dem::contactLawNames()));

TEST(ContactLawRegistry, UnknownLawIsAConfigErrorWithSuggestion) {
  const auto cfg = common::Config::parse("law: hertz_mindlim\n", "s.yaml");
  try {
    cfg.choice("law", dem::contactLawNames());
    FAIL();
  } catch (const common::ConfigError& e) {
    // The registered names, whatever they are: a new law changes the list, not this test.
    EXPECT_EQ(std::string(e.what()),
              fmt::format("law = hertz_mindlim (s.yaml:1:6): unknown name; expected one of: {}. Did you mean "
                          "\"hertz_mindlin\"?",
                          fmt::join(dem::contactLawNames(), ", ")));
  }
}
