#include "dem/cluster.hpp"

#include "common/errors.hpp"

#include <cmath>
#include <fstream>

#include <gtest/gtest.h>

#include "dem/contact_queries.hpp"
#include "dem/simulation.hpp"

using dem::Vec3;

namespace {
constexpr double kPi = 3.14159265358979323846;
}

// Non-overlapping spheres are integrated exactly: V = Σ 4/3 π r³, I/m of a sphere 2/5 r², plus
// parallel-axis terms.
TEST(ClusterMass, SeparateSpheresAreExact) {
  const auto m = dem::unionMassProperties({Vec3(-1, 0, 0), Vec3(1, 0, 0)}, {0.5, 0.5});
  EXPECT_NEAR(m.volume, 2 * 4.0 / 3.0 * kPi * 0.125, 1e-15);
  EXPECT_NEAR(m.center.norm(), 0.0, 1e-15);
  EXPECT_NEAR(m.inertiaPerMass(0, 0), 0.4 * 0.25, 1e-14);
  EXPECT_NEAR(m.inertiaPerMass(1, 1), 0.4 * 0.25 + 1.0, 1e-14);
}

// Two unit spheres at distance d overlap in a lens of volume π (4 + d)(2 − d)² / 12 (counted once).
// The midpoint grid at resolution 160 (and 320) converges on it: the stated accuracy is ~1e-3.
TEST(ClusterMass, OverlapCountedOnceAgainstTheLens) {
  const double d = 1.0;
  const double exact = 2 * 4.0 / 3.0 * kPi - kPi * (4 + d) * (2 - d) * (2 - d) / 12;
  const auto coarse = dem::unionMassProperties({Vec3(0, 0, 0), Vec3(d, 0, 0)}, {1.0, 1.0}, 160);
  const auto fine = dem::unionMassProperties({Vec3(0, 0, 0), Vec3(d, 0, 0)}, {1.0, 1.0}, 320);
  EXPECT_NEAR(coarse.volume / exact, 1.0, 1e-3);
  EXPECT_LT(std::abs(fine.volume / exact - 1), std::abs(coarse.volume / exact - 1) + 1e-5);
  EXPECT_NEAR(coarse.center.x(), 0.5, 1e-9);  // symmetric
  EXPECT_NEAR(coarse.inertiaPerMass(1, 2), 0.0, 1e-9);
}

TEST(ClusterMass, CubeClusterMatchesTheCubeVolume) {
  const auto c = dem::makeCubeCluster(0.41, 3);
  ASSERT_EQ(c.centers.size(), 27u);
  ASSERT_TRUE(c.shape.has_value());
  EXPECT_NEAR(c.shape->volume, 0.41 * 0.41 * 0.41, 1e-15);
  EXPECT_NEAR(c.shape->inertiaPerMass(0, 0), 0.41 * 0.41 / 6, 1e-15);  // m a²/6
  const auto u = dem::unionMassProperties(c.centers, c.radii, 200);
  EXPECT_NEAR(u.volume / c.shape->volume, 1.0, 5e-3);
}

TEST(ClusterFile, RoundTripAndErrors) {
  const auto c = dem::makeCubeCluster(0.41, 2);
  const auto path = std::filesystem::temp_directory_path() / "cosim_cluster_test.yaml";
  dem::writeClusterFile(path, c);
  const auto back = dem::readClusterFile(path);
  ASSERT_EQ(back.centers.size(), 8u);
  EXPECT_NEAR((back.centers[7] - c.centers[7]).norm(), 0, 1e-12);
  EXPECT_NEAR(back.shape->inertiaPerMass(2, 2), c.shape->inertiaPerMass(2, 2), 1e-12);
  std::ofstream(path) << "spheres:\n  - [0, 0, 0, 0.1]\n  - [1, 0, 0]\n";
  try {
    dem::readClusterFile(path);
    FAIL();
  } catch (const common::ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "spheres[1] (" + path.string() + ":3:5): expected [x, y, z, r].");
  }
  std::filesystem::remove(path);
}

// Torque-free rotation of an asymmetric body (I = 1, 2, 3) spinning near its intermediate axis (the
// unstable one: it flips): angular momentum in the world frame is conserved to round-off and the
// kinetic energy ½ ω·L stays within 1e-4 of its start (symplectic splitting, bounded error).
TEST(ClusterRotation, FreeAsymmetricBodyConservesMomentumAndEnergy) {
  dem::Simulation sim;
  sim.interactions().addMaterial({"m", 1000, 1e9, 0.25});
  const Vec3 inertia(1, 2, 3), w0(0.01, 2.0, 0.01);
  sim.addCluster({Vec3(0, 0, 0)}, {0.1}, 0, 10.0, inertia, Vec3::Zero(), dem::Quat::Identity(), Vec3::Zero(), w0, false);
  sim.settings().dt = 1e-3;
  sim.initialize();
  const Vec3 L0 = totalAngularMomentum(sim.bodies());
  const double e0 = 0.5 * w0.dot(inertia.cwiseProduct(w0));
  double maxEnergyError = 0, minOmegaY = 10;
  for (int i = 0; i < 20000; ++i) {
    sim.step();
    const Vec3 w = sim.bodies().angularVelocity[0];
    maxEnergyError = std::max(maxEnergyError, std::abs(0.5 * w.dot(sim.bodies().angularMomentum[0]) - e0) / e0);
    minOmegaY = std::min(minOmegaY, (sim.bodies().orientation[0].conjugate() * w).y());
  }
  EXPECT_LT((totalAngularMomentum(sim.bodies()) - L0).norm() / L0.norm(), 1e-12);
  EXPECT_LT(maxEnergyError, 1e-4);
  EXPECT_LT(minOmegaY, -1.5);  // the Dzhanibekov flip happened: the body-frame spin reversed
}

namespace {
// The unit cube [0,1]³ as 12 outward triangles.
common::TriangleMesh unitCube() {
  common::TriangleMesh m;
  for (int i = 0; i < 8; ++i) m.nodes.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}
}  // namespace

// Divergence theorem on the unit cube: V = 1, centroid (½, ½, ½), I/m = 1/6 on the diagonal; the same
// with the triangles turned inside out.
TEST(ClusterMesh, CubeMassPropertiesAreExact) {
  auto cube = unitCube();
  for (int flip = 0; flip < 2; ++flip) {
    const auto m = dem::meshMassProperties(cube);
    EXPECT_NEAR(m.volume, 1.0, 1e-14);
    EXPECT_NEAR((m.center - Vec3::Constant(0.5)).norm(), 0.0, 1e-14);
    EXPECT_NEAR((m.inertiaPerMass - Eigen::Matrix3d::Identity() / 6).norm(), 0.0, 1e-14);
    for (auto& t : cube.triangles) std::swap(t[1], t[2]);
  }
  EXPECT_TRUE(dem::insideMesh(cube, Vec3(0.5, 0.2, 0.9)));
  EXPECT_FALSE(dem::insideMesh(cube, Vec3(1.2, 0.5, 0.5)));
  EXPECT_FALSE(dem::insideMesh(cube, Vec3(-0.01, 0.5, 0.5)));
}

TEST(ClusterMesh, FillingACubeMeshMatchesItsVolume) {
  const auto c = dem::fillMesh(unitCube(), 64);
  EXPECT_EQ(c.centers.size(), 64u);  // 4³ lattice points inside
  const auto u = dem::unionMassProperties(c.centers, c.radii, 200);
  EXPECT_NEAR(u.volume, 1.0, 5e-3);
  EXPECT_NEAR((u.center - Vec3::Constant(0.5)).norm(), 0.0, 1e-9);
}
