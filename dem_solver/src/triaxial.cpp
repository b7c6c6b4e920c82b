#include "dem/triaxial.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/memory.hpp"
#include "common/run_loop.hpp"
#include "common/summary.hpp"
#include "dem/contact_queries.hpp"
#include "dem/scene.hpp"
#include "dem/time_steps.hpp"
#include "cell_hash.hpp"

namespace dem {

using common::Config;
using common::Interval;

namespace {

constexpr double kPi = 3.14159265358979323846;
// Walls in this order: x0, x1, y0, y1, z0 (bottom), z1 (top); each normal points into the sample.
constexpr int kWalls = 6;
const std::array<const char*, kWalls> kWallNames = {"x0", "x1", "y0", "y1", "z0", "z1"};

double sphereVolume(double r) { return 4.0 / 3.0 * kPi * r * r * r; }

struct Box {
  Vec3 lo, hi;
  Vec3 size() const { return hi - lo; }
  double volume() const { return size().prod(); }
};

Box boxOf(const Simulation& sim) {
  const auto& p = sim.planeWalls().walls();
  return {Vec3(p[0].point.x(), p[2].point.y(), p[4].point.z()), Vec3(p[1].point.x(), p[3].point.y(), p[5].point.z())};
}

// Compressive stress on each wall: the spheres push it against its inward normal [Pa].
std::array<double, kWalls> wallStresses(const Simulation& sim) {
  const Box box = boxOf(sim);
  const Vec3 L = box.size();
  const std::array<double, 3> area = {L.y() * L.z(), L.x() * L.z(), L.x() * L.y()};
  std::array<double, kWalls> sigma{};
  for (int w = 0; w < kWalls; ++w)
    sigma[w] = -sim.planeWalls().forces()[w].dot(sim.planeWalls().walls()[w].normal) / area[w / 2];
  return sigma;
}

// Mean resultant contact force on the free spheres over the mean contact force: 0 in equilibrium.
double unbalancedForceRatio(const Simulation& sim) {
  const auto network = contactNetwork(sim);
  if (network.empty()) return 1.0;
  double contact = 0.0;
  for (const auto& l : network) contact += std::abs(l.normalForce);
  contact /= static_cast<double>(network.size());
  double resultant = 0.0;
  const auto& B = sim.bodies();
  for (std::size_t b = 0; b < B.size(); ++b) resultant += B.force[b].norm();
  resultant /= static_cast<double>(B.size());
  return contact > 0.0 ? resultant / contact : 1.0;
}

// The spheres (their centres, radii and velocities), the six walls of `box`, the scene's laws with
// `change`: one phase's simulation.
std::unique_ptr<Simulation> buildPhase(const TriaxialScene& scene, const std::vector<Vec3>& centre,
                                       const std::vector<double>& radius, const std::vector<Vec3>& velocity,
                                       const Box& box, const LawOverride& change) {
  auto sim = std::make_unique<Simulation>();
  const auto materials = loadMaterials(scene.cfg, *sim);
  loadInteractions(scene.cfg, *sim, materials, change);
  const auto grain = materials.at(scene.specimen.material), wall = materials.at(scene.test.wallMaterial);
  for (std::size_t i = 0; i < centre.size(); ++i)
    addSphere(*sim, centre[i], radius[i], grain, velocity[i], Vec3::Zero(), false);
  for (int w = 0; w < kWalls; ++w) {
    PlaneWall p;
    p.name = kWallNames[static_cast<std::size_t>(w)];
    const int axis = w / 2;
    const bool high = w % 2 == 1;
    p.point = high ? box.hi : box.lo;
    p.normal = (high ? -1.0 : 1.0) * Vec3::Unit(axis);
    p.material = wall;
    sim->planeWalls().add(p);
  }
  auto& set = sim->settings();
  set.gravity = Vec3::Zero();
  set.localDamping = scene.test.localDamping;
  set.dt = scene.test.dtFraction * criticalTimeStep(*sim);
  set.bondAtStart = false;  // the sample is cemented once consolidated (runTriaxial)
  sim->initialize();
  return sim;
}

// Servo: moves wall w inward by gain × (σ_target − σ_w) A_w / K_w per step, at most vmax.
void servo(Simulation& sim, int w, double sigma, double target, double stiffness, double gain, double vmax) {
  const Box box = boxOf(sim);
  const Vec3 L = box.size();
  const std::array<double, 3> area = {L.y() * L.z(), L.x() * L.z(), L.x() * L.y()};
  const double dt = sim.settings().dt;
  double speed = stiffness > 0.0 ? gain * (target - sigma) * area[w / 2] / stiffness / dt : vmax;
  speed = std::clamp(speed, -vmax, vmax);
  sim.planeWalls().setVelocity(static_cast<std::uint32_t>(w), speed * sim.planeWalls().walls()[w].normal);
}

// A radius drawn by number from a (radius, mass fraction passing) table: the mass is spread evenly over
// each interval [r0, r1], so the number of grains there goes as ΔF / (r1 − r0) ∫ r⁻³ dr. The interval is
// drawn by its number, then r by the inverse of that r⁻³ distribution: exact, no rejection.
double sieveRadius(const std::vector<std::pair<double, double>>& sieve, double u, double v) {
  std::vector<double> number(sieve.size(), 0.0);  // cumulative, per interval end
  for (std::size_t k = 1; k < sieve.size(); ++k) {
    const auto& [r0, f0] = sieve[k - 1];
    const auto& [r1, f1] = sieve[k];
    number[k] = number[k - 1] + (f1 - f0) / (r1 - r0) * 0.5 * (1.0 / (r0 * r0) - 1.0 / (r1 * r1));
  }
  const double target = u * number.back();
  std::size_t k = 1;
  while (k + 1 < sieve.size() && number[k] <= target) ++k;  // an interval without mass is passed over
  const double a = 1.0 / (sieve[k - 1].first * sieve[k - 1].first), b = 1.0 / (sieve[k].first * sieve[k].first);
  return 1.0 / std::sqrt(a - v * (a - b));
}

}  // namespace

double frictionAngle(double q, double sigma3, double cohesion) {
  // f(φ) = (q + 2σ3) sin φ + 2c cos φ − q rises on [0, π/2) while (q + 2σ3) cos φ > 2c sin φ: bisection.
  auto f = [&](double phi) { return (q + 2.0 * sigma3) * std::sin(phi) + 2.0 * cohesion * std::cos(phi) - q; };
  double lo = 0.0, hi = 0.5 * kPi - 1e-12;
  if (f(lo) >= 0.0) return 0.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) < 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Specimen specimenRadii(const SpecimenSettings& s) {
  std::mt19937_64 rng(s.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Specimen out;
  out.radius.reserve(s.count);
  while (out.radius.size() < s.count) {
    if (s.sieve.empty()) {
      out.radius.push_back(s.rmin + (s.rmax - s.rmin) * u(rng));
      continue;
    }
    const double a = u(rng), b = u(rng);
    out.radius.push_back(sieveRadius(s.sieve, a, b));
  }
  // Largest first: random sequential addition then fills around them.
  std::sort(out.radius.begin(), out.radius.end(), std::greater<>());
  double solid = 0.0;
  for (double r : out.radius) solid += sphereVolume(r);
  const double volume = solid / (1.0 - s.porosity);
  const double edge = std::cbrt(volume / s.aspect.prod());
  out.lo = Vec3::Zero();
  out.hi = edge * s.aspect;
  return out;
}

Specimen randomSpecimen(const SpecimenSettings& s, double shrink) {
  std::mt19937_64 rng(s.seed ^ 0x9e3779b97f4a7c15ULL);  // the placement's own stream
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Specimen out = specimenRadii(s);
  const double rmax = out.radius.front() * shrink;
  detail::CellHash grid(2.0 * rmax);
  out.centre.reserve(s.count);
  for (std::uint32_t i = 0; i < s.count; ++i) {
    const double r = out.radius[i] * shrink;
    bool placed = false;
    for (int attempt = 0; attempt < 10000 && !placed; ++attempt) {
      Vec3 x;
      for (int k = 0; k < 3; ++k) x[k] = out.lo[k] + r + (out.hi[k] - out.lo[k] - 2.0 * r) * u(rng);
      const bool free = grid.forEachNear(x, [&](std::uint32_t j) { return (out.centre[j] - x).norm() >= r + out.radius[j] * shrink; });
      if (!free) continue;
      grid.insert(i, x);
      out.centre.push_back(x);
      placed = true;
    }
    if (!placed)
      throw std::runtime_error(fmt::format("sphere {} of {} found no free place in the {:.4g} × {:.4g} × {:.4g} m box",
                                           i + 1, s.count, out.hi.x(), out.hi.y(), out.hi.z()));
  }
  return out;
}

bool isTriaxialScene(const Config& cfg) { return cfg.has("triaxial"); }

TriaxialScene loadTriaxialScene(const Config& cfg) {
  TriaxialScene scene;
  scene.cfg = cfg;
  // The laws are built per phase; building them once here checks the materials and interactions.
  Simulation check;
  const auto materials = loadMaterials(cfg, check);
  loadInteractions(cfg, check, materials);
  std::vector<std::string> names;
  for (const auto& [n, i] : materials) names.push_back(n);

  const Config sp = cfg.at("specimen");
  SpecimenSettings& s = scene.specimen;
  s.material = sp.choice("material", names);
  const auto count = sp.get<std::int64_t>("count");
  if (count < 2 || count > 50'000'000) sp.failAt("count", "expected a whole number of spheres in [2, 5e7].");
  s.count = static_cast<std::uint32_t>(count);
  if (auto shortfall = common::memoryShortfall(2000.0 * static_cast<double>(count), fmt::format("{} spheres", count)))
    sp.failAt("count", fmt::format("{}. Use fewer spheres.", *shortfall));
  if (sp.has("sieve") == sp.has("radius")) sp.fail("give either radius: [r_min, r_max] or a sieve: table.");
  if (sp.has("radius")) {
    const auto r = sp.get<std::vector<double>>("radius");
    if (r.size() != 2 || !(r[0] > 0) || r[1] < r[0]) sp.failAt("radius", "expected [r_min, r_max] with 0 < r_min ≤ r_max.");
    s.rmin = r[0], s.rmax = r[1];
  } else {
    const Config sieve = sp.at("sieve");
    for (const auto& row : sieve.elements()) {
      const auto v = row.as<std::vector<double>>();
      if (v.size() != 2 || !(v[0] > 0) || v[1] < 0 || v[1] > 1)
        row.fail("expected [radius > 0, mass fraction passing in [0, 1]].");
      if (!s.sieve.empty() && (v[0] <= s.sieve.back().first || v[1] < s.sieve.back().second))
        row.fail("radii must increase and the passing fractions must not decrease.");
      s.sieve.emplace_back(v[0], v[1]);
    }
    if (s.sieve.size() < 2 || s.sieve.front().second != 0.0 || s.sieve.back().second != 1.0)
      sieve.fail("expected at least two rows, the first passing 0 and the last 1.");
    s.rmin = s.sieve.front().first, s.rmax = s.sieve.back().first;
  }
  s.aspect = sp.get<Eigen::Vector3d>("aspect", Vec3(1, 1, 2));
  if (!(s.aspect.minCoeff() > 0)) sp.failAt("aspect", "expected three positive proportions, e.g. [1, 1, 2].");
  s.porosity = sp.get("porosity", Interval::open(0.2, 0.7));
  s.compactionFriction = sp.get("compaction_friction", 0.0, Interval::nonNegative());
  s.growthIncrements = sp.get<int>("growth_increments", 40);
  if (s.growthIncrements < 1 || s.growthIncrements > 100000) sp.failAt("growth_increments", "expected 1 … 100000.");
  s.relaxSteps = sp.get<int>("relax_steps", 300);
  if (s.relaxSteps < 1 || s.relaxSteps > 10'000'000) sp.failAt("relax_steps", "expected 1 … 1e7.");
  s.seed = static_cast<std::uint64_t>(sp.get<std::int64_t>("seed", 1));
  if (s.rmax > 20.0 * s.rmin)
    sp.fail(fmt::format("the radii span {:.3g} to {:.3g} m, more than a factor 20: the sample would need millions of "
                        "the smallest to hold the largest.",
                        s.rmin, s.rmax));
  {
    // The box must be a sample, several of the largest grains across.
    const Specimen radii = specimenRadii(s);
    const double narrowest = (radii.hi - radii.lo).minCoeff(), largest = 2.0 * radii.radius.front();
    if (narrowest < 4.0 * largest)
      sp.failAt("count", fmt::format("{} spheres at porosity {} fill a box only {:.3g} of the largest diameters across "
                                     "(the narrowest side, {:.4g} m); at least 4 are needed: more spheres, or an aspect "
                                     "closer to a cube.",
                                     count, s.porosity, narrowest / largest, narrowest));
  }

  const Config tx = cfg.at("triaxial");
  TriaxialSettings& t = scene.test;
  t.wallMaterial = tx.choice("wall_material", names);
  for (const auto& pair : {std::pair(s.material, s.material), std::pair(s.material, t.wallMaterial)})
    if (!check.interactions().law(materials.at(pair.first), materials.at(pair.second)))
      cfg.failAt("interactions", fmt::format("no interaction is defined for the material pair ({}, {}); add it.",
                                             pair.first, pair.second));
  if (check.interactions().materials()[materials.at(s.material)].rigid)
    sp.failAt("material", "a rigid material is for walls only (a sphere needs a finite stiffness).");
  t.confining = tx.get("confining_pressure", Interval::positive());
  t.strainRate = tx.get("axial_strain_rate", Interval::positive());
  t.strainEnd = tx.get("axial_strain_end", 0.1, Interval{0.0, 0.5, true, false});
  t.servoGain = tx.get("servo_gain", 0.25, Interval{0.0, 1.0, true, false});
  t.tolerance = tx.get("stress_tolerance", 0.01, Interval{0.0, 0.5, true, false});
  t.unbalancedLimit = tx.get("unbalanced_force_ratio", 0.01, Interval{0.0, 1.0, true, false});
  t.maxConsolidationTime = tx.get("max_consolidation_time", 1.0, Interval::positive());
  t.seriesStrain = tx.get("series_strain", 0.001, Interval::positive());
  t.snapshotStrain = tx.get("snapshot_strain", 0.01, Interval::positive());
  t.macroCohesion = tx.get("macro_cohesion", 0.0, Interval::nonNegative());
  // A sample's spheres touch several others at once: half the single-contact critical step at most (as
  // dt_safety's default elsewhere).
  t.dtFraction = cfg.get("dt_fraction", 0.2, Interval{0.0, 0.5, true, false});
  t.localDamping = cfg.get("local_damping", 0.2, Interval{0.0, 1.0, false, true});
  return scene;
}

namespace {

/// The grown sample (phase 1): its spheres at the target porosity in the box they were grown in.
struct Grown {
  std::vector<Vec3> centre, velocity;
  std::vector<double> radius;
  Box box;
  double solid = 0.0, meanRadius = 0.0, porosity = 0.0;
  std::int64_t steps = 0;
};

// Generation: placed at porosity 0.75 (shrunk radii), grown to the target porosity in increments, each
// relaxed, with the compaction friction and no bonds; walls fixed.
Grown growSample(const TriaxialScene& scene) {
  const SpecimenSettings& sp = scene.specimen;
  const double shrink = std::cbrt((1.0 - 0.75) / (1.0 - sp.porosity));
  Specimen spec;
  try {
    spec = randomSpecimen(sp, shrink);
  } catch (const std::runtime_error& e) {
    throw common::SimulationError(fmt::format("specimen generation failed: {}.", e.what()));
  }
  const std::size_t n = spec.radius.size();
  Grown g;
  for (double r : spec.radius) g.solid += sphereVolume(r), g.meanRadius += r;
  g.meanRadius /= static_cast<double>(n);
  auto log = common::logger("dem");
  log->info("specimen: {} spheres in a {:.4g} × {:.4g} × {:.4g} m box, grown from porosity 0.75 to {} in {} increments",
            n, spec.hi.x(), spec.hi.y(), spec.hi.z(), sp.porosity, sp.growthIncrements);
  g.box = Box{spec.lo, spec.hi};
  LawOverride growth;
  growth.friction = sp.compactionFriction;
  growth.bonds = false;
  g.centre = spec.centre, g.velocity.assign(n, Vec3::Zero());
  std::vector<double> radius(n);
  double stress = 0.0;
  for (int k = 1; k <= sp.growthIncrements; ++k) {
    const double scale = shrink + (1.0 - shrink) * k / sp.growthIncrements;
    for (std::size_t i = 0; i < n; ++i) radius[i] = spec.radius[i] * scale;
    auto sim = buildPhase(scene, g.centre, radius, g.velocity, g.box, growth);
    const int steps = k == sp.growthIncrements ? 4 * sp.relaxSteps : sp.relaxSteps;
    for (int s = 0; s < steps; ++s) sim->step();
    g.steps += steps;
    const auto sigma = wallStresses(*sim);
    stress = 0.0;
    for (double x : sigma) stress += x / kWalls;
    for (std::size_t i = 0; i < n; ++i) g.centre[i] = sim->bodies().position[i], g.velocity[i] = sim->bodies().velocity[i];
  }
  g.radius = std::move(spec.radius);
  g.porosity = 1.0 - g.solid / g.box.volume();
  const double sigma3 = scene.test.confining;
  log->info("grown to porosity {:.4f} in {} steps; mean wall stress {:.4g} Pa (σ3 = {:.4g} Pa)", g.porosity, g.steps,
            stress, sigma3);
  if (stress > 10.0 * sigma3)
    log->warn("the target porosity {} is below what these spheres reach with compaction_friction {}: the grown "
              "sample pushes on its walls with {:.3g} × σ3, and the consolidation lets it expand",
              sp.porosity, sp.compactionFriction, stress / sigma3);
  return g;
}

/// One row of the `triaxial` series: strains from the consolidated state, stresses from the walls.
struct Row {
  double e1, ev, s1, sx, sy, q, p, porosity, z, unbalanced;
};

/// The sample between its servo-controlled walls, as the test measures and loads it.
class Sample {
 public:
  Sample(const TriaxialScene& scene, Simulation& sim, common::H5Writer& h5, double solid, double vmax)
      : sim(sim), h5(h5), start(boxOf(sim)), tx_(scene.test), series_(h5, sim, {}), solid_(solid), vmax_(vmax) {
    h5.addSeries("triaxial", {"axial_strain", "volumetric_strain", "sigma_axial", "sigma_x", "sigma_y",
                              "deviatoric_stress", "mean_stress", "porosity", "coordination", "unbalanced_force_ratio",
                              "broken_bonds", "phase"});
  }

  Row measure() const {
    const auto sigma = wallStresses(sim);
    const Box box = boxOf(sim);
    Row r;
    r.e1 = (start.size().z() - box.size().z()) / start.size().z();
    r.ev = (start.volume() - box.volume()) / start.volume();
    r.s1 = 0.5 * (sigma[4] + sigma[5]);
    r.sx = 0.5 * (sigma[0] + sigma[1]);
    r.sy = 0.5 * (sigma[2] + sigma[3]);
    r.q = r.s1 - 0.5 * (r.sx + r.sy);
    r.p = (r.s1 + r.sx + r.sy) / 3.0;
    r.porosity = 1.0 - solid_ / box.volume();
    const auto c = contactCounts(sim);
    r.z = 2.0 * static_cast<double>(c.pairs + static_cast<std::int64_t>(sim.bonds().size())) /
          static_cast<double>(sim.spheres().size());
    r.unbalanced = unbalancedForceRatio(sim);
    return r;
  }

  void write(const Row& r, double phase) {
    h5.append("triaxial", sim.time(),
              std::vector<double>{r.e1, r.ev, r.s1, r.sx, r.sy, r.q, r.p, r.porosity, r.z, r.unbalanced,
                                  static_cast<double>(sim.bonds().broken()), phase});
    series_.write(series_.sample());
  }

  /// The walls move to hold σ3 (all six while consolidating, the lateral four under axial loading).
  void servoWalls(bool axial) {
    const auto sigma = wallStresses(sim);
    const auto k = planeContactStiffness(sim);
    for (int w = 0; w < (axial ? kWalls : 4); ++w) servo(sim, w, sigma[w], tx_.confining, k[w], tx_.servoGain, vmax_);
  }

  double axialStrain() const { return (start.size().z() - boxOf(sim).size().z()) / start.size().z(); }

  Simulation& sim;
  common::H5Writer& h5;
  Box start;  ///< the consolidated state the strains are measured from

 private:
  const TriaxialSettings& tx_;
  SeriesRecorder series_;
  double solid_, vmax_;
};

/// Consolidation to σ3 with the scene's laws, in blocks of 100 steps until the walls hold σ3 and the
/// sample is in equilibrium; the bonds form at its end, between the consolidated sample's neighbours.
/// Returns the consolidated row; the strains are measured from here on.
Row consolidate(const TriaxialSettings& tx, Sample& sample) {
  Simulation& sim = sample.sim;
  sample.write(sample.measure(), 0.0);
  writeParticleSnapshot(sample.h5, sim, sim.time());
  double worst = 1.0, unbalanced = 1.0;
  for (;;) {
    for (int s = 0; s < 100; ++s) {
      sample.servoWalls(true);
      sim.step();
    }
    const auto sigma = wallStresses(sim);
    worst = 0.0;
    for (double x : sigma) worst = std::max(worst, std::abs(x / tx.confining - 1.0));
    unbalanced = unbalancedForceRatio(sim);
    if (worst < tx.tolerance && unbalanced < tx.unbalancedLimit) break;
    if (sim.time() > tx.maxConsolidationTime) {
      sample.write(sample.measure(), 0.0);
      sample.h5.flush();
      throw common::InstabilityError(
          {"consolidation did not converge", "the sample", sim.time(),
           fmt::format("after {:.4g} s the wall stresses are within {:.3g} of σ3 (wanted {}) and the unbalanced "
                       "force ratio is {:.3g} (wanted {})",
                       sim.time(), worst, tx.tolerance, unbalanced, tx.unbalancedLimit),
           fmt::format("raise triaxial.max_consolidation_time (now {} s) or local_damping (now {})",
                       tx.maxConsolidationTime, tx.localDamping)});
    }
  }
  sample.start = boxOf(sim);
  // Measured and written before the bonds form: forming them rebuilds the contacts, and the forces are
  // summed again only by the next step.
  const Row consolidated = sample.measure();
  sample.write(consolidated, 0.0);
  writeParticleSnapshot(sample.h5, sim, sim.time());
  // The consolidated sample and the pairs it cemented, as data, for a peer code to start from the same
  // state and bond the same pairs (tests/bench/peers).
  std::vector<double> spheres, pairs;
  const auto& S = sim.spheres();
  for (std::size_t i = 0; i < S.size(); ++i)
    spheres.insert(spheres.end(), {S.position[i].x(), S.position[i].y(), S.position[i].z(), S.radius[i]});
  sample.h5.writeArray("/triaxial/consolidated_spheres", spheres, 4);
  const Box& b = sample.start;
  sample.h5.writeArray("/triaxial/consolidated_box",
                       std::vector<double>{b.lo.x(), b.lo.y(), b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z()}, 3);
  sim.formBonds();
  for (const Bond& bond : sim.bonds().bonds()) pairs.insert(pairs.end(), {double(bond.a), double(bond.b)});
  sample.h5.writeArray("/triaxial/bonds", pairs, 2);
  common::logger("dem")->info(
      "consolidated in {:.4g} s ({} steps): porosity {:.4f}, coordination {:.3f}, unbalanced {:.2g}; {} bonds",
      sim.time(), sim.steps(), consolidated.porosity, consolidated.z, unbalanced, sim.bonds().created());
  return consolidated;
}

/// The axial compression as common::runLoop drives it: the top and bottom walls close at the constant
/// strain rate (engineering strain of the consolidated height), the lateral walls hold σ3. The clock is the
/// axial strain ε1, series rows and snapshots fall at its intervals, and the test ends at the step nearest
/// to triaxial.axial_strain_end.
class Compression final : public common::SteppedRun {
 public:
  Compression(const TriaxialSettings& tx, Sample& sample, const Row& consolidated)
      : tx_(tx), sample_(sample), sim_(sample.sim), consolidated_(consolidated), last_(consolidated),
        maxCompaction_(consolidated.ev), firstStep_(static_cast<std::int64_t>(sim_.steps())),
        steps_(std::llround(tx.strainEnd / tx.strainRate / sim_.settings().dt)) {
    const double axialSpeed = tx.strainRate * sample.start.size().z();
    sim_.planeWalls().setVelocity(4, 0.5 * axialSpeed * Vec3::UnitZ());
    sim_.planeWalls().setVelocity(5, -0.5 * axialSpeed * Vec3::UnitZ());
  }

  double clock() const override { return sample_.axialStrain(); }
  double clockStep() const override { return tx_.strainRate * sim_.settings().dt; }
  std::int64_t steps() const override { return static_cast<std::int64_t>(sim_.steps()); }
  bool finished() const override { return steps() - firstStep_ >= steps_; }

  void step() override {
    sample_.servoWalls(false);
    sim_.step();
    if (secant_ == 0.0 && clock() >= 5e-4) {
      const Row r = sample_.measure();
      secant_ = (r.q - consolidated_.q) / r.e1;  // the walls held σ3 within the tolerance only
    }
  }

  void writeSeries(common::SeriesRow) override {
    last_ = sample_.measure();
    sample_.write(last_, 1.0);
    maxCompaction_ = std::max(maxCompaction_, last_.ev);
    lateralError_ = std::max({lateralError_, std::abs(last_.sx / tx_.confining - 1.0),
                              std::abs(last_.sy / tx_.confining - 1.0)});
    if (last_.q > peakQ_) {
      peakQ_ = last_.q, peakStrain_ = last_.e1, peakTime_ = sim_.time();
      peak_ = sim_.saveCheckpoint();
    }
  }
  void writeSnapshot(bool) override { writeParticleSnapshot(sample_.h5, sim_, sim_.time()); }
  void archive(common::StateArchive&) override {
    throw common::ConfigError("the triaxial test writes no checkpoints");
  }

  std::string status() const override {
    return fmt::format("ε1 = {:.4g} of {:.4g} ({:.0f} %), q = {:.4g} Pa, {} bonds broken, {} steps", clock(),
                       tx_.strainEnd, 100 * clock() / tx_.strainEnd, last_.q, sim_.bonds().broken(), steps());
  }

  void report(common::Summary& summary, double loopSeconds, bool failed) override {
    summary.set("end_time", sim_.time());
    if (failed) return;
    summary.set("peak_deviatoric_stress", peakQ_);
    summary.set("axial_strain_at_peak", peakStrain_);
    summary.set("max_compaction_volumetric_strain", maxCompaction_);
    summary.set("final_volumetric_strain", last_.ev);
    summary.set("final_axial_strain", last_.e1);
    summary.set("final_deviatoric_stress", last_.q);
    summary.set("friction_angle_estimate", frictionAngle(peakQ_, tx_.confining, tx_.macroCohesion) * 180.0 / kPi);
    summary.set("macro_cohesion_assumed", tx_.macroCohesion);
    summary.set("secant_modulus_0_05_percent", secant_);
    summary.set("coordination_final", last_.z);
    summary.set("lateral_stress_error_max", lateralError_);
    summary.set("compression_wall_time_s", loopSeconds);  // the axial loading alone, as peers time it
    summary.set("compression_steps", steps_);
    common::logger("dem")->info(
        "peak q = {:.4g} Pa at ε1 = {:.4f}; ε_v final {:.4f} (most compaction {:.4f}); {} of {} bonds broke", peakQ_,
        peakStrain_, last_.ev, maxCompaction_, sim_.bonds().broken(), sim_.bonds().created());
  }

  /// The force network at the peak, in a file of its own (ParaView: peak.xdmf).
  void writePeak(const std::filesystem::path& file) {
    if (!peak_) return;
    sim_.restoreCheckpoint(*peak_);
    common::H5Writer peakFile(file);
    writeParticleSnapshot(peakFile, sim_, peakTime_);
    peakFile.flush();
  }

 private:
  const TriaxialSettings& tx_;
  Sample& sample_;
  Simulation& sim_;
  const Row consolidated_;
  Row last_;
  double peakQ_ = -1.0, peakStrain_ = 0.0, peakTime_ = 0.0, maxCompaction_, lateralError_ = 0.0, secant_ = 0.0;
  std::shared_ptr<const Simulation::Checkpoint> peak_;
  const std::int64_t firstStep_, steps_;
};

}  // namespace

void runTriaxial(TriaxialScene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress) {
  auto log = common::logger("dem");
  const TriaxialSettings& tx = scene.test;
  const auto loopStart = std::chrono::steady_clock::now();
  const Grown grown = growSample(scene);

  auto owned = buildPhase(scene, grown.centre, grown.radius, grown.velocity, grown.box, LawOverride{});
  Simulation& sim = *owned;
  const double dt = sim.settings().dt;
  const double density = sim.interactions().materials()[sim.spheres().material[0]].density;
  // Walls move at most at the axial loading speed: the consolidation is as quasi-static as the test.
  const double vmax = tx.strainRate * grown.box.size().z();
  const double inertial = tx.strainRate * 2.0 * grown.meanRadius * std::sqrt(density / tx.confining);
  log->info("consolidation to σ3 = {:.4g} Pa; dt = {:.4g} s; inertial number of the loading I = {:.3g}", tx.confining,
            dt, inertial);
  if (inertial > 1e-3)
    log->warn("the inertial number I = ε̇ d √(ρ/σ3) = {:.3g} is above 1e-3: the test is not quasi-static. Lower "
              "triaxial.axial_strain_rate to {:.3g} 1/s or less.",
              inertial, tx.strainRate * 1e-3 / inertial);
  common::H5Writer h5(outDir / "dem.h5");
  Sample sample(scene, sim, h5, grown.solid, vmax);
  const Row consolidated = consolidate(tx, sample);
  const double consolidationTime = sim.time();

  Compression compression(tx, sample, consolidated);
  common::RunLoopSettings s;
  s.label = "triaxial";
  s.series = common::Cadence::after(tx.seriesStrain);
  s.snapshots = common::Cadence::after(tx.snapshotStrain);
  s.seriesAtEnd = s.snapshotAtEnd = true;
  s.progress = progress;
  std::optional<common::StateArchive> noRestart;
  common::runLoop(compression, std::move(s), &h5, noRestart, {}, summary);

  summary.set("strain_convention", std::string("compression positive; strains from the consolidated state"));
  summary.set("confining_pressure", tx.confining);
  summary.set("spheres", static_cast<std::int64_t>(sim.spheres().size()));
  summary.set("mean_radius", grown.meanRadius);
  summary.set("porosity_generated", grown.porosity);
  summary.set("porosity_consolidated", consolidated.porosity);
  summary.set("coordination_consolidated", consolidated.z);
  // The ledger over the consolidation and compression: what the walls did against what the sample holds
  // and dissipated.
  const EnergyLedger& e = sim.energy();
  const double scale = std::max({std::abs(e.wallWork), e.elastic, e.damping + e.friction + e.cundall + e.bondFracture});
  summary.set("energy_balance_error", scale > 0.0 ? std::abs(e.residual(sim.initialEnergy())) / scale : 0.0);
  summary.set("wall_work", e.wallWork);
  summary.set("bonds_created", sim.bonds().created());
  summary.set("broken_bonds", sim.bonds().broken());
  summary.set("bond_fracture_energy", sim.energy().bondFracture);
  summary.set("inertial_number", inertial);
  summary.set("consolidation_time", consolidationTime);
  summary.set("growth_steps", grown.steps);
  summary.set("dt", dt);
  const double loopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - loopStart).count();
  summary.set("loop_wall_time_s", loopSeconds);
  reportCost(sim, summary, loopSeconds);
  compression.writePeak(outDir / "peak.h5");
}

}  // namespace dem
