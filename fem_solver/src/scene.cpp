#include "fem/scene.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <set>

#include <fmt/format.h>

#include "common/config.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/memory.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "fem/bridging.hpp"
#include "fem/static_cache.hpp"
#include "element_registry.hpp"

namespace fem {

using common::Config;
using common::Interval;

namespace {


const Mesh::Group& requireGroup(const Config& where, const Mesh& mesh) {
  const std::string name = where.get<std::string>("group");
  if (const Mesh::Group* g = mesh.group(name)) return *g;
  std::string list, hint;
  for (const auto& n : mesh.groupNames()) list += (list.empty() ? "" : ", ") + n;
  if (auto s = common::suggest(name, mesh.groupNames())) hint = fmt::format(" Did you mean \"{}\"?", *s);
  where.failAt("group", fmt::format("the mesh has no physical group \"{}\" (it has: {}).{}", name, list, hint));
}

// A lower bound of the memory a generated mesh of `elements` takes to build and solve (≈ 300 bytes per
// element: nodes, connectivity, element state, its share of the sparse matrix); refused before
// generating if the machine cannot hold it.
void requireMemoryFor(const Config& where, const char* key, double elements) {
  if (auto shortfall = common::memoryShortfall(300.0 * elements, fmt::format("{:.3g} elements", elements)))
    where.failAt(key, fmt::format("{}. Use fewer, larger elements.", *shortfall));
}

Mesh loadMesh(const Config& m) {
  try {
    if (Config r = m.child("rectangle")) {
      const auto size = r.get<std::vector<double>>("size");
      if (size.size() != 2 || !(size[0] > 0 && size[1] > 0)) r.failAt("size", "expected [lx, ly] > 0.");
      const double h = r.get("element_size", Interval::positive());
      requireMemoryFor(r, "element_size", 2.0 * std::ceil(size[0] / h) * std::ceil(size[1] / h));
      return rectangleMesh(size[0], size[1], h, r.get<bool>("structured", true), r.get<Eigen::Vector3d>("origin", Vec3::Zero()));
    }
    if (Config b = m.child("box")) {
      const Vec3 size = b.get<Eigen::Vector3d>("size");
      if (size.minCoeff() <= 0) b.failAt("size", "expected [lx, ly, lz] > 0.");
      const double h = b.get("element_size", Interval::positive());
      requireMemoryFor(b, "element_size", 5.0 * std::ceil(size.x() / h) * std::ceil(size.y() / h) * std::ceil(size.z() / h));
      return boxMesh(size, h, b.get<Eigen::Vector3d>("origin", Vec3::Zero()));
    }
    if (Config l = m.child("line")) {
      const int n = l.get<int>("elements");
      if (n < 1) l.failAt("elements", "must be at least 1.");
      requireMemoryFor(l, "elements", n);
      return lineMesh(l.get<Eigen::Vector3d>("start"), l.get<Eigen::Vector3d>("end"), n);
    }
    return readMesh(m.filePath("file"));
  } catch (const common::SimulationError& e) {
    m.fail(e.what());
  }
}

std::vector<int> components(const Config& c, const std::string& key) {
  std::vector<int> out;
  for (const auto& e : c.at(key).elements()) {
    const std::string a = e.as<std::string>();
    if (a == "x") out.push_back(0);
    else if (a == "y") out.push_back(1);
    else if (a == "z") out.push_back(2);
    else e.fail("expected x, y or z.");
  }
  return out;
}

using ElementMaterials = std::map<std::string, ElementMaterial>;

// `materials:`.
ElementMaterials loadMaterials(const Config& cfg) {
  std::map<std::string, ElementMaterial> materials;
  for (const auto& [name, m] : cfg.at("materials").entries())
    materials[name] = {m.get("young_modulus", Interval::positive()), m.get("poisson_ratio", 0.0, Interval{-1, 0.5, true, true}),
                       m.get("density", Interval::positive())};
  return materials;
}

// `elements:`, each block of a registered type on a mesh group of its dimension.
void loadElements(const Config& cfg, const ElementMaterials& materials, Scene& scene) {
  Model& model = scene.model;
  std::vector<std::string> materialNames;
  for (const auto& [n, m] : materials) materialNames.push_back(n);
  for (const auto& e : cfg.at("elements").elements()) {
    const std::string type = e.choice("type", elementTypes().names());
    const ElementType& kind = elementTypes().at(type);
    const Mesh::Group& g = requireGroup(e, scene.mesh);
    const ElementMaterial& mat = materials.at(e.choice("material", materialNames));
    if (g.dim != kind.dimension)
      e.failAt("group", fmt::format("{} needs a {}-D group of {}; \"{}\" is {}-D.", type, kind.dimension,
                                    kind.dimension == 2 ? "triangles" : kind.dimension == 3 ? "tetrahedra" : "lines",
                                    e.get<std::string>("group"), g.dim));
    try {
      model.blocks.push_back(kind.make(e, g.connectivity, model.reference, mat));
    } catch (const common::SimulationError& err) {
      e.fail(err.what());
    }
    scene.blockGroups.push_back(e.get<std::string>("group"));
  }
}

// `boundary_conditions:`; the nodes no element uses are fixed too.
void loadBoundaryConditions(const Config& cfg, Scene& scene) {
  Model& model = scene.model;
  // Nodes no element uses would have zero mass and no stiffness.
  std::vector<std::uint8_t> used(model.nodes(), 0);
  for (const auto& b : model.blocks)
    for (auto n : b->connectivity()) used[n] = 1;

  model.fixed.assign(model.dofs(), 0);
  model.prescribed.assign(model.dofs(), 0.0);
  model.deadLoad.assign(model.dofs(), 0.0);
  if (Config bcs = cfg.child("boundary_conditions")) {
    for (const auto& bc : bcs.elements()) {
      const Mesh::Group& g = requireGroup(bc, scene.mesh);
      const auto comps = components(bc, "fixed");
      const Vec3 value = bc.get<Eigen::Vector3d>("displacement", Vec3::Zero());
      for (auto n : g.nodes)
        for (int k : comps) {
          model.fixed[3 * n + static_cast<std::size_t>(k)] = 1;
          model.prescribed[3 * n + static_cast<std::size_t>(k)] = value[k];
        }
      scene.reactionGroups.push_back({bc.get<std::string>("group"), g.nodes});
    }
  }
  for (std::size_t n = 0; n < model.nodes(); ++n)
    if (!used[n])
      for (int k = 0; k < 3; ++k) model.fixed[3 * n + static_cast<std::size_t>(k)] = 1;

}

// `loads:`: gravity, pressures on membranes, forces spread over a group's nodes.
void loadLoads(const Config& cfg, Scene& scene) {
  Model& model = scene.model;
  if (Config loads = cfg.child("loads")) {
    for (const auto& l : loads.elements()) {
      const std::string type = l.choice("type", {"gravity", "pressure", "force"});
      if (type == "gravity") {
        model.gravity = l.get<Eigen::Vector3d>("acceleration");
      } else if (type == "pressure") {
        const Mesh::Group& g = requireGroup(l, scene.mesh);
        const std::string group = l.get<std::string>("group");
        const double q = l.get<double>("value");
        const Vec3 dir = l.get<Eigen::Vector3d>("direction", Vec3(0, 0, -1)).normalized();
        bool applied = false;
        for (std::size_t b = 0; b < model.blocks.size(); ++b)
          if (scene.blockGroups[b] == group) {
            model.blocks[b]->addPressure(q, dir, model.deadLoad);
            applied = true;
          }
        if (!applied || g.dim != 2) l.failAt("group", "a pressure needs a group of membrane elements.");
      } else {
        const Mesh::Group& g = requireGroup(l, scene.mesh);
        const Vec3 f = l.get<Eigen::Vector3d>("force") / static_cast<double>(g.nodes.size());
        for (auto n : g.nodes)
          for (int k = 0; k < 3; ++k) model.deadLoad[3 * n + static_cast<std::size_t>(k)] += f[k];
      }
    }
  }

}

// `analysis:`, `static:` and `explicit:`: the solve and its time step, checked against the critical step.
void loadAnalysis(const Config& cfg, Scene& scene) {
  Model& model = scene.model;
  scene.analysis = cfg.choice("analysis", {"static", "explicit"});
  if (Config st = cfg.child("static")) {
    scene.staticSettings.method = st.choice("method", {"newton", "dynamic_relaxation"}, "newton") == "newton"
                                      ? StaticSettings::Method::kNewton
                                      : StaticSettings::Method::kDynamicRelaxation;
    scene.staticSettings.fallback = st.get<bool>("fallback", true);
    scene.staticSettings.relaxationIterations = st.get<int>("relaxation_iterations", 200000);
    scene.staticSettings.loadSteps = st.get<int>("load_steps", 1);
    if (scene.staticSettings.loadSteps < 1) st.failAt("load_steps", "must be at least 1.");
    scene.staticSettings.maxIterations = st.get<int>("max_iterations", 50);
    scene.staticSettings.tolerance = st.get("tolerance", 1e-8, Interval::positive());
    scene.staticSettings.continuationStart = st.get("prestress_continuation", 0.0, Interval::nonNegative());
    scene.rampTime = st.get("ramp_time", 0.0, Interval::nonNegative());
  }
  if (scene.analysis == "explicit") {
    const Config ex = cfg.at("explicit");
    const bool bySteps = ex.has("steps");
    if (!bySteps) scene.endTime = ex.get("end_time", Interval::positive());
    const std::string initial = ex.choice("initial_state", {"none", "static", "file"}, "none");
    scene.initialStatic = initial == "static";
    if (initial == "file") scene.initialStateFile = ex.filePath("initial_state_file");
    if (Config d = ex.child("damping")) {
      model.alpha = d.get("alpha", 0.0, Interval::nonNegative());
      model.beta = d.get("beta", 0.0, Interval::nonNegative());
    }
    const double critical = model.criticalTimeStep();
    const double safety = scene.dtSafety = ex.get("dt_safety", 0.9, Interval{0, 1, true, false});
    scene.dtWarnOnly = ex.choice("dt_check", {"error", "warn"}, "error") == "warn";
    scene.energyTolerance = ex.get("energy_tolerance", 0.1, Interval{0.0, 1e3, true, true});
    if (Config dt = ex.child("dt")) {
      scene.dt = ex.get("dt", Interval::positive());
      if (scene.dt > safety * critical) {
        const std::string msg = fmt::format(
            "is above the safe step {:.4g} s = dt_safety {} × critical {:.4g} s (smallest element, reference "
            "configuration). Lower dt, or set explicit.dt_check: warn to run anyway (the run still stops with exit 3 "
            "if it then goes wrong).",
            safety * critical, safety, critical);
        if (!scene.dtWarnOnly) dt.fail(msg);
        common::logger("fem")->warn("explicit.dt = {:.4g} s {}", scene.dt, msg);
      }
      if (!bySteps) common::requireWholeSteps(ex, "end_time", scene.endTime, scene.dt);
    } else {
      scene.dtFraction = ex.get("dt_fraction", 0.8, Interval{0, 1, true, false});
      scene.dt = scene.dtFraction * critical;
      if (!bySteps) common::requireStepCount(ex, "dt_fraction", scene.endTime, scene.dt);
      if (!bySteps) scene.dt = scene.endTime / std::ceil(scene.endTime / scene.dt);  // end_time in whole steps
    }
    scene.bySteps = bySteps;
    if (bySteps) {
      const auto steps = ex.get<std::size_t>("steps");
      if (steps == 0) ex.failAt("steps", "must be at least 1.");
      if (static_cast<double>(steps) > 1e12) ex.failAt("steps", "is more than the 1e+12 steps a run may take.");
      scene.endTime = static_cast<double>(steps) * scene.dt;
    }
  }
}

// `output:`, `probes:` and `interface:`.
void loadOutput(const Config& cfg, Scene& scene) {
  Model& model = scene.model;
  if (Config out = cfg.child("output")) {
    scene.outputInterval = out.get("interval", 0.0, Interval::nonNegative());
    scene.seriesInterval = out.get("series_interval", 0.0, Interval::nonNegative());
    scene.checkpointInterval = out.get("checkpoint_interval", 0.0, Interval::nonNegative());
  }
  if (Config probes = cfg.child("probes"))
    for (const auto& p : probes.elements()) {
      std::uint32_t node = 0;
      if (auto point = p.find<Eigen::Vector3d>("point")) {  // the nearest node
        for (std::uint32_t i = 0; i < model.nodes(); ++i)
          if ((model.reference[i] - *point).squaredNorm() < (model.reference[node] - *point).squaredNorm()) node = i;
      } else {
        node = requireGroup(p, scene.mesh).nodes.front();
      }
      scene.probes.push_back({p.get<std::string>("name"), node});
    }
  if (Config itf = cfg.child("interface")) {
    requireGroup(itf, scene.mesh);
    scene.interfaceGroup = itf.get<std::string>("group");
    scene.interfaceMode = itf.choice("mode", {"dirichlet", "neumann"});
  }
}

// A flat membrane without prestress has no out-of-plane stiffness: Newton cannot start from it.
void refuseFlatMembranes(const Config& cfg, const Scene& scene) {
  const Model& model = scene.model;
  if ((scene.analysis == "static" || scene.initialStatic) && scene.staticSettings.continuationStart == 0.0) {
    const auto elems = cfg.at("elements").elements();
    for (std::size_t b = 0; b < model.blocks.size(); ++b) {
      const Prestressed* m = model.blocks[b]->prestressed();
      if (!m || m->prestress() > 0.0) continue;
      const auto& conn = model.blocks[b]->connectivity();
      const Vec3 a = model.reference[conn[0]];
      const Vec3 normal = (model.reference[conn[1]] - a).cross(model.reference[conn[2]] - a).normalized();
      double offPlane = 0.0, extent = 0.0;
      for (auto n : conn) {
        offPlane = std::max(offPlane, std::abs((model.reference[n] - a).dot(normal)));
        extent = std::max(extent, (model.reference[n] - a).norm());
      }
      if (offPlane <= 1e-9 * extent)
        elems[b].fail("is a flat membrane with zero prestress: its stiffness is singular out of plane, so a static "
                      "solve cannot start. Give a prestress > 0, or static.prestress_continuation (e.g. 1e-3 E).");
    }
  }
}

// `bridging:` and the initial conditions of an explicit run (`explicit.initial_wave`, `initial_velocity`).
void loadInitialConditions(const Config& cfg, Scene& scene) {
  Model& model = scene.model;
  if (Config b = cfg.child("bridging")) {
    if (scene.analysis != "explicit")
      b.fail("is a coupling of explicit dynamics (one common step with the particles): analysis must be explicit.");
    scene.bridging = common::readBridgingZone(b);
    weighBridgingZone(model, *scene.bridging);
  }
  if (Config w = cfg.child("explicit") ? cfg.at("explicit").child("initial_wave") : Config()) {
    if (scene.initialStatic || !scene.initialStateFile.empty())
      w.fail("starts from the reference configuration; it does not combine with explicit.initial_state.");
    scene.initialWave = readInitialWave(w);
  }
  if (Config v = cfg.child("explicit") ? cfg.at("explicit").child("initial_velocity") : Config()) {
    if (scene.initialWave) v.fail("and explicit.initial_wave both set the initial velocity; give one.");
    scene.initialVelocity = readInitialVelocity(v);
  }
}

}  // namespace

Scene loadScene(const Config& cfg) {
  Scene scene;
  scene.mesh = loadMesh(cfg.at("mesh"));
  Model& model = scene.model;
  model.reference = scene.mesh.nodes;
  loadElements(cfg, loadMaterials(cfg), scene);
  loadBoundaryConditions(cfg, scene);
  loadLoads(cfg, scene);
  loadAnalysis(cfg, scene);
  loadOutput(cfg, scene);
  refuseFlatMembranes(cfg, scene);
  loadInitialConditions(cfg, scene);
  cfg.checkUnknownKeys();
  model.finalize();
  if (scene.initialWave) scene.initialWave->apply(model);
  if (scene.initialVelocity) scene.initialVelocity->apply(model);
  if (!scene.initialStateFile.empty()) {
    try {
      model.setDisplacement(common::readH5Array(scene.initialStateFile, "/state/displacement"));
    } catch (const common::SimulationError& e) {
      cfg.at("explicit").failAt("initial_state_file", e.what());
    }
  }
  return scene;
}

std::vector<Vec3> groupReactions(const Scene& scene) {
  std::vector<Vec3> out;
  for (const auto& r : scene.reactionGroups) {
    Vec3 sum = Vec3::Zero();
    for (auto n : r.nodes) sum += scene.model.supportForce(n);
    out.push_back(sum);
  }
  return out;
}

void reportProbesAndReactions(const Scene& scene, common::Summary& summary, const std::string& suffix) {
  const auto& u = scene.model.displacement();
  for (const auto& p : scene.probes) {
    const Vec3 d(u[3 * p.node], u[3 * p.node + 1], u[3 * p.node + 2]);
    summary.set(p.name + "_sag" + suffix, -d.z());
    summary.set(p.name + "_displacement" + suffix, std::vector<double>{d.x(), d.y(), d.z()});
  }
  const auto r = groupReactions(scene);
  for (std::size_t i = 0; i < r.size(); ++i)
    summary.set("reaction_" + scene.reactionGroups[i].name + suffix, std::vector<double>{r[i].x(), r[i].y(), r[i].z()});
}

void addMeshes(common::H5Writer& h5, const Scene& scene) {
  const Model& model = scene.model;
  std::vector<double> nodes;
  for (const auto& x : model.reference) nodes.insert(nodes.end(), {x.x(), x.y(), x.z()});
  for (std::size_t b = 0; b < model.blocks.size(); ++b) {
    const auto& conn = model.blocks[b]->connectivity();
    std::vector<std::int64_t> cells(conn.begin(), conn.end());
    h5.addMesh(scene.blockGroups[b], nodes, cells, model.blocks[b]->cellType());
  }
}

SeriesRecorder::SeriesRecorder(common::H5Writer& h5, const Scene& scene) : h5_(h5), scene_(scene) {
  std::vector<std::string> reactionCols, probeCols;
  for (const auto& r : scene.reactionGroups)
    for (const char* c : {"_fx", "_fy", "_fz"}) reactionCols.push_back(r.name + c);
  for (const auto& p : scene.probes)
    for (const char* c : {"_ux", "_uy", "_uz"}) probeCols.push_back(p.name + c);
  reactions_ = !reactionCols.empty();
  probes_ = !probeCols.empty();
  if (reactions_) h5.addSeries("reactions", reactionCols);
  if (probes_) h5.addSeries("probes", probeCols);
  h5.addSeries("energy", {"kinetic", "strain", "external_work", "damping", "coupled_work", "residual"});
}

SeriesRecorder::Row SeriesRecorder::sample(double t, double initialEnergy) const {
  Row row;
  row.time = t;
  for (const auto& r : groupReactions(scene_)) row.reactions.insert(row.reactions.end(), {r.x(), r.y(), r.z()});
  const auto& u = scene_.model.displacement();
  for (const auto& p : scene_.probes) row.probes.insert(row.probes.end(), {u[3 * p.node], u[3 * p.node + 1], u[3 * p.node + 2]});
  const EnergyState& e = scene_.model.energy();
  row.energy = {e.kinetic, e.strain, e.externalWork, e.damping, e.coupledWork,
                e.kinetic + e.strain + e.damping - e.externalWork - initialEnergy - e.initialShift};
  return row;
}

void SeriesRecorder::write(const Row& row) {
  if (row.time < 0) return;
  if (reactions_) h5_.append("reactions", row.time, row.reactions);
  if (probes_) h5_.append("probes", row.time, row.probes);
  h5_.append("energy", row.time, row.energy);
}

void writeSnapshot(common::H5Writer& h5, const Scene& scene, double time, bool coupled) {
  const Model& model = scene.model;
  const auto x = model.positions();
  const std::vector<double>&v = model.velocity(), &u = model.displacement();
  for (std::size_t b = 0; b < model.blocks.size(); ++b) {
    const auto& blk = *model.blocks[b];
    std::vector<double> stress(blk.size() * static_cast<std::size_t>(blk.stressComponents()));
    blk.stress(u, stress);
    std::vector<common::Field> points{{"displacement", 3, u}, {"velocity", 3, v}};
    // Coupled: the force the other side puts on each node (the contact force of a rockfall block).
    if (coupled) points.push_back({"coupled_force", 3, model.coupledForce});
    h5.writeMeshSnapshot(scene.blockGroups[b], time, x, points,
                         {{blk.stressComponents() == 1 ? "axial_force" : "pk2_stress", blk.stressComponents(), stress}});
  }
}

static std::string physicsOf(const Scene& scene, bool enabled) {
  // What the run computes: element kinds, and the optional parts — a static solve, mass- and
  // stiffness-proportional damping (β K v costs a second internal-force pass per step), a followed step.
  std::set<std::string> kinds;
  for (const auto& b : scene.model.blocks) kinds.insert(b->name());
  std::vector<std::pair<std::string, bool>> parts;
  for (const ElementType& type : elementTypes().entries()) parts.emplace_back(type.name, kinds.count(type.name) > 0);
  parts.emplace_back("static_solve", scene.analysis == "static" || scene.initialStatic);
  parts.emplace_back("explicit_dynamics", scene.analysis == "explicit");
  parts.emplace_back("mass_damping", scene.model.alpha > 0.0);
  parts.emplace_back("stiffness_damping", scene.model.beta > 0.0);
  parts.emplace_back("followed_step", scene.analysis == "explicit" && scene.dtFraction > 0.0);
  std::string out;
  for (const auto& [name, on] : parts)
    if (on == enabled) out += (out.empty() ? "" : ", ") + name;
  return out;
}

namespace {
constexpr const char* kStandaloneKind = "fem_solver standalone";
}  // namespace

void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart) {
  auto log = common::logger("fem");
  Model& model = scene.model;
  log->info("{} nodes, {} element blocks ({} elements), analysis {}", model.nodes(), model.blocks.size(),
            [&] {
              std::size_t n = 0;
              for (const auto& b : model.blocks) n += b->size();
              return n;
            }(),
            scene.analysis);
  // A restart reopens the results where the checkpoint left them; the state is read once the loop's
  // parts exist (below).
  if (!restart.empty() && scene.analysis != "explicit")
    throw common::ConfigError(fmt::format("--restart: a {} analysis has no steps to continue from", scene.analysis));
  common::ResultsFile results =
      common::openResults(outDir / "fem.h5", restart, kStandaloneKind, model.shape(), outDir / "checkpoint" / "fem.h5");
  std::optional<common::StateArchive>& from = results.restart;
  common::H5Writer& h5 = *results.h5;
  addMeshes(h5, scene);
  SeriesRecorder series(h5, scene);

  auto reactions = [&] { return groupReactions(scene); };
  auto probeDisplacement = [&](const Probe& p) {
    const auto& u = model.displacement();
    return Vec3(u[3 * p.node], u[3 * p.node + 1], u[3 * p.node + 2]);
  };
  auto writeSnapshot = [&](double t) { fem::writeSnapshot(h5, scene, t, false); };
  auto writeSeries = [&](double t, double initialEnergy) { series.write(series.sample(t, initialEnergy)); };

  auto reportProbes = [&](const std::string& suffix) { reportProbesAndReactions(scene, summary, suffix); };

  if (!from && (scene.analysis == "static" || scene.initialStatic)) {
    const auto start = std::chrono::steady_clock::now();
    // An explicit run's initial static state is the same for every run of this structure and load:
    // solved once, then reused (fem/static_cache.hpp).
    bool reused = false;
    StaticReport rep;
    if (scene.analysis == "static") {
      rep = model.solveStatic(scene.staticSettings);
    } else {
      const CachedStatic cached = solveStaticCached(model, scene.staticSettings);
      rep = cached.report;
      reused = cached.reused;
      summary.set("static_reused", static_cast<std::int64_t>(reused));
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    log->info("static: {} stages, {} load steps, {} Newton iterations, residual {:.3g}, {:.3f} s", rep.stages,
              rep.loadSteps, rep.iterations, rep.residual, seconds);
    summary.set("static_iterations", static_cast<std::int64_t>(rep.iterations));
    summary.set("relaxation_iterations", static_cast<std::int64_t>(rep.relaxationIterations));
    // The static state, for explicit runs that start from it (explicit.initial_state: file).
    h5.writeArray("/state/displacement", model.displacement(), 3);
    summary.set("static_residual", rep.residual);
    summary.set("static_time_s", seconds);
    summary.set("strain_energy_static", model.strainEnergy());
    reportProbes(scene.analysis == "static" ? "" : "_static");
    if (scene.analysis == "static") {
      writeSnapshot(0.0);
      writeSeries(0.0, 0.0);
      summary.setCost("physics", physicsOf(scene, true));
      summary.setCost("physics_left_out", physicsOf(scene, false));
      return;
    }
  }

  model.initializeExplicit(scene.dt);
  const auto loopStart = std::chrono::steady_clock::now();
  double initial = model.energy().kinetic + model.energy().strain;
  const double seriesEvery = scene.seriesInterval > 0 ? scene.seriesInterval : std::max(scene.dt, scene.endTime / 2000);
  // The current state (stable step, most compressed element) is checked at every series row and at
  // least every 64 steps: it costs about one internal-force pass.
  constexpr std::int64_t kCheckEvery = 64;
  const double referenceCritical = model.criticalTimeStep();
  double nextSeries = 0.0, nextSnap = 0.0, maxResidual = 0.0, scale = 0.0;
  double criticalMin = referenceCritical, jacobianMin = std::numeric_limits<double>::infinity();
  double dtMin = scene.dt, dtMax = scene.dt;
  std::int64_t lastCheck = -kCheckEvery;
  bool warnedDt = false;
  std::map<std::string, double> maxSag;
  std::vector<double> maxReaction(scene.reactionGroups.size(), 0.0);
  auto where = [&](std::size_t block, std::size_t element) {
    return fmt::format("{} element {} of block {}", model.blocks[block]->name(), element, scene.blockGroups[block]);
  };
  auto checkCurrent = [&](bool follow) {
    lastCheck = model.steps();
    const Model::Current now = model.current();
    criticalMin = std::min(criticalMin, now.criticalTimeStep);
    jacobianMin = std::min(jacobianMin, now.jacobian);
    if (now.jacobian <= 0.0)
      throw common::InstabilityError(
          {"element inverted", where(now.block, now.element), model.time(),
           fmt::format("its volume ratio det F = {:.3g} ≤ 0: the element turned inside out under the load", now.jacobian),
           "a smaller load, or a finer mesh where the solid is crushed: St. Venant–Kirchhoff offers no resistance to "
           "compression beyond det F → 0, so a strongly compressed solid needs another material law"});
    if (scene.dtFraction > 0.0) {
      if (!follow) return;
      // Follow the stable step: a stretched membrane or cable is stiffer and its waves faster. Each change
      // of step costs the scheme a little of its energy conservation, so the step changes only when the
      // stable step moved by a few per cent (and never stays above 0.99 of it).
      const double follow = std::min(scene.dtFraction * now.criticalTimeStep, scene.dtFraction * referenceCritical);
      const double dt = model.dt();
      if (dt > std::min(1.02 * follow, 0.99 * now.criticalTimeStep) || follow > 1.05 * dt) {
        // The remaining time in whole steps: the run lands on end_time exactly.
        const double remaining = scene.endTime - model.time();
        model.setTimeStep(remaining / std::ceil(remaining / follow - 1e-9));
        dtMin = std::min(dtMin, model.dt()), dtMax = std::max(dtMax, model.dt());
      }
    } else if (model.dt() > now.criticalTimeStep && !warnedDt) {
      warnedDt = true;
      log->warn("t = {:.4g} s: dt = {:.4g} s is above the stable step of the deformed state, {:.4g} s (reference {:.4g} s; "
                "{}, the most compressed element, has Jacobian {:.3g}). The energy check stops the run if it diverges; "
                "leave explicit.dt out to follow the stable step.",
                model.time(), model.dt(), now.criticalTimeStep, referenceCritical, where(now.block, now.element),
                now.jacobian);
    }
  };
  auto energyCheck = [&] {
    const EnergyState& e = model.energy();
    scale = std::max(scale, std::abs(e.externalWork) + std::abs(initial) + e.kinetic);
    const double residual = e.kinetic + e.strain + e.damping - e.externalWork - initial - e.initialShift;
    maxResidual = std::max(maxResidual, std::abs(residual));
    // Round-off: the balance subtracts terms as large as each of them.
    const double roundOff = 1e-9 * (std::abs(e.kinetic) + std::abs(e.strain) + std::abs(e.externalWork) +
                                    std::abs(initial) + std::abs(e.initialShift));
    if (std::abs(residual) <= scene.energyTolerance * scale + roundOff) return;
    const Model::Current now = model.current();
    const auto& v = model.velocity();
    std::size_t fastest = 0;
    double kinetic = 0.0;  // ½ m v² at the half step: the shadow form turns negative when steps alternate
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (std::abs(v[i]) > std::abs(v[fastest])) fastest = i;
      kinetic += 0.5 * model.nodeMass()[i / 3] * v[i] * v[i];
    }
    const bool growth = residual > 0 || kinetic > scale;
    // The deformed state's stable step once the run has blown up says little: the smallest seen does.
    const double safe = scene.dtSafety * std::min({now.criticalTimeStep, referenceCritical, criticalMin});
    const std::string dtFix = common::wholeStepValue(scene.bySteps ? 0.0 : scene.endTime, safe);
    throw common::InstabilityError(
        {growth ? "energy growth" : "energy loss", fmt::format("node {}", fastest / 3), model.time(),
         fmt::format("the energy balance is off by {:.4g} J, {:.3g} of the run's energy scale {:.4g} J (allowed {:.3g}, "
                     "key explicit.energy_tolerance); node {} moves at {:.4g} m/s; dt = {:.4g} s, the stable step now "
                     "{:.4g} s (reference {:.4g} s)",
                     residual, std::abs(residual) / std::max(scale, 1e-300), scale, scene.energyTolerance, fastest / 3,
                     std::abs(v[fastest]), model.dt(), now.criticalTimeStep, referenceCritical),
         safe < model.dt()
             ? fmt::format("explicit.dt = {} s (at most dt_safety {} × the smallest stable step seen{}), or leave "
                           "explicit.dt out so that explicit.dt_fraction follows the stable step",
                           dtFix, scene.dtSafety, scene.bySteps ? "" : "; end_time in whole steps")
             : fmt::format("not the time step (dt = {:.4g} s is below dt_safety × the smallest stable step seen, {:.4g} "
                           "s): the energy came with the loads or, in a coupled run, with the interface forces (a "
                           "smaller coupling.time_window, a tighter coupling tolerance or an implicit scheme)",
                           model.dt(), safe),
         safe < model.dt() ? std::vector<std::string>{"explicit.dt=" + dtFix}
                           : std::vector<std::string>{}});
  };
  // Everything the loop carries from step to step, for a checkpoint: one list, written and read.
  double nextCheckpoint = scene.checkpointInterval;
  std::int64_t checkpoints = 0;
  auto archive = [&](common::StateArchive& a) {
    if (!a.reading()) common::archiveExtent(a, h5);
    a.shape(model.shape());
    Model::State state = model.saveState();
    a.io("model", state);
    if (a.reading()) model.restoreState(state);
    std::vector<std::string> sagNames;
    std::vector<double> sagValues;
    for (const auto& [name, s] : maxSag) sagNames.push_back(name), sagValues.push_back(s);
    a.io("max_sag_names", sagNames), a.io("max_sag", sagValues);
    for (std::size_t i = 0; i < sagNames.size() && i < sagValues.size(); ++i) maxSag[sagNames[i]] = sagValues[i];
    a.io("max_reaction", maxReaction), a.io("initial", initial), a.io("next_series", nextSeries);
    a.io("next_snapshot", nextSnap), a.io("max_residual", maxResidual), a.io("scale", scale);
    a.io("critical_min", criticalMin), a.io("jacobian_min", jacobianMin), a.io("dt_min", dtMin), a.io("dt_max", dtMax);
    a.io("last_check", lastCheck), a.io("warned_dt", warnedDt), a.io("next_checkpoint", nextCheckpoint);
    a.io("summary", summary);  // what the static start reported
  };
  std::int64_t restartedAt = -1;  // the step the checkpoint holds: what a test of the restart checks
  if (from) {
    archive(*from);
    restartedAt = static_cast<std::int64_t>(model.steps());
    log->info("restarted from {} at t = {:.6g} s (step {})", restart.string(), model.time(), model.steps());
  }
  common::Progress bar("fem", scene.endTime, progress);
  // The same tolerance as requireWholeSteps: an end_time within 1e-6 steps of a whole number is reached
  // after exactly that number of steps.
  const double endTolerance = 1e-6 * scene.dt;
  try {
    while (model.time() < scene.endTime - endTolerance) {
      const double t = model.time();
      if (t + 0.5 * model.dt() >= nextSeries) {
        writeSeries(t, initial);
        nextSeries += seriesEvery;
        checkCurrent(true);
      } else if (model.steps() - lastCheck >= kCheckEvery) {
        checkCurrent(true);
      }
      if (scene.outputInterval > 0 && t + 0.5 * model.dt() >= nextSnap) {
        writeSnapshot(t);
        nextSnap += scene.outputInterval;
      }
      model.stepExplicit();
      energyCheck();
      for (const auto& p : scene.probes) maxSag[p.name] = std::max(maxSag[p.name], -probeDisplacement(p).z());
      const auto r = reactions();
      for (std::size_t i = 0; i < r.size(); ++i) maxReaction[i] = std::max(maxReaction[i], r[i].norm());
      if (scene.checkpointInterval > 0 && model.time() + 0.5 * model.dt() >= nextCheckpoint &&
          model.time() < scene.endTime - endTolerance) {
        nextCheckpoint += scene.checkpointInterval;
        common::StateArchive::write(outDir / "checkpoint" / "fem.h5", kStandaloneKind, archive);
        ++checkpoints;
      }
      bar.update(model.time(), model.steps());
    }
  } catch (const common::SimulationError&) {
    summary.setSteps(model.steps());
    summary.set("end_time", model.time());
    summary.set("energy_balance_error", scale > 0 ? maxResidual / scale : 0.0);
    summary.set("critical_dt", referenceCritical);
    summary.set("critical_dt_min", criticalMin);
    throw;
  }
  bar.finish(model.time(), model.steps());
  const double loopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - loopStart).count();
  summary.set("loop_wall_time_s", loopSeconds);
  summary.set("steps_per_s", loopSeconds > 0 ? static_cast<double>(model.steps()) / loopSeconds : 0.0);
  summary.setCost("time_per_step_s", model.steps() > 0 ? loopSeconds / static_cast<double>(model.steps()) : 0.0);
  summary.setCost("physics", physicsOf(scene, true));
  summary.setCost("physics_left_out", physicsOf(scene, false));
  if (scene.checkpointInterval > 0) summary.setCost("checkpoints_written", checkpoints);
  if (!restart.empty()) summary.setCost("restarted_from", restart.string());
  if (restartedAt >= 0) summary.setCost("restarted_at_step", restartedAt);
  writeSeries(model.time(), initial);
  if (scene.outputInterval > 0) writeSnapshot(model.time());
  checkCurrent(false);
  summary.setSteps(model.steps());
  summary.set("end_time", model.time());
  summary.set("dt", scene.dt);
  if (scene.dtFraction > 0.0) summary.set("dt_min", dtMin), summary.set("dt_max", dtMax);
  summary.set("critical_dt", referenceCritical);
  // The stable step of the deformed states checked (a stretched net's is shorter) and the most
  // compressed element's Jacobian.
  summary.set("critical_dt_min", criticalMin);
  summary.set("jacobian_min", jacobianMin);
  summary.set("energy_balance_error", scale > 0 ? maxResidual / scale : 0.0);
  for (const auto& [name, s] : maxSag) summary.set(name + "_sag_max", s);
  for (std::size_t i = 0; i < maxReaction.size(); ++i)
    summary.set("reaction_" + scene.reactionGroups[i].name + "_max", maxReaction[i]);
  reportProbes("");
}

}  // namespace fem
