// The Model API a coupled participant uses: forces set from outside (coupledForce) act like loads in
// statics and dynamics, and the support forces balance them.
#include <cmath>

#include <gtest/gtest.h>

#include "elements/truss.hpp"
#include "fem/mesh.hpp"
#include "fem/model.hpp"

TEST(FemModel, CoupledForcesActLikeLoadsAndSupportsBalanceThem) {
  const fem::Mesh mesh = fem::lineMesh({0, 0, 0}, {2, 0, 0}, 10);
  fem::Model model;
  model.reference = mesh.nodes;
  model.blocks.push_back(std::make_unique<fem::Truss>(mesh.group("line")->connectivity, model.reference,
                                                      fem::Truss::Params{2e11, 7800, 1e-4, 0.0, false}));
  model.fixed.assign(model.dofs(), 0);
  for (auto n : mesh.group("line")->nodes) model.fixed[3 * n + 1] = model.fixed[3 * n + 2] = 1;
  const auto start = mesh.group("start")->nodes.front(), end = mesh.group("end")->nodes.front();
  for (int k = 0; k < 3; ++k) model.fixed[3 * start + static_cast<unsigned>(k)] = 1;
  model.finalize();
  model.coupledForce[3 * end] = 5000.0;  // set from outside after finalize(), as a coupler does
  model.solveStatic(fem::StaticSettings{});
  double lambda = 1.0;  // SVK bar: (λ³ − λ) EA/2 = F
  for (int k = 0; k < 50; ++k) lambda -= (lambda * lambda * lambda - lambda - 2 * 5000.0 / 2e7) / (3 * lambda * lambda - 1);
  EXPECT_NEAR(model.displacement()[3 * end], 2.0 * (lambda - 1), 1e-12);
  EXPECT_NEAR(model.supportForce(start).x(), -5000.0, 1e-6);
  // Dynamics: released from rest at t = 0 with the force doubled, the end accelerates at first by
  // F/m_end and moves ½ a dt² in the first step (the first kick is half a step).
  model.initializeExplicit(0.2 * model.criticalTimeStep());
  model.coupledForce[3 * end] = 10000.0;
  const double u0 = model.displacement()[3 * end];
  model.stepExplicit();
  const double m = model.nodeMass()[end];
  EXPECT_NEAR((model.displacement()[3 * end] - u0) / (model.dt() * model.dt()), 0.5 * 5000.0 / m, 1e-6 * 5000.0 / m);
}
