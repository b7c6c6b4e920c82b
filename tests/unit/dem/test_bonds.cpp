// Cohesive bonds (issue 27, Kozicki & Donzé 2008 §2.1): a bond breaks at its strength — in tension at σ_t A, in shear
// at c A + μ F_n — the broken pair becomes a frictional contact, and the energy the bond held is booked;
// Cundall local damping takes the fraction λ of the work it damps.
#include <cmath>
#include <cstring>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "dem/contact_law.hpp"
#include "dem/contact_queries.hpp"
#include "dem/simulation.hpp"

using dem::Vec3;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kR = 0.01, kE = 1e8, kSigmaT = 1e5, kCohesion = 2e5, kMu = 0.5, kAlpha = 0.25;

dem::Material rock() { return {"rock", 2500, kE, 0.25}; }

std::unique_ptr<dem::ContactLaw> cohesive(double tensile, double cohesion, double reach = 1.0) {
  const auto cfg = common::Config::parse(
      fmt::format("{{law: cohesive_frictional, friction: {}, tensile_strength: {}, cohesion: {}, "
                  "shear_stiffness_ratio: {}, interaction_radius: {}}}",
                  kMu, tensile, cohesion, kAlpha, reach),
      "test.yaml");
  return dem::makeContactLaw("cohesive_frictional", cfg, rock(), rock());
}

// Sphere 0 fixed at the origin, sphere 1 fixed at `position` moving at `velocity` (both prescribed).
std::unique_ptr<dem::Simulation> pair(const Vec3& position, const Vec3& velocity, double dt,
                                       std::unique_ptr<dem::ContactLaw> law) {
  auto owned = std::make_unique<dem::Simulation>();
  dem::Simulation& sim = *owned;
  const auto m = sim.interactions().addMaterial(rock());
  sim.interactions().set(m, m, std::move(law));
  addSphere(sim, Vec3::Zero(), kR, m, Vec3::Zero(), Vec3::Zero(), true);
  addSphere(sim, position, kR, m, velocity, Vec3::Zero(), true);
  sim.settings().dt = dt;
  sim.settings().gravity = Vec3::Zero();
  sim.initialize();
  return owned;
}

// k_n = 2 E_h R* with E_h = E for one material, R* = r/2; area π r².
const double kn = 2.0 * kE * kR / 2.0, area = kPi * kR * kR;

}  // namespace

TEST(DemBonds, TensionBreaksAtTheTensileStrength) {
  const double strength = kSigmaT * area;  // 31.4 N
  // 1.2 million steps to the break: the peak is resolved to k_n v dt = 1e-6 of the strength.
  const double dt = 1e-6, v = 1e-6 * strength / kn / dt;
  auto owner = pair(Vec3(2 * kR, 0, 0), Vec3(v, 0, 0), dt, cohesive(kSigmaT, kCohesion));
  dem::Simulation& sim = *owner;
  ASSERT_EQ(sim.bonds().size(), 1u);
  EXPECT_EQ(contactCounts(sim).pairCandidates, 0) << "a bonded pair is no contact candidate";
  double peak = 0.0;
  while (sim.bonds().size() == 1 && sim.steps() < 2'000'000) {
    sim.step();
    peak = std::max(peak, sim.bodies().force[0].x());  // the bond pulls sphere 0 towards sphere 1 (+x)
  }
  ASSERT_EQ(sim.bonds().broken(), 1);
  EXPECT_LE(peak, strength);
  EXPECT_NEAR(peak / strength, 1.0, 1.01e-6);
  // Stretched by strength / k_n when it broke: all of ½ T² / k_n released (the pair is apart, nothing
  // replaces it).
  EXPECT_NEAR(sim.energy().bondFracture / (0.5 * strength * strength / kn), 1.0, 3e-6);
  sim.step();
  EXPECT_EQ(sim.bodies().force[0].norm(), 0.0) << "apart and unbonded: no force";
}

