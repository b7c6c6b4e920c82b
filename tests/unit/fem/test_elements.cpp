// Contract tests over every element type (CONTRIBUTING.md): the tangent is the derivative of the internal
// forces, rigid-body motion gives zero force, the stiffness is symmetric, forces balance (Σ f = 0).
#include <random>

#include <gtest/gtest.h>

#include "element_registry.hpp"
#include "elements/membrane_tri3.hpp"
#include "elements/tet4.hpp"
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
  std::vector<Vec3> tet{{0, 0, 0}, {1.0, 0.1, 0.0}, {0.2, 0.9, 0.1}, {0.1, 0.2, 1.1}};
  out.push_back({"tet4", std::make_unique<fem::Tet4>(std::vector<std::uint32_t>{0, 1, 2, 3}, tet,
                                                     fem::Tet4::Params{2e11, 0.3, 7800}),
                 tet});
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

// Patch test: a homogeneous deformation gradient F gives the stress S = λ tr(E) I + 2μ E of that F in
// every element, and the critical step of the lumped tet matches its closed-form bound.
TEST(ElementContract, Tet4ReproducesAHomogeneousStrainExactly) {
  std::vector<Vec3> tet{{0, 0, 0}, {1.0, 0.1, 0.0}, {0.2, 0.9, 0.1}, {0.1, 0.2, 1.1}};
  fem::Tet4 t({0, 1, 2, 3}, tet, fem::Tet4::Params{2e11, 0.3, 7800});
  Eigen::Matrix3d H;
  H << 1e-3, 2e-4, -1e-4, 0.5e-3, -2e-3, 3e-4, 1e-4, 0.0, 1.5e-3;
  std::vector<double> u;
  for (const auto& x : tet) {
    const Vec3 d = H * x;
    u.insert(u.end(), {d.x(), d.y(), d.z()});
  }
  std::vector<double> s(6);
  t.stress(u, s);
  const Eigen::Matrix3d E = 0.5 * (H + H.transpose() + H.transpose() * H);
  const double lambda = 2e11 * 0.3 / (1.3 * 0.4), mu = 2e11 / 2.6;
  const Eigen::Matrix3d S = lambda * E.trace() * Eigen::Matrix3d::Identity() + 2 * mu * E;
  const double expected[6] = {S(0, 0), S(1, 1), S(2, 2), S(0, 1), S(1, 2), S(0, 2)};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(s[static_cast<std::size_t>(k)], expected[k], 1e-6 * S.norm());
}

TEST(ElementContract, RigidMotionGivesOnlyThePrestressForces) {
  for (auto& c : cases()) {
    const auto x0 = flat(c.reference);
    const auto f0 = forces(*c.element, x0, x0);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    std::vector<Vec3> moved;
    for (const auto& p : c.reference) moved.push_back(R * p + Vec3(3, -1, 2));
    const auto x1 = flat(moved);
    const auto f1 = forces(*c.element, x1, x0);
    // Round-off bound: strains of a finite rotation are differences of O(1) terms, so forces carry an
    // error of ~ε ‖K‖ ‖u‖.
    std::vector<double> zero(x0.size(), 0.0);
    std::vector<fem::Triplet> t;
    c.element->tangent(zero, t);
    double kmax = 0, umax = 0;
    for (const auto& tr : t) kmax = std::max(kmax, std::abs(tr.value()));
    for (std::size_t i = 0; i < x0.size(); ++i) umax = std::max(umax, std::abs(x1[i] - x0[i]));
    // Rotated reference state: the same (prestress) forces, rotated.
    for (std::size_t i = 0; i < c.reference.size(); ++i) {
      const Vec3 a(f0[3 * i], f0[3 * i + 1], f0[3 * i + 2]), b(f1[3 * i], f1[3 * i + 1], f1[3 * i + 2]);
      EXPECT_NEAR((R * a - b).norm(), 0.0, 1e-13 * kmax * umax + 1e-9 * a.norm()) << c.name;
    }
  }
}

