// Contract tests over every registered rod law (CONTRIBUTING.md): symmetric positive semi-definite stiffness,
// no force for rigid-body motions (translations and small rotations), action = −reaction, the axial
// stiffness k_l E₀A/L, and no dependence on the frame the law picks internally.
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "lattice/rod_law.hpp"

using lattice::Mat12;
using Vec3 = Eigen::Vector3d;
using Vec12 = Eigen::Matrix<double, 12, 1>;

namespace {

const lattice::RelativeStiffness kStiffness{1.0, 0.6, 0.6};
const lattice::RodSection kSection{3e10, 9e-6};

// Rigid motion of the rod a → b: translation t and small rotation w about the origin.
Vec12 rigid(const Vec3& a, const Vec3& b, const Vec3& t, const Vec3& w) {
  Vec12 u;
  u << t + w.cross(a), w, t + w.cross(b), w;
  return u;
}

}  // namespace

TEST(RodLawContract, SymmetricPositiveSemiDefinite) {
  for (const auto& name : lattice::rodLawNames()) {
    const auto law = lattice::makeRodLaw(name);
    const Mat12 K = law->stiffness(Vec3(1, 2, -0.5).normalized(), 0.003, kStiffness, kSection);
    EXPECT_LT((K - K.transpose()).norm(), 1e-12 * K.norm()) << name;
    Eigen::SelfAdjointEigenSolver<Mat12> eig(K);
    EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-10 * eig.eigenvalues().maxCoeff()) << name;
  }
}

TEST(RodLawContract, RigidMotionGivesNoForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const auto& name : lattice::rodLawNames()) {
    const auto law = lattice::makeRodLaw(name);
    for (int trial = 0; trial < 10; ++trial) {
      const Vec3 a(u(rng), u(rng), u(rng));
      const Vec3 b = a + 0.003 * Vec3(u(rng), u(rng), u(rng)).normalized();
      const Mat12 K = law->stiffness((b - a).normalized(), (b - a).norm(), kStiffness, kSection);
      const Vec12 f = K * rigid(a, b, Vec3(u(rng), u(rng), u(rng)), Vec3(u(rng), u(rng), u(rng)));
      // Relative to the force of a unit stretch: round-off only.
      EXPECT_LT(f.norm(), 1e-9 * K.norm()) << name;
    }
  }
}

TEST(RodLawContract, ForcesBalanceAndAxialStiffnessIsKlEAOverL) {
  for (const auto& name : lattice::rodLawNames()) {
    const auto law = lattice::makeRodLaw(name);
    const Vec3 e = Vec3(0.3, -0.4, 1.2).normalized();
    const double L = 0.004;
    const Mat12 K = law->stiffness(e, L, kStiffness, kSection);
    Vec12 u = Vec12::Zero();
    u.segment<3>(6) = 1e-7 * e;  // stretch by δ = 1e-7 m
    const Vec12 f = K * u;
    const double kn = kStiffness.kl * kSection.youngModulus * kSection.area / L;
    EXPECT_NEAR(f.segment<3>(6).dot(e), kn * 1e-7, 1e-12 * kn * 1e-7) << name;
    EXPECT_LT((f.segment<3>(0) + f.segment<3>(6)).norm(), 1e-12 * kn * 1e-7) << name;
    // Moments about the first node balance too: θ-moments plus the lever of the second node's force.
    const Vec3 m = f.segment<3>(3) + f.segment<3>(9) + (L * e).cross(f.segment<3>(6));
    EXPECT_LT(m.norm(), 1e-12 * kn * 1e-7 * L) << name;
  }
}

TEST(RodLawContract, StiffnessRotatesWithTheRod) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  Mat12 T = Mat12::Zero();
  for (int i = 0; i < 4; ++i) T.block<3, 3>(3 * i, 3 * i) = R;
  for (const auto& name : lattice::rodLawNames()) {
    const auto law = lattice::makeRodLaw(name);
    const Vec3 e = Vec3(0.2, 0.1, 1.0).normalized();
    const Mat12 K = law->stiffness(e, 0.003, kStiffness, kSection);
    const Mat12 Kr = law->stiffness(R * e, 0.003, kStiffness, kSection);
    EXPECT_LT((Kr - T * K * T.transpose()).norm(), 1e-10 * K.norm()) << name;
  }
}

// The beam's springs one by one: a transverse offset of the second node with both rotations zero is
// resisted by k_s = k_b E₀A/L; a relative twist by k_T = k_t E₀A²/(6L).
TEST(Beam, ShearAndTorsionSprings) {
  const auto law = lattice::makeRodLaw("beam");
  const double L = 0.003, EA = kSection.youngModulus * kSection.area;
  const Mat12 K = law->stiffness(Vec3::UnitZ(), L, kStiffness, kSection);
  Vec12 u = Vec12::Zero();
  u[6] = 1e-7;  // node b moves along x
  EXPECT_NEAR((K * u)[6], kStiffness.kb * EA / L * 1e-7, 1e-9 * EA / L * 1e-7);
  u.setZero();
  u[11] = 1e-4;  // node b twists about z
  EXPECT_NEAR((K * u)[11], kStiffness.kt * EA * kSection.area / (6 * L) * 1e-4, 1e-9 * EA * kSection.area / L * 1e-4);
}
