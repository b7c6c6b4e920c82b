#include "dem/scene.hpp"

#include <algorithm>
#include <iterator>
#include <map>
#include <set>

#include <fmt/format.h>

#include "common/config.hpp"
#include "common/log.hpp"
#include "common/memory.hpp"
#include "common/mesh_io.hpp"
#include "dem/cluster.hpp"
#include "dem/contact_queries.hpp"
#include "dem/time_steps.hpp"

#include <random>

#include <Eigen/Eigenvalues>

namespace dem {

using common::Config;
using common::Interval;

namespace {

std::uint32_t materialIndex(const Config& owner, const std::map<std::string, std::uint32_t>& byName) {
  std::vector<std::string> names;
  for (const auto& [n, i] : byName) names.push_back(n);
  return byName.at(owner.choice("material", names));
}

// A flat rectangle in the plane z = origin.z, triangulated on an nx × ny grid. pattern: "right" (every
// cell cut along the same diagonal), "alternate" (chequered diagonals), "random" (random diagonals);
// jitter moves interior nodes in-plane by up to that fraction of a cell (irregular, still flat).
common::TriangleMesh gridMesh(const Config& g) {
  const Vec3 origin = g.get<Eigen::Vector3d>("origin");
  const auto size = g.get<std::vector<double>>("size");
  const auto div = g.get<std::vector<int>>("divisions");
  if (size.size() != 2 || !(size[0] > 0 && size[1] > 0)) g.failAt("size", "expected [lx, ly] > 0.");
  if (div.size() != 2 || div[0] < 1 || div[1] < 1) g.failAt("divisions", "expected [nx, ny] ≥ 1.");
  // ≈ 200 bytes per triangle (nodes, indices, contact search cells): refused before generating.
  const double triangles = 2.0 * div[0] * static_cast<double>(div[1]);
  if (auto shortfall = common::memoryShortfall(200.0 * triangles, fmt::format("{:.3g} wall triangles", triangles)))
    g.failAt("divisions", fmt::format("{}. Use fewer divisions.", *shortfall));
  const std::string pattern = g.choice("pattern", {"right", "alternate", "random"}, "alternate");
  const double jitter = g.get("jitter", 0.0, Interval{0.0, 0.45, false, false});
  std::mt19937 rng(static_cast<unsigned>(g.get<int>("seed", 1)));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  common::TriangleMesh mesh;
  const int nx = div[0], ny = div[1];
  const double hx = size[0] / nx, hy = size[1] / ny;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      Vec3 p = origin + Vec3(i * hx, j * hy, 0);
      if (i > 0 && i < nx && j > 0 && j < ny) p += jitter * Vec3(u(rng) * hx, u(rng) * hy, 0);
      mesh.nodes.push_back(p);
    }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      bool flip = pattern == "alternate" ? ((i + j) % 2 == 1) : pattern == "random" ? (u(rng) > 0) : false;
      if (!flip) {
        mesh.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        mesh.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      } else {
        mesh.triangles.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
        mesh.triangles.push_back({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  return mesh;
}

// A cluster's `orientation`, a quaternion [w, x, y, z] (identity if absent).
Quat readOrientation(const Config& c) {
  Quat orientation = Quat::Identity();
  if (auto q = c.find<std::vector<double>>("orientation")) {
    if (q->size() != 4) c.failAt("orientation", "expected a quaternion [w, x, y, z].");
    orientation = Quat((*q)[0], (*q)[1], (*q)[2], (*q)[3]);
    if (orientation.norm() < 1e-12) c.failAt("orientation", "the quaternion must not be zero.");
    orientation.normalize();
  }
  return orientation;
}

MeshWall loadMeshWall(const Config& w) {
  common::TriangleMesh tm;
  if (Config grid = w.child("grid")) {
    tm = gridMesh(grid);
  } else {
    const auto file = w.filePath("file");
    try {
      tm = common::readTriangleMesh(file, w.get<std::string>("physical", ""));
    } catch (const common::SimulationError& e) {
      w.failAt("file", e.what());
    }
  }
  // A triangle of zero area has no normal: a sphere touching it would get a contact without a direction.
  double extent = 0.0;
  for (const auto& x : tm.nodes) extent = std::max(extent, (x - tm.nodes.front()).norm());
  for (std::size_t k = 0; k < tm.triangles.size(); ++k) {
    const auto& t = tm.triangles[k];
    const double doubled = (tm.nodes[t[1]] - tm.nodes[t[0]]).cross(tm.nodes[t[2]] - tm.nodes[t[0]]).norm();
    if (!(doubled > 1e-12 * extent * extent))
      w.failAt(w.child("grid") ? "grid" : "file",
               fmt::format("triangle {} (nodes {}, {}, {}) has zero area: its corners are on one line. Remove it or "
                           "fix its nodes.",
                           k, t[0], t[1], t[2]));
  }
  MeshWall mesh;
  mesh.nodes = tm.nodes;
  mesh.triangles = tm.triangles;
  if (auto shift = w.find<Eigen::Vector3d>("translate"))
    for (auto& x : mesh.nodes) x += *shift;
  const std::string motion = w.choice("motion", {"fixed", "prescribed", "external"}, "fixed");
  mesh.motion = motion == "fixed" ? MeshWall::Motion::kFixed
                : motion == "prescribed" ? MeshWall::Motion::kPrescribed : MeshWall::Motion::kExternal;
  if (mesh.motion == MeshWall::Motion::kPrescribed) mesh.velocity = w.get<Eigen::Vector3d>("velocity");
  mesh.oneSided = w.choice("sides", {"two", "one"}, "two") == "one";
  if (mesh.oneSided) mesh.depthRadii = w.get("depth", 3.0, common::Interval::positive());
  if (auto rho = w.find<double>("areal_density")) {  // a deformable sheet: lumped node masses
    if (!(*rho > 0)) w.failAt("areal_density", "must be > 0 (mass per area, kg/m²).");
    mesh.nodeMass.assign(mesh.nodes.size(), 0.0);
    for (const auto& t : mesh.triangles) {
      const double area = 0.5 * (mesh.nodes[t[1]] - mesh.nodes[t[0]]).cross(mesh.nodes[t[2]] - mesh.nodes[t[0]]).norm();
      for (auto n : t) mesh.nodeMass[n] += *rho * area / 3;
    }
  }
  return mesh;
}

// The bodies in runs, each run's material and the node that made it: the first body of each material
// stands for it in the errors about materials, a body's node in the error about its overlap. One run per
// node, not per body: a `generate` entry of 10⁶ spheres would otherwise hold 70 MB of node handles
// while the run starts.
struct BodyNodes {
  struct Run {
    std::size_t first;  // its first body
    std::uint32_t material;
    Config node;
  };
  std::vector<Run> runs;
  std::size_t bodies = 0;
  void add(std::uint32_t m, const Config& c, std::size_t count = 1) {
    if (count > 0) runs.push_back({bodies, m, c}), bodies += count;
  }
  const Config& nodeOf(std::size_t body) const {
    auto before = [](std::size_t b, const Run& r) { return b < r.first; };
    return std::prev(std::upper_bound(runs.begin(), runs.end(), body, before))->node;
  }
};
using Materials = std::map<std::string, std::uint32_t>;

void requireLaw(const Simulation& sim, const Config& where, std::uint32_t a, std::uint32_t b) {
  if (!sim.interactions().law(a, b))
    where.fail(fmt::format("no interaction is defined for the material pair ({}, {}); add it under "
                           "interactions.",
                           sim.interactions().materials()[a].name, sim.interactions().materials()[b].name));
}

// `spheres:`, one body each.
void loadSpheres(const Config& cfg, Simulation& sim, const Materials& materials, BodyNodes& nodes) {
  if (Config spheres = cfg.child("spheres")) {
    for (const auto& s : spheres.elements()) {
      const std::uint32_t mat = materialIndex(s, materials);
      const double radius = s.get("radius", Interval::positive());
      const auto b = addSphere(sim, s.get<Eigen::Vector3d>("position"), radius, mat,
                                   s.get<Eigen::Vector3d>("velocity", Vec3::Zero()),
                                   s.get<Eigen::Vector3d>("angular_velocity", Vec3::Zero()), s.get<bool>("fixed", false));
      sim.setExternalForce(b, s.get<Eigen::Vector3d>("force", Vec3::Zero()));
      nodes.add(mat, s);
    }
  }
}

// `generate:`, lone spheres on a lattice filling a box.
void loadGenerated(const Config& cfg, Simulation& sim, const Materials& materials, BodyNodes& nodes) {
  if (Config generate = cfg.child("generate")) {
    for (const auto& g : generate.elements()) {
      const std::uint32_t mat = materialIndex(g, materials);
      const auto count = g.get<std::size_t>("count");
      const auto radius = g.get<std::vector<double>>("radius");
      if (radius.size() != 2 || !(radius[0] > 0) || radius[1] < radius[0])
        g.failAt("radius", "expected [r_min, r_max] with 0 < r_min ≤ r_max.");
      const Config box = g.at("box");
      const Vec3 lo = box.get<Eigen::Vector3d>("min"), hi = box.get<Eigen::Vector3d>("max");
      // A cubic lattice of spacing 2.1 r_max inside the box, filled bottom-up, each site jittered by up to
      // 0.05 r_max: never overlapping, reproducible from the seed.
      const double spacing = 2.1 * radius[1];
      // Sites counted in doubles: a large box's lattice overflows an int per axis and its product any integer.
      const Eigen::Array3d axes = ((hi - lo).array() / spacing).floor();
      const double sites = (axes > 0).all() ? axes.prod() : 0.0;
      if (sites < static_cast<double>(count))
        g.failAt("count", fmt::format("the box holds only {:.0f} spheres of radius {} on the generation lattice (spacing "
                                      "{:.4g} m); enlarge the box or lower the count.",
                                      sites, radius[1], spacing));
      // About 1 KB per sphere in the run (bodies, neighbour list, contact history; docs/performance.md).
      if (auto shortfall = common::memoryShortfall(1.1e3 * static_cast<double>(count + sim.spheres().size()),
                                                   fmt::format("{} spheres", count + sim.spheres().size())))
        g.failAt("count", *shortfall + ": lower the count.");
      const Eigen::Array3i n = axes.min(1e9).cast<int>();
      std::mt19937_64 rng(static_cast<std::uint64_t>(g.get<int>("seed", 1)));
      std::uniform_real_distribution<double> u(0.0, 1.0);
      const Vec3 velocity = g.get<Eigen::Vector3d>("velocity", Vec3::Zero());
      nodes.add(mat, g, count);
      for (std::size_t k = 0; k < count; ++k) {
        const auto i = static_cast<int>(k % static_cast<std::size_t>(n.x()));
        const auto j = static_cast<int>((k / static_cast<std::size_t>(n.x())) % static_cast<std::size_t>(n.y()));
        const auto l = static_cast<int>(k / static_cast<std::size_t>(n.x() * n.y()));
        const Vec3 jitter = 0.05 * radius[1] * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        const Vec3 p = lo + spacing * Vec3(i + 0.5, j + 0.5, l + 0.5) + jitter;
        const double r = radius[0] + (radius[1] - radius[0]) * u(rng);
        addSphere(sim, p, r, mat, velocity, Vec3::Zero(), false);
      }
    }
  }
}

// A block of bonded spheres: each member its own body, the law of its material pair bonds them at
// initialize() (dem_solver/README.md §Bonded clusters).
void addBondedCluster(const Config& c, const ClusterShape& shape, std::uint32_t mat, Simulation& sim, BodyNodes& nodes) {
  const auto overlap = largestOverlap(shape.centers, shape.radii);
  if (overlap.first > 1e-9)
    c.fail(fmt::format("bonded: the members must not overlap (their bonds would start compressed, and push the "
                       "block apart as they break), but spheres {} and {} overlap by {:.3g} of their radii sum; "
                       "use cube: {{edge, n}} (touching spheres) or a cluster file of touching spheres.",
                       overlap.second.first, overlap.second.second, overlap.first));
  double volume = 0.0;
  for (double r : shape.radii) volume += 4.0 / 3.0 * 3.14159265358979323846 * r * r * r;
  const double density = c.has("mass") ? c.get("mass", Interval::positive()) / volume
                                        : sim.interactions().materials()[mat].density;
  const Quat orientation = readOrientation(c);
  Vec3 centre = Vec3::Zero();
  for (const Vec3& x : shape.centers) centre += x;
  centre /= static_cast<double>(shape.centers.size());
  const Vec3 position = c.get<Eigen::Vector3d>("position");
  const Vec3 velocity = c.get<Eigen::Vector3d>("velocity", Vec3::Zero());
  const Vec3 spin = c.get<Eigen::Vector3d>("angular_velocity", Vec3::Zero());
  const bool fixed = c.get<bool>("fixed", false);
  for (std::size_t k = 0; k < shape.centers.size(); ++k) {
    const double r = shape.radii[k];
    const double m = density * 4.0 / 3.0 * 3.14159265358979323846 * r * r * r;
    const Vec3 arm = orientation * (shape.centers[k] - centre);
    sim.addCluster({Vec3::Zero()}, {r}, mat, m, Vec3::Constant(0.4 * m * r * r), position + arm,
                   Quat::Identity(), velocity + spin.cross(arm), spin, fixed);
  }
  nodes.add(mat, c, shape.centers.size());
}

// `clusters:`, rigid bodies of spheres from a file or a cube, or bonded blocks.
void loadClusters(const Config& cfg, Simulation& sim, const Materials& materials, BodyNodes& nodes) {
  if (Config clusters = cfg.child("clusters")) {
    for (const auto& c : clusters.elements()) {
      const std::uint32_t mat = materialIndex(c, materials);
      ClusterShape shape;
      const bool bonded = c.get<bool>("bonded", false);
      if (c.has("file")) {
        shape = readClusterFile(c.filePath("file"));
      } else if (const Config box = c.child("box")) {
        if (!bonded) box.fail("is a lattice to bond: give bonded: true (a rigid cluster is a cube or a file).");
        const double spacing = box.get("spacing", Interval::positive());
        const Eigen::Vector3d n = box.get<Eigen::Vector3d>("n");
        for (int k = 0; k < 3; ++k)
          if (!(n[k] >= 1 && n[k] <= 1000 && n[k] == std::floor(n[k])))
            box.failAt("n", "expected three whole numbers of spheres, each in [1, 1000].");
        if (auto shortfall = common::memoryShortfall(1.1e3 * n.prod(), fmt::format("{:.0f} spheres", n.prod())))
          box.failAt("n", *shortfall + ": fewer spheres.");
        shape = makeBoxLattice(spacing, n.cast<int>());
      } else {
        const Config gen = c.at("cube");
        const double edge = gen.get("edge", Interval::positive());
        const int n = gen.get<int>("n");
        if (n < 1 || n > 1000) gen.failAt("n", "expected a whole number of spheres per edge in [1, 1000].");
        // Bonded: touching spheres (a bond starts at rest only between spheres that do not overlap).
        shape = bonded ? makeCubeLattice(edge, n) : makeCubeCluster(edge, n);
      }
      if (bonded) {
        addBondedCluster(c, shape, mat, sim, nodes);
        continue;
      }
      const std::string source = c.choice("mass_properties", {"shape", "spheres"}, shape.shape ? "shape" : "spheres");
      if (source == "shape" && !shape.shape)
        c.failAt("mass_properties", "the cluster file declares no `shape:` mass properties; use spheres.");
      const MassProperties props = source == "shape" ? *shape.shape : unionMassProperties(shape.centers, shape.radii);
      const double mass = c.get("mass", props.volume * sim.interactions().materials()[mat].density, Interval::positive());
      // Principal frame: eigenvectors of the inertia tensor, right-handed.
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(props.inertiaPerMass);
      Eigen::Matrix3d axes = eig.eigenvectors();
      if (axes.determinant() < 0) axes.col(2) *= -1;
      std::vector<Vec3> local;
      for (const auto& x : shape.centers) local.push_back(axes.transpose() * (x - props.center));
      const Quat orientation = readOrientation(c);
      const auto b = sim.addCluster(local, shape.radii, mat, mass, mass * eig.eigenvalues(),
                                    c.get<Eigen::Vector3d>("position"), orientation * Quat(axes),
                                    c.get<Eigen::Vector3d>("velocity", Vec3::Zero()),
                                    c.get<Eigen::Vector3d>("angular_velocity", Vec3::Zero()), c.get<bool>("fixed", false));
      sim.setExternalForce(b, c.get<Eigen::Vector3d>("force", Vec3::Zero()));
      nodes.add(mat, c);
    }
  }
}

// `walls:`, planes and meshes, each touchable by every body material (`firstOfMaterial`).
void loadWalls(const Config& cfg, Simulation& sim, const Materials& materials,
               const std::map<std::uint32_t, Config>& firstOfMaterial) {
  if (Config walls = cfg.child("walls")) {
    std::size_t i = 0;
    // Wall names name the walls' series columns and snapshot grids: unique, and not the grids the
    // spheres and their contact network use.
    std::set<std::string> names;
    auto wallName = [&](const Config& w) {
      std::string name = w.get<std::string>("name", fmt::format("wall{}", i++));
      if (name == "spheres" || name == "contacts")
        w.failAt("name", fmt::format("\"{}\" is the name of the spheres' output; give the wall another.", name));
      if (!names.insert(name).second) w.failAt("name", fmt::format("another wall is already named \"{}\".", name));
      return name;
    };
    for (const auto& w : walls.elements()) {
      if (w.choice("type", {"plane", "mesh"}) == "mesh") {
        MeshWall mesh = loadMeshWall(w);
        mesh.name = wallName(w);
        mesh.material = materialIndex(w, materials);
        for (const auto& [m, node] : firstOfMaterial) requireLaw(sim, w, m, mesh.material);
        sim.meshWalls().add(std::move(mesh));
        continue;
      }
      PlaneWall p;
      p.name = wallName(w);
      p.point = w.get<Eigen::Vector3d>("point");
      p.normal = w.get<Eigen::Vector3d>("normal");
      if (p.normal.norm() < 1e-12) w.failAt("normal", "must not be the zero vector.");
      p.velocity = w.get<Eigen::Vector3d>("velocity", Vec3::Zero());
      p.material = materialIndex(w, materials);
      // Every sphere material must be able to touch this wall.
      for (const auto& [m, node] : firstOfMaterial) requireLaw(sim, w, m, p.material);
      sim.planeWalls().add(p);
    }
  }
}

// Gravity, damping, skins, the end time and the time step, checked against the scene's stable and safe
// steps.
void loadTimeStep(const Config& cfg, Scene& scene) {
  auto log = common::logger("dem");
  Simulation& sim = *scene.sim;
  auto& set = sim.settings();
  set.gravity = cfg.get<Eigen::Vector3d>("gravity", Vec3(0, 0, -9.81));
  set.localDamping = cfg.get("local_damping", 0.0, Interval{0.0, 1.0, false, true});
  if (Config nb = cfg.child("neighbor")) {
    set.skin = nb.get("skin", 0.0, Interval::nonNegative());
    set.meshSkin = nb.get("mesh_skin", 0.0, Interval::nonNegative());
    set.rankMargin = nb.get("rank_margin", 0.0, Interval::nonNegative());
  }
  scene.endTime = cfg.get("end_time", Interval::positive());
  set.endTime = scene.endTime;

  set.dtSafety = cfg.get("dt_safety", 0.5, Interval{0.0, 1.0, true, false});
  set.stepsPerContact = cfg.get<int>("steps_per_contact", 20);
  if (set.stepsPerContact < 1) cfg.failAt("steps_per_contact", "must be a whole number ≥ 1.");
  scene.energyTolerance = cfg.get("energy_tolerance", 0.1, Interval{0.0, 1e3, true, true});
  const double critical = criticalTimeStep(sim);
  const double speed = approachSpeedEstimate(sim);
  const double contact = contactDuration(sim, speed);
  const double safe = safeTimeStep(sim, speed);
  const std::string check = cfg.choice("dt_check", {"error", "warn"}, "error");
  std::string limits = fmt::format("dt_safety {} × the critical step {:.4g} s (Rayleigh, smallest sphere, stiffest law)",
                                   set.dtSafety, critical);
  if (std::isfinite(contact))
    limits = fmt::format("the smaller of {} and the elastic contact duration {:.4g} s at the fastest approach this "
                         "scene can reach, {:.4g} m/s (two fastest bodies head-on + free fall over its height), over "
                         "steps_per_contact {}",
                         limits, contact, speed, set.stepsPerContact);
  if (Config dtNode = cfg.child("dt")) {
    set.dt = cfg.get("dt", Interval::positive());
    if (set.dt > safe) {
      const std::string msg = fmt::format("is above the safe step {:.4g} s: {}. Lower dt, or set dt_check: warn to run "
                                          "anyway (the run still stops with exit 3 if it then goes wrong).",
                                          safe, limits);
      if (check == "error") dtNode.fail(msg);
      log->warn("dt = {:.4g} s {}", set.dt, msg);
    }
    common::requireWholeSteps(cfg, "end_time", scene.endTime, set.dt);
  } else {
    const double fraction = cfg.get("dt_fraction", 0.2, Interval{0.0, 1.0, true, false});
    const double wanted = std::min(fraction * critical, contact / set.stepsPerContact);
    if (!std::isfinite(wanted)) cfg.failAt("dt", "no contact law bounds the time step; give dt explicitly.");
    common::requireStepCount(cfg, "dt_fraction", scene.endTime, wanted);
    set.dt = scene.endTime / std::ceil(scene.endTime / wanted);  // end_time in whole steps
    log->info("dt = {:.4g} s (≤ dt_fraction {} × critical {:.4g} s and ≤ the contact duration {:.4g} s at {:.4g} m/s "
              "over {} steps)",
              set.dt, fraction, critical, contact, speed, set.stepsPerContact);
  }

}

// `output:`, with the defaults that follow from the bodies and the time step.
void loadOutput(const Config& cfg, Scene& scene) {
  scene.output.interval = scene.endTime / 100;
  const std::size_t nb = scene.sim->bodies().size();
  if (nb <= 8)
    for (std::uint32_t b = 0; b < nb; ++b) scene.output.track.push_back(b);
  if (Config out = cfg.child("output")) {
    scene.output.interval = out.get("interval", scene.output.interval, Interval::nonNegative());
    if (auto t = out.find<std::vector<int>>("track")) {
      scene.output.track.clear();
      for (int b : *t) {
        if (b < 0 || static_cast<std::size_t>(b) >= nb)
          out.failAt("track", fmt::format("body {} does not exist (the scene has {} bodies).", b, nb));
        scene.output.track.push_back(static_cast<std::uint32_t>(b));
      }
    }
    scene.output.seriesInterval = out.get("series_interval", 0.0, Interval::nonNegative());
    scene.output.checkpointInterval = out.get("checkpoint_interval", 0.0, Interval::nonNegative());
  }
  if (scene.output.seriesInterval == 0.0) scene.output.seriesInterval = std::max(scene.sim->settings().dt, scene.endTime / 2000);

}

// `probe:`.
void loadProbe(const Config& cfg, Scene& scene) {
  if (Config probe = cfg.child("probe")) {
    const std::string type = probe.choice("type", {"impact", "acceleration", "packing"});
    scene.probe.kind = type == "impact"         ? ProbeSettings::Kind::kImpact
                       : type == "acceleration" ? ProbeSettings::Kind::kAcceleration
                                                : ProbeSettings::Kind::kPacking;
    if (scene.probe.kind == ProbeSettings::Kind::kPacking) {
      scene.probe.regionMin = probe.get<Eigen::Vector3d>("min");
      scene.probe.regionMax = probe.get<Eigen::Vector3d>("max");
      if ((scene.probe.regionMax - scene.probe.regionMin).minCoeff() <= 0)
        probe.failAt("max", "must be above min in every direction.");
    }
    const auto body = probe.get<std::size_t>("body", 0);
    const std::size_t nb = scene.sim->bodies().size();
    if (body >= nb) probe.failAt("body", fmt::format("body {} does not exist (the scene has {} bodies).", body, nb));
    scene.probe.body = static_cast<std::uint32_t>(body);
    if (scene.probe.kind == ProbeSettings::Kind::kAcceleration) {
      scene.probe.direction = probe.get<Eigen::Vector3d>("direction").normalized();
      scene.probe.from = probe.get("from", 0.0, Interval::nonNegative());
    }
  }

}

// `interface:`, the mesh wall a coupled run drives.
void loadInterface(const Config& cfg, Scene& scene) {
  if (Config itf = cfg.child("interface")) {
    scene.interfaceWall = itf.get<std::string>("wall");
    const auto& meshes = scene.sim->meshWalls().walls();
    auto it = std::find_if(meshes.begin(), meshes.end(), [&](const MeshWall& w) { return w.name == scene.interfaceWall; });
    if (it == meshes.end()) itf.failAt("wall", "is not the name of a mesh wall of this scene.");
    if (it->motion != MeshWall::Motion::kExternal) itf.failAt("wall", "the interface wall needs `motion: external`.");
  }
}

}  // namespace

std::map<std::string, std::uint32_t> loadMaterials(const Config& cfg, Simulation& sim) {
  std::map<std::string, std::uint32_t> materials;
  for (const auto& [name, m] : cfg.at("materials").entries()) {
    Material mat;
    mat.name = name;
    mat.density = m.get("density", Interval::positive());
    mat.rigid = m.get<bool>("rigid", false);
    mat.youngModulus = m.get("young_modulus", 0.0, Interval::nonNegative());
    mat.poissonRatio = m.get("poisson_ratio", 0.25, Interval::open(-1.0, 0.5));
    if (mat.rigid && m.has("young_modulus"))
      m.failAt("young_modulus", "a rigid material has no Young's modulus; leave it out (or drop rigid: true).");
    materials[name] = sim.interactions().addMaterial(mat);
  }
  if (materials.empty()) cfg.failAt("materials", "define at least one material.");
  return materials;
}

void loadInteractions(const Config& cfg, Simulation& sim, const std::map<std::string, std::uint32_t>& materials,
                      const LawOverride& change) {
  std::vector<std::string> materialNames;
  for (const auto& [n, i] : materials) materialNames.push_back(n);
  const Config interactions = cfg.at("interactions");
  for (const auto& entry : interactions.elements()) {
    const Config pair = entry.at("materials");
    const auto names = pair.as<std::vector<std::string>>();
    if (names.size() != 2) pair.fail("expected two material names, e.g. [rock, steel].");
    std::uint32_t ids[2];
    for (int k = 0; k < 2; ++k) {
      auto it = materials.find(names[static_cast<std::size_t>(k)]);
      if (it == materials.end()) {
        std::string hint;
        if (auto s = common::suggest(names[static_cast<std::size_t>(k)], materialNames))
          hint = fmt::format(" Did you mean \"{}\"?", *s);
        pair.elements()[static_cast<std::size_t>(k)].fail(fmt::format("is not a material of this scene.{}", hint));
      }
      ids[k] = it->second;
    }
    if (sim.interactions().law(ids[0], ids[1]))
      entry.fail(fmt::format("the pair ({}, {}) is given a law twice.", names[0], names[1]));
    const std::string law = entry.choice("law", contactLawNames());
    sim.interactions().set(ids[0], ids[1],
                       makeContactLaw(law, entry, sim.interactions().materials()[ids[0]], sim.interactions().materials()[ids[1]], change));
  }
}

Scene loadScene(const Config& cfg, bool initialize) {
  Scene scene;
  scene.sim = std::make_unique<Simulation>();
  Simulation& sim = *scene.sim;

  const Materials materials = loadMaterials(cfg, sim);
  loadInteractions(cfg, sim, materials);
  BodyNodes nodes;
  loadSpheres(cfg, sim, materials, nodes);
  loadGenerated(cfg, sim, materials, nodes);
  loadClusters(cfg, sim, materials, nodes);
  if (sim.bodies().size() == 0) cfg.failAt("spheres", "the scene has no bodies; add spheres or clusters.");

  // The first body of each material stands for it in error messages.
  std::map<std::uint32_t, Config> firstOfMaterial;
  for (const auto& run : nodes.runs) firstOfMaterial.emplace(run.material, run.node);
  for (const auto& [m, node] : firstOfMaterial)
    if (sim.interactions().materials()[m].rigid)
      node.failAt("material", fmt::format("material \"{}\" is rigid: walls only (a body needs a finite stiffness for its "
                                          "own time step).",
                                          sim.interactions().materials()[m].name));
  loadWalls(cfg, sim, materials, firstOfMaterial);
  for (const auto& [mi, node] : firstOfMaterial)
    for (const auto& [mj, other] : firstOfMaterial)
      if (mj <= mi && (mi != mj || nodes.bodies > 1)) requireLaw(sim, node, mi, mj);

  loadTimeStep(cfg, scene);
  loadOutput(cfg, scene);
  loadProbe(cfg, scene);
  loadInterface(cfg, scene);
  if (Config b = cfg.child("bridging")) sim.settings().bridging = common::readBridgingZone(b);
  cfg.checkUnknownKeys();
  if (!initialize) return scene;
  sim.initialize();
  const auto [a, b, overlap] = largestSphereOverlap(sim);
  const double tolerance = 1e-3 * std::min(sim.spheres().radius[a], sim.spheres().radius[b]);
  if (overlap > tolerance)
    nodes.nodeOf(sim.spheres().body[b]).fail(
        fmt::format("this body overlaps body {} by {:.4g} m at the start (tolerance {:.3g} m = 0.1 % of the smaller "
                    "sphere radius); move them apart.",
                    sim.spheres().body[a], overlap, tolerance));
  return scene;
}

}  // namespace dem