TEST(DemBonds, ShearBreaksAtCohesionPlusFrictionTimesNormalForce) {
  // Pressed by δ = 1e-5 m (F_n = 10 N), then sheared along y.
  const double delta = 1e-5;
  const double strength = kCohesion * area + kMu * kn * delta;
  const double ks = kAlpha * kn, dt = 1e-6, v = 1e-6 * strength / ks / dt;
  auto owner = pair(Vec3(2 * kR - delta, 0, 0), Vec3(0, v, 0), dt, cohesive(kSigmaT, kCohesion));
  dem::Simulation& sim = *owner;
  ASSERT_EQ(sim.bonds().size(), 1u);
  double shear = 0.0, normal = 0.0;
  while (sim.bonds().size() == 1 && sim.steps() < 2'000'000) {
    sim.step();
    if (sim.bonds().size() == 0) break;
    // Force on sphere 0 split along the normal (from sphere 1 to sphere 0) and across it.
    const Vec3 x0 = sim.bodies().position[0], x1 = sim.bodies().position[1];
    const Vec3 n = (x0 - x1).normalized();
    const Vec3 f = sim.bodies().force[0];
    normal = f.dot(n);
    shear = (f - normal * n).norm();
  }
  ASSERT_EQ(sim.bonds().broken(), 1);
  // The strength at the last bonded step, from that step's normal force (the normal turned a little as
  // the spheres slid past each other).
  const double limit = kCohesion * area + kMu * normal;
  EXPECT_LE(shear, limit);
  EXPECT_NEAR(shear / limit, 1.0, 1.5e-6);
  EXPECT_NEAR(limit / strength, 1.0, 0.05);
  // Still pressed: the pair is a frictional contact now, its shear force capped at μ F_n.
  sim.step();
  EXPECT_EQ(contactCounts(sim).pairs, 1);
  const Vec3 x0 = sim.bodies().position[0], x1 = sim.bodies().position[1];
  const Vec3 n = (x0 - x1).normalized();
  const Vec3 f = sim.bodies().force[0];
  EXPECT_GT(f.dot(n), 0.0);
  EXPECT_LE((f - f.dot(n) * n).norm(), kMu * f.dot(n) * (1 + 1e-12));
}

TEST(DemBonds, BondsFormWithinTheInteractionRadiusAtRest) {
  // A gap of 5 % of the diameter: bonded with interaction_radius 1.1, at rest there; not with 1.0.
  const Vec3 apart(2 * kR * 1.05, 0, 0);
  auto farOwner = pair(apart, Vec3::Zero(), 1e-6, cohesive(kSigmaT, kCohesion, 1.0));
  dem::Simulation& far = *farOwner;
  EXPECT_EQ(far.bonds().size(), 0u);
  auto nearOwner = pair(apart, Vec3::Zero(), 1e-6, cohesive(kSigmaT, kCohesion, 1.1));
  dem::Simulation& near = *nearOwner;
  ASSERT_EQ(near.bonds().size(), 1u);
  near.step();
  EXPECT_EQ(near.bodies().force[0].norm(), 0.0);
  EXPECT_EQ(near.energy().elastic, 0.0);
  // No strengths, no bonds: the law is then purely frictional.
  EXPECT_EQ(pair(Vec3(2 * kR, 0, 0), Vec3::Zero(), 1e-6, cohesive(0.0, 0.0))->bonds().size(), 0u);
}

TEST(DemBonds, FreeBondedPairOscillatesAndTheLedgerCloses) {
  // Two free spheres, bonded, flying apart at 1 mm/s each: the bond stops and reverses them, in tension
  // then compression, and stores and returns the energy (no dashpots, e = 1).
  dem::Simulation sim;
  const auto m = sim.interactions().addMaterial(rock());
  sim.interactions().set(m, m, cohesive(1e9, 1e9));
  addSphere(sim, Vec3::Zero(), kR, m, Vec3(-1e-3, 0, 0), Vec3::Zero(), false);
  addSphere(sim, Vec3(2 * kR, 0, 0), kR, m, Vec3(1e-3, 0, 0), Vec3::Zero(), false);
  const double mass = 2500 * 4.0 / 3.0 * kPi * kR * kR * kR;
  const double period = 2 * kPi * std::sqrt(0.5 * mass / kn);  // reduced mass m/2
  sim.settings().dt = period / 2000;
  sim.settings().gravity = Vec3::Zero();
  sim.initialize();
  const double e0 = sim.energy().total();
  double minGap = 0, maxGap = 0;
  for (int i = 0; i < 3000; ++i) {
    sim.step();
    const double gap = (sim.bodies().position[1] - sim.bodies().position[0]).norm() - 2 * kR;
    minGap = std::min(minGap, gap), maxGap = std::max(maxGap, gap);
    ASSERT_NEAR(sim.energy().residual(sim.initialEnergy()) / e0, 0.0, 1e-5);
  }
  // Amplitude of the relative motion: v_rel / ω = 2 mm/s × period / 2π, both ways.
  const double amplitude = 2e-3 * period / (2 * kPi);
  EXPECT_NEAR(maxGap / amplitude, 1.0, 1e-3);
  EXPECT_NEAR(-minGap / amplitude, 1.0, 1e-3);
  EXPECT_EQ(sim.bonds().broken(), 0);
  EXPECT_EQ(contactCounts(sim).pairs, 0);
}

