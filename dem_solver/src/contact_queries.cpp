#include "dem/contact_queries.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "body_stiffness.hpp"
#include "contact_set.hpp"
#include "mesh_walls.hpp"
#include "plane_walls.hpp"
#include "sphere_pairs.hpp"

namespace dem {

std::vector<NetworkLine> contactNetwork(const Simulation& sim) {
  std::vector<NetworkLine> out;
  const ContactSet& pairs = sim.components().pairs.contacts();
  const auto& x = sim.spheres().position;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!(pairs.overlap[i] > 0.0)) continue;
    const auto t = sim.interactions().laws()[static_cast<std::size_t>(pairs.law[i])]->normalTangent(pairs.effRadius[i], pairs.effMass[i],
                                                                                    pairs.overlap[i]);
    out.push_back({x[pairs.a[i]], x[pairs.b[i]], t.force});
  }
  for (const auto& line : sim.bonds().lines()) out.push_back({x[line.a], x[line.b], line.normalForce});
  return out;
}

double contactStableStep(const Simulation& sim) {
  const Bodies& bodies = sim.bodies();
  const Spheres& spheres = sim.spheres();
  BodyStiffness stiffness(bodies.size());
  sim.components().pairs.addStiffness(sim.interactions().laws(), spheres, bodies, stiffness);
  for (const Bond& bond : sim.bonds().bonds())  // as a touching pair, in tension too
    stiffness.addPair(bodies, spheres.body[bond.a], spheres.body[bond.b], bond.kn, bond.gammaN);
  sim.components().planes.addStiffness(sim.interactions().laws(), spheres, stiffness);
  sim.components().meshes.addStiffness(sim.interactions().laws(), spheres, stiffness);
  const std::vector<double>& k = stiffness.k;
  const std::vector<double>& c = stiffness.c;
  double dt = std::numeric_limits<double>::infinity();
  const auto n = static_cast<std::ptrdiff_t>(bodies.size());
#pragma omp parallel for schedule(static) reduction(min : dt) if (n > kParallelMin)
  for (std::ptrdiff_t b = 0; b < n; ++b) {
    if (bodies.fixed[b] || !(k[b] > 0.0)) continue;
    const double m = bodies.mass[b], omega = std::sqrt(k[b] / m), zeta = c[b] / (2.0 * std::sqrt(k[b] * m));
    dt = std::min(dt, 2.0 / omega * (std::sqrt(1.0 + zeta * zeta) - zeta));
  }
  return dt;
}

std::vector<double> planeContactStiffness(const Simulation& sim) {
  return sim.components().planes.contactStiffness(sim.interactions().laws());
}

ContactCounts contactCounts(const Simulation& sim) {
  ContactCounts c;
  const ContactSet& ss = sim.components().pairs.contacts();
  c.pairCandidates = static_cast<std::int64_t>(ss.size());
  for (std::size_t k = 0; k < ss.size(); ++k) c.pairs += ss.overlap[k] > 0.0;
  for (const ContactPoint& p : sim.components().planes.contacts().point) c.walls += p.overlap > 0.0;
  c.walls += static_cast<std::int64_t>(sim.components().meshes.contacts().contacts.size());
  return c;
}

std::tuple<std::uint32_t, std::uint32_t, double> largestSphereOverlap(const Simulation& sim) {
  std::tuple<std::uint32_t, std::uint32_t, double> worst{0, 0, -std::numeric_limits<double>::infinity()};
  const SpherePairs& pairs = sim.components().pairs;
  const ContactSet& ss = pairs.contacts();
  for (std::size_t k = 0; k < ss.size(); ++k)
    if (const double overlap = pairs.overlap(k, sim.spheres()); overlap > std::get<2>(worst))
      worst = {ss.a[k], ss.b[k], overlap};
  return worst;
}

Vec3 totalAngularMomentum(const Bodies& bodies) {
  Vec3 L = Vec3::Zero();
  for (std::size_t b = 0; b < bodies.size(); ++b)
    if (!bodies.fixed[b]) L += bodies.mass[b] * bodies.position[b].cross(bodies.velocity[b]) + bodies.angularMomentum[b];
  return L;
}

}  // namespace dem