// The stable step of the current state, over every element type: a rigid rotation leaves it at the
// reference value (tensile prestress aside), a uniform stretch λ shortens it as the tangent of the
// nominal stress grows (d(λS)/dλ = S + λ² E), and a squeezed tet reports det F.
TEST(ElementContract, CurrentStableStepFollowsTheStretch) {
  // Truss, exact: L / √((E λ² + S)/ρ), S = E (λ² − 1)/2 + σ₀.
  std::vector<Vec3> bar{{0, 0, 0}, {2.0, 0, 0}};
  const double E = 2e11, rho = 7800, sigma0 = 1e6;
  fem::Truss truss({0, 1}, bar, fem::Truss::Params{E, rho, 1e-4, sigma0, false});
  EXPECT_NEAR(truss.current(std::vector<double>(6, 0.0)).criticalTimeStep, 2.0 / std::sqrt((E + sigma0) / rho), 1e-15);
  const double lambda = 1.1;
  const std::vector<double> pulled{0, 0, 0, 2.0 * (lambda - 1), 0, 0};
  const auto stretched = truss.current(pulled);
  const double S = E * (lambda * lambda - 1) / 2 + sigma0;
  EXPECT_NEAR(stretched.criticalTimeStep, 2.0 / std::sqrt((E * lambda * lambda + S) / rho), 1e-15);
  EXPECT_NEAR(stretched.jacobian, lambda, 1e-14);

  // Membrane under an equal biaxial stretch λ: c² = (E/(1−ν²) λ² + S)/ρ, S = E/(1−ν) (λ² − 1)/2 + σ₀.
  std::vector<Vec3> tri{{0, 0, 0}, {1.0, 0, 0}, {0, 1.0, 0}};
  const double nu = 0.3, h = 1.0 / std::sqrt(2.0);  // smallest altitude
  fem::MembraneTri3 membrane({0, 1, 2}, tri, fem::MembraneTri3::Params{5e7, nu, 80, 0.008, 2e3});
  std::vector<double> u;
  for (const auto& x : tri) u.insert(u.end(), {(lambda - 1) * x.x(), (lambda - 1) * x.y(), 0.0});
  const auto m = membrane.current(u);
  const double Sm = 5e7 / (1 - nu) * (lambda * lambda - 1) / 2 + 2e3;
  EXPECT_NEAR(m.criticalTimeStep, 0.827 * h / std::sqrt((5e7 / (1 - nu * nu) * lambda * lambda + Sm) / 80), 1e-12);
  EXPECT_NEAR(m.jacobian, lambda * lambda, 1e-12);  // area ratio

  // Tet: at rest its exact bound; squeezed flat through itself, det F < 0.
  std::vector<Vec3> tet{{0, 0, 0}, {1.0, 0.1, 0.0}, {0.2, 0.9, 0.1}, {0.1, 0.2, 1.1}};
  fem::Tet4 t({0, 1, 2, 3}, tet, fem::Tet4::Params{2e11, 0.3, 7800});
  EXPECT_DOUBLE_EQ(t.current(std::vector<double>(12, 0.0)).criticalTimeStep, t.criticalTimeStep());
  std::vector<double> squeeze;
  for (const auto& x : tet) squeeze.insert(squeeze.end(), {0.0, 0.0, -1.5 * x.z()});  // z → −z/2
  EXPECT_NEAR(t.current(squeeze).jacobian, -0.5, 1e-12);
}

// Each element says how its cells are written, and only membranes carry a prestress a static solve may
// continue on (Model::solveStatic asks for the capability, never for the type).
TEST(ElementContract, DeclaresItsOutputCellAndCapabilities) {
  for (const auto& c : cases()) {
    const std::size_t cellNodes = static_cast<std::size_t>(c.element->cellType());
    EXPECT_EQ(cellNodes, static_cast<std::size_t>(c.element->nodesPerElement())) << c.name;
    EXPECT_EQ(c.element->prestressed() != nullptr, c.name == "membrane_tri3") << c.name;
  }
  auto membrane = std::move(cases().front().element);
  membrane->prestressed()->setPrestress(5e3);
  EXPECT_EQ(membrane->prestressed()->prestress(), 5e3);
}

// Every registered type has a case above (so its contract is tested) and its registry entry builds it
// from a scene entry's keys.
TEST(ElementContract, EveryRegisteredTypeIsCoveredAndBuiltByItsEntry) {
  const auto all = cases();
  for (const fem::ElementType& t : fem::elementTypes().entries()) {
    const auto c = std::find_if(all.begin(), all.end(), [&](const Case& k) { return k.name == t.name; });
    ASSERT_NE(c, all.end()) << t.name << " is registered but has no contract case";
    const std::vector<std::uint32_t> conn(static_cast<std::size_t>(c->element->nodesPerElement()));
    std::vector<std::uint32_t> nodes(conn.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) nodes[i] = static_cast<std::uint32_t>(i);
    const auto keys = common::Config::parse("{thickness: 0.01, area: 1.0e-4, prestress: 1000.0}");
    const fem::ElementMaterial steel{2e11, 0.3, 7800};
    auto e = t.make(keys, nodes, c->reference, steel);
    EXPECT_EQ(e->name(), t.name);
    EXPECT_EQ(e->size(), 1u);
  }
}
