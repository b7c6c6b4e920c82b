// The time steps a DEM scene may take (dem/time_steps.hpp), from its bodies, walls and laws.
#include "dem/time_steps.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/simulation.hpp"

namespace dem {

double criticalTimeStep(const Simulation& sim) {
  const Spheres& S = sim.spheres();
  const Bodies& B = sim.bodies();
  double dt = std::numeric_limits<double>::infinity();
  const auto nm = sim.interactions().materials().size();
  for (std::size_t s = 0; s < S.size(); ++s) {
    // A bridging weight scales a body's mass and its bonds alike: its step is the unweighted one.
    const auto b = S.body[s];
    const double m = B.mass[b] / (sim.settings().bridging ? sim.settings().bridging->massWeight(B.position[b]) : 1.0);
    for (std::size_t other = 0; other < nm; ++other)
      if (const ContactLaw* law = sim.interactions().law(S.material[s], static_cast<std::uint32_t>(other)))
        dt = std::min(dt, law->criticalTimeStep(sim.interactions().materials()[S.material[s]], S.radius[s], 0.5 * m));
  }
  return dt;
}

double contactDuration(const Simulation& sim, double approachSpeed) {
  const Spheres& S = sim.spheres();
  const Bodies& B = sim.bodies();
  if (!(approachSpeed > 0.0)) return std::numeric_limits<double>::infinity();
  const auto nm = sim.interactions().materials().size();
  // The smallest radius and body mass of each material's free spheres, and which materials walls and
  // fixed bodies are made of: the partners a sphere can meet.
  std::vector<double> minRadius(nm, std::numeric_limits<double>::infinity()), minMass = minRadius;
  std::vector<std::uint8_t> wallMaterial(nm, 0);
  for (const auto& p : sim.planeWalls().walls()) wallMaterial[p.material] = 1;
  for (const auto& m : sim.meshWalls().walls()) wallMaterial[m.material] = 1;
  for (std::size_t s = 0; s < S.size(); ++s) {
    const auto b = S.body[s], mat = S.material[s];
    if (B.fixed[b]) {
      wallMaterial[mat] = 1;
      continue;
    }
    minRadius[mat] = std::min(minRadius[mat], S.radius[s]);
    minMass[mat] = std::min(minMass[mat], B.mass[b]);
  }
  const auto freeBodies = std::count(B.fixed.begin(), B.fixed.end(), std::uint8_t{0});
  double duration = std::numeric_limits<double>::infinity();
  // One evaluation per distinct (material, radius, mass) would do; spheres of one size repeat it cheaply.
  double lastR = -1, lastM = -1;
  std::uint32_t lastMat = static_cast<std::uint32_t>(nm);
  for (std::size_t s = 0; s < S.size(); ++s) {
    const auto b = S.body[s], mat = S.material[s];
    const double R = S.radius[s], m = B.mass[b];
    if (B.fixed[b] || (R == lastR && m == lastM && mat == lastMat)) continue;
    lastR = R, lastM = m, lastMat = mat;
    for (std::size_t o = 0; o < nm; ++o) {
      const ContactLaw* law = sim.interactions().law(mat, static_cast<std::uint32_t>(o));
      if (!law) continue;
      if (wallMaterial[o]) duration = std::min(duration, law->elasticImpact(R, m, approachSpeed).contactDuration);
      if (freeBodies > 1 && std::isfinite(minRadius[o])) {
        const double Rs = R * minRadius[o] / (R + minRadius[o]), ms = m * minMass[o] / (m + minMass[o]);
        duration = std::min(duration, law->elasticImpact(Rs, ms, approachSpeed).contactDuration);
      }
    }
  }
  return duration;
}

double safeTimeStep(const Simulation& sim, double approachSpeed) {
  const SimulationSettings& set = sim.settings();
  return std::min(set.dtSafety * criticalTimeStep(sim),
                  contactDuration(sim, approachSpeed) / static_cast<double>(set.stepsPerContact));
}

double approachSpeedEstimate(const Simulation& sim) {
  const Bodies& B = sim.bodies();
  double first = 0.0, second = 0.0;
  auto consider = [&](double speed) {
    if (speed > first) second = first, first = speed;
    else second = std::max(second, speed);
  };
  for (std::size_t b = 0; b < B.size(); ++b) consider(B.velocity[b].norm());
  for (const auto& p : sim.planeWalls().walls()) consider(p.velocity.norm());
  for (const auto& m : sim.meshWalls().walls()) consider(m.velocity.norm());
  const double g = sim.settings().gravity.norm();
  double height = 0.0;
  if (g > 0.0) {
    const Vec3 down = sim.settings().gravity / g;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    auto extend = [&](const Vec3& x) {
      const double h = -down.dot(x);
      lo = std::min(lo, h), hi = std::max(hi, h);
    };
    for (const auto& x : B.position) extend(x);
    for (const auto& p : sim.planeWalls().walls())
      if (std::abs(p.normal.normalized().dot(down)) > 1e-9) extend(p.point);  // a wall along g bounds no fall
    for (const auto& m : sim.meshWalls().walls())
      for (const auto& x : m.nodes) extend(x);
    height = hi - lo;
  }
  return first + second + std::sqrt(2.0 * g * height);
}

}  // namespace dem