TEST(DemLocalDamping, TakesTheFractionLambdaOfAnUnloadingSpring) {
  // A sphere pressed δ₀ into a plane, released without gravity: the spring pushes it out while local
  // damping removes λ |F| sign(v) — the sphere leaves with (1 − λ) ½ k δ₀², and the ledger books λ ½ k δ₀²
  // as Cundall dissipation.
  const double lambda = 0.2, k = 1e5, delta0 = 1e-4;
  dem::Simulation sim;
  const auto m = sim.interactions().addMaterial(rock());
  const auto cfg = common::Config::parse(fmt::format("{{law: linear_spring_dashpot, stiffness_normal: {}}}", k), "t.yaml");
  sim.interactions().set(m, m, dem::makeContactLaw("linear_spring_dashpot", cfg, rock(), rock()));
  addSphere(sim, Vec3(0, 0, kR - delta0), kR, m, Vec3::Zero(), Vec3::Zero(), false);
  sim.planeWalls().add({"floor", Vec3::Zero(), Vec3::UnitZ(), Vec3::Zero(), m});
  const double mass = 2500 * 4.0 / 3.0 * kPi * kR * kR * kR;
  sim.settings().dt = 0.5 * kPi * std::sqrt(mass / k) / 20000;
  sim.settings().gravity = Vec3::Zero();
  sim.settings().localDamping = lambda;
  sim.initialize();
  const double stored = 0.5 * k * delta0 * delta0;
  EXPECT_NEAR(sim.energy().elastic / stored, 1.0, 1e-12);
  while (sim.bodies().position[0].z() < kR + 1e-6) sim.step();
  sim.step();
  EXPECT_NEAR(sim.energy().kinetic / stored, 1.0 - lambda, 2e-4);
  EXPECT_NEAR(sim.energy().cundall / stored, lambda, 2e-4);
  EXPECT_NEAR(sim.energy().residual(sim.initialEnergy()) / stored, 0.0, 1e-4);
}

TEST(DemBonds, NothingMoreIsBookedOnceTheLastBondBroke) {
  // Pulled apart fast: the bond breaks within a few hundred steps; afterwards the ledger stays put.
  const double strength = kSigmaT * area, dt = 1e-6, v = 1e-3 * strength / kn / dt;
  auto owner = pair(Vec3(2 * kR, 0, 0), Vec3(v, 0, 0), dt, cohesive(kSigmaT, kCohesion));
  dem::Simulation& sim = *owner;
  while (sim.bonds().broken() == 0 && sim.steps() < 10000) sim.step();
  ASSERT_EQ(sim.bonds().broken(), 1);
  const double released = sim.energy().bondFracture, damping = sim.energy().damping;
  for (int i = 0; i < 100; ++i) sim.step();
  EXPECT_EQ(sim.energy().bondFracture, released);
  EXPECT_EQ(sim.energy().damping, damping);
  EXPECT_EQ(sim.energy().elastic, 0.0);
}

TEST(DemBonds, ACheckpointRepeatsBondsBreakingBitForBit) {
  // A 4 × 4 × 4 block of touching spheres, bonded weakly, dropped on a floor: bonds break at the
  // impact. Saved before, stepped through it, restored and stepped again: the same bits.
  dem::Simulation sim;
  const auto m = sim.interactions().addMaterial(rock());
  sim.interactions().set(m, m, cohesive(2e4, 2e4));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k)
        addSphere(sim, Vec3(2 * kR * i, 2 * kR * j, 0.02 + kR + 2 * kR * k), kR, m, Vec3(0, 0, -1.5), Vec3::Zero(), false);
  sim.planeWalls().add({"floor", Vec3::Zero(), Vec3::UnitZ(), Vec3::Zero(), m});
  const double mass = 2500 * 4.0 / 3.0 * kPi * kR * kR * kR;
  sim.settings().dt = 0.05 * std::sqrt(mass / (2 * kn));
  sim.settings().gravity = Vec3(0, 0, -9.81);
  sim.initialize();
  ASSERT_EQ(sim.bonds().size(), 144u);  // 3 · 4 · 4 · 3 neighbours along the axes
  const auto saved = sim.saveCheckpoint();
  auto run = [&] {
    std::vector<double> bits;
    for (int i = 0; i < 8000; ++i) sim.step();
    for (std::size_t b = 0; b < sim.bodies().size(); ++b)
      for (int c = 0; c < 3; ++c) bits.push_back(sim.bodies().position[b][c]), bits.push_back(sim.bodies().velocity[b][c]);
    const dem::EnergyLedger& e = sim.energy();
    bits.insert(bits.end(), {e.elastic, e.damping, e.friction, e.bondFracture, static_cast<double>(sim.bonds().broken())});
    return bits;
  };
  const auto first = run();
  EXPECT_GT(sim.bonds().broken(), 0) << "the impact breaks bonds";
  EXPECT_LT(std::abs(sim.energy().residual(sim.initialEnergy())) / sim.initialEnergy(), 1e-3);
  sim.restoreCheckpoint(*saved);
  const auto second = run();
  ASSERT_EQ(first.size(), second.size());
  for (std::size_t i = 0; i < first.size(); ++i) ASSERT_EQ(std::memcmp(&first[i], &second[i], sizeof(double)), 0) << i;
}
