// Contract tests over every element type (STYLE.md): the tangent is the derivative of the internal
// forces, rigid-body motion gives zero force, the stiffness is symmetric, forces balance (Σ f = 0).
#include <random>

#include <gtest/gtest.h>

#include "elements/membrane_tri3.hpp"
#include "elements/truss.hpp"

using fem::Vec3;

namespace {

struct Case {
  std::string name;
  std::unique_ptr<fem::Element> element;
  std::vector<Vec3> reference;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  std::vector<Vec3> tri{{0, 0, 0}, {1.2, 0.1, 0.05}, {0.3, 0.9, -0.1}};
  out.push_back({"membrane_tri3", std::make_unique<fem::MembraneTri3>(std::vector<std::uint32_t>{0, 1, 2}, tri,
                                                                     fem::MembraneTri3::Params{5e7, 0.3, 80, 0.008, 2e3}),
                 tri});
  std::vector<Vec3> bar{{0, 0, 0}, {1.0, 0.5, 0.2}};
  out.push_back({"truss", std::make_unique<fem::Truss>(std::vector<std::uint32_t>{0, 1}, bar,
                                                       fem::Truss::Params{2e11, 7800, 1e-4, 1e6, false}),
                 bar});
  return out;
}

std::vector<double> flat(const std::vector<Vec3>& p) {
  std::vector<double> x;
  for (const auto& v : p) x.insert(x.end(), {v.x(), v.y(), v.z()});
  return x;
}

// Forces at positions x (the element takes displacements from its reference).
std::vector<double> forces(const fem::Element& e, const std::vector<double>& x, const std::vector<double>& x0) {
  std::vector<double> u(x.size()), slots(3 * e.connectivity().size());
  for (std::size_t i = 0; i < x.size(); ++i) u[i] = x[i] - x0[i];
  e.internalForces(u, slots);
  return slots;  // one element whose nodes are 0..n-1: slots are the nodal forces
}

}  // namespace

TEST(ElementContract, TangentIsTheDerivativeOfTheInternalForces) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  for (auto& c : cases()) {
    const auto x0 = flat(c.reference);
    auto x = x0;
    for (auto& v : x) v += u(rng);  // a deformed state
    std::vector<double> disp(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) disp[i] = x[i] - x0[i];
    std::vector<fem::Triplet> t;
    c.element->tangent(disp, t);
    const int n = static_cast<int>(x.size());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
    for (const auto& tr : t) K(tr.row(), tr.col()) += tr.value();
    const auto f0 = forces(*c.element, x, x0);
    double scale = 0;
    for (double v : f0) scale = std::max(scale, std::abs(v));
    const double h = 1e-7;
    for (int j = 0; j < n; ++j) {
      auto xp = x, xm = x;
      xp[static_cast<std::size_t>(j)] += h;
      xm[static_cast<std::size_t>(j)] -= h;
      const auto fp = forces(*c.element, xp, x0), fm = forces(*c.element, xm, x0);
      for (int i = 0; i < n; ++i)
        EXPECT_NEAR(K(i, j), (fp[static_cast<std::size_t>(i)] - fm[static_cast<std::size_t>(i)]) / (2 * h),
                    1e-6 * K.cwiseAbs().maxCoeff())
            << c.name << " K(" << i << "," << j << ")";
    }
    EXPECT_NEAR((K - K.transpose()).norm(), 0.0, 1e-9 * K.norm()) << c.name;
    for (int k = 0; k < 3; ++k) {  // Σ f = 0 per component
      double s = 0;
      for (int i = k; i < n; i += 3) s += f0[static_cast<std::size_t>(i)];
      EXPECT_NEAR(s, 0.0, 1e-9 * scale) << c.name;
    }
  }
}

TEST(ElementContract, RigidMotionGivesOnlyThePrestressForces) {
  for (auto& c : cases()) {
    const auto x0 = flat(c.reference);
    const auto f0 = forces(*c.element, x0, x0);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    std::vector<Vec3> moved;
    for (const auto& p : c.reference) moved.push_back(R * p + Vec3(3, -1, 2));
    const auto f1 = forces(*c.element, flat(moved), x0);
    // Rotated reference state: the same (prestress) forces, rotated.
    for (std::size_t i = 0; i < c.reference.size(); ++i) {
      const Vec3 a(f0[3 * i], f0[3 * i + 1], f0[3 * i + 2]), b(f1[3 * i], f1[3 * i + 1], f1[3 * i + 2]);
      EXPECT_NEAR((R * a - b).norm(), 0.0, 1e-9 * (1 + a.norm())) << c.name;
    }
  }
}
