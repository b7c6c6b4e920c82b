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

}  // namespace fem
