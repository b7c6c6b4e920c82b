#include "lattice/scene.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "common/config.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/memory.hpp"
#include "common/results_file.hpp"
#include "common/run_loop.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "lattice/closed_surface.hpp"
#include "lattice/volume_geometry.hpp"

namespace lattice {

using common::Config;
using common::Interval;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Defaults: the Lattice Geometrical Model of YADE (Kozicki & Donzé 2008; Kozicki & Tejchman 2007):
// relative stiffnesses, and critical strains of its 2007 calibration, the interface "below 6e-5" taken as 5e-5.
constexpr std::array<PhaseProperties, kPhaseCount> kDefaultPhases{{
    {{1.0, 0.6, 0.6}, 2.0e-4, 2.0e-3},    // matrix
    {{3.0, 2.1, 2.1}, 1.333e-4, 2.0e-3},  // aggregate
    {{0.7, 0.28, 0.28}, 5.0e-5, 2.0e-3},  // interface
}};

SieveCurve readSieve(const Config& s) {
  const std::string type = s.choice("type", {"fuller", "table"});
  if (type == "fuller") {
    const double dMin = s.get("d_min", Interval::positive());
    const double dMax = s.get("d_max", Interval::positive());
    if (!(dMax > dMin)) s.failAt("d_max", fmt::format("must be larger than d_min = {}.", dMin));
    return SieveCurve::fuller(dMin, dMax, s.get("exponent", 0.5, Interval::positive()),
                              static_cast<int>(s.get("classes", 12.0, Interval::closed(1, 1000))));
  }
  const Config table = s.at("table");
  std::vector<double> d, p;
  const auto rows = table.elements();
  if (rows.size() < 2) table.fail("needs at least two rows [diameter (m), passing fraction (0–1)].");
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto row = rows[i].as<std::vector<double>>();
    if (row.size() != 2) rows[i].fail("expected [diameter (m), passing fraction (0–1)].");
    if (!(row[0] > 0)) rows[i].fail("the diameter must be > 0.");
    if (!(row[1] >= 0 && row[1] <= 1)) rows[i].fail("the passing fraction must be in [0, 1].");
    if (i > 0 && !(row[0] > d.back()))
      rows[i].fail(fmt::format("the diameters must increase down the table; the row above has {}.", d.back()));
    if (i > 0 && row[1] < p.back())
      rows[i].fail(fmt::format("the sieve curve is not monotone: passing {} is below the {} of the row above (a smaller "
                               "sieve cannot pass more).",
                               row[1], p.back()));
    d.push_back(row[0]);
    p.push_back(row[1]);
  }
  if (!(p.back() > p.front())) table.fail("the passing fraction must grow from the first row to the last.");
  return SieveCurve::table(d, p);
}

PhaseProperties readPhase(const Config& phases, Phase phase) {
  PhaseProperties p = kDefaultPhases[static_cast<std::size_t>(phase)];
  const Config c = phases.valid() ? phases.child(phaseName(phase)) : Config();
  if (!c) return p;
  p.stiffness.kl = c.get("k_l", p.stiffness.kl, Interval::positive());
  p.stiffness.kb = c.get("k_b", p.stiffness.kb, Interval::nonNegative());
  p.stiffness.kt = c.get("k_t", p.stiffness.kt, Interval::nonNegative());
  p.tensileStrain = c.get("tensile_strain", p.tensileStrain, Interval::positive());
  p.compressiveStrain = c.get("compressive_strain", p.compressiveStrain, Interval::positive());
  return p;
}

// Volume specimens are loaded through the planes at both ends of their bounding box along the axis: the
// area of the boundary triangles in the upper plane is the loaded area. Both planes must hold a face.
double loadedFaceArea(const ClosedSurface& solid, int axis, const Config& loading) {
  const Box& b = solid.bounds();
  const double tol = 1e-9 * b.size[axis];
  double area[2] = {0.0, 0.0};
  const auto& X = solid.vertices();
  for (const auto& t : solid.triangles())
    for (int side = 0; side < 2; ++side) {
      const double plane = b.origin[axis] + side * b.size[axis];
      if (std::all_of(t.begin(), t.end(), [&](auto i) { return std::abs(X[i][axis] - plane) <= tol; }))
        area[side] += 0.5 * (X[t[1]] - X[t[0]]).cross(X[t[2]] - X[t[0]]).norm();
    }
  const char name = static_cast<char>('x' + axis);
  for (int side = 0; side < 2; ++side)
    if (area[side] <= 0.0)
      loading.failAt("axis", fmt::format("loads the volume through the planes {} = {:.6g} m and {:.6g} m (the ends of its bounding "
                                         "box), but it has no face in the plane {} = {:.6g} m. Choose the axis along which the "
                                         "volume ends in flat faces.",
                                         name, b.origin[axis], b.origin[axis] + b.size[axis], name,
                                         b.origin[axis] + side * b.size[axis]));
  return area[1];
}

// The specimen's keys: its shape (a box, or a gmsh volume read once every key is checked), its lattice and
// rod length.
struct SpecimenKeys {
  Config sp, geo;
  Box box;
  std::filesystem::path geometryFile;
  int volumeTag = 0;
  double geometryScale = 1.0;
  std::string kind;
  double rodLength = 0.0, minDistance = 0.0;
  std::uint64_t nodeSeed = 1;
  // Rods ≈ 16 per (rod length)³ of volume in a random lattice (1 per node and axis in a cubic one), each
  // ≈ 500 bytes while generating and solving (the 8M-rod cube: 3.68 GB peak, docs/performance.md).
  // Checked before generating: a tiny rod length otherwise fills the memory and never returns.
  void refuseUnfitting(const Box& b) const {
    const double cells = b.size.x() * b.size.y() * b.size.z() / (rodLength * rodLength * rodLength);
    const double rods = (kind == "random" ? 16.0 : 3.0) * cells;
    if (auto shortfall = common::memoryShortfall(500.0 * rods, fmt::format("about {:.3g} rods", rods)))
      sp.failAt("rod_length", fmt::format("in a {:.4g} × {:.4g} × {:.4g} m specimen {}. Raise rod_length.", b.size.x(),
                                          b.size.y(), b.size.z(), *shortfall));
  }
};

SpecimenKeys readSpecimenKeys(const Config& cfg) {
  SpecimenKeys k;
  k.sp = cfg.at("specimen");
  const Config& sp = k.sp;
  // A box (size, origin) or a closed gmsh volume (geometry), read once every key is checked.
  k.geo = sp.child("geometry");
  const Config& geo = k.geo;
  if (geo) {
    for (const char* key : {"size", "origin"})
      if (sp.has(key))
        sp.failAt(key, "cannot be combined with specimen.geometry: the volume defines the specimen's shape. Remove one of them.");
    if (!geo.isMap()) geo.fail("expected {file: FILE.geo|.step|.brep|.msh, volume: TAG (optional), scale: METRES PER UNIT (optional)}.");
    k.geometryFile = geo.filePath("file");
    k.volumeTag = static_cast<int>(geo.get("volume", 0.0, Interval::closed(1, 1e9)));
    k.geometryScale = geo.get("scale", 1.0, Interval::positive());
  } else {
    k.box.size = sp.get<Eigen::Vector3d>("size");
    if (k.box.size.minCoeff() <= 0) sp.failAt("size", "expected [lx, ly, lz] > 0.");
    k.box.origin = sp.get<Eigen::Vector3d>("origin", Vec3::Zero());
  }
  k.kind = sp.choice("lattice", {"random", "cubic"}, "random");
  if (geo && k.kind != "random") sp.failAt("lattice", "must be random with specimen.geometry (a cubic lattice needs a box).");
  k.rodLength = sp.get("rod_length", Interval::positive());
  if (!geo && k.rodLength >= k.box.size.minCoeff())
    sp.failAt("rod_length", fmt::format("is not below the smallest specimen side {} m (specimen.size): the specimen would have "
                                        "no inner node. Lower rod_length.",
                                        k.box.size.minCoeff()));
  if (!geo) k.refuseUnfitting(k.box);
  k.minDistance = k.kind == "random" ? sp.get("min_distance", 0.5, Interval{0, 0.8, false, false}) : 0.0;
  k.nodeSeed = static_cast<std::uint64_t>(k.kind == "random" ? sp.get<long>("seed", 1) : 1);
  return k;
}

struct AggregateKeys {
  Config ag;
  AggregateSettings settings;
  std::optional<SieveCurve> sieve;
};

AggregateKeys readAggregateKeys(const Config& cfg) {
  AggregateKeys a;
  a.ag = cfg.child("aggregates");
  const Config& ag = a.ag;
  if (ag) {
    a.settings.volumeFraction = ag.get("volume_fraction", Interval::open(0, 1));
    a.settings.gap = ag.get("gap", 0.0, Interval::nonNegative());
    a.settings.attempts = static_cast<int>(ag.get("attempts", 20000.0, Interval::closed(1, 1e9)));
    a.settings.seed = static_cast<std::uint64_t>(ag.get<long>("seed", 2));
    a.sieve = readSieve(ag.at("sieve"));
  }
  return a;
}

// The phases and `rod:`; returns whether the rods' area follows from the volume (no `rod.area`).
bool readPhasesAndRod(const Config& cfg, Scene& scene) {
  const Config phases = cfg.child("phases");
  for (std::size_t p = 0; p < kPhaseCount; ++p) scene.phases[p] = readPhase(phases, static_cast<Phase>(p));

  const Config rod = cfg.at("rod");
  scene.law = rod.choice("law", rodLawNames(), "beam");
  scene.section.youngModulus = rod.get("young_modulus", Interval::positive());
  const bool autoArea = !rod.has("area");
  if (!autoArea) scene.section.area = rod.get("area", Interval::positive());
  return autoArea;
}

// `interface:`, the faces a coupled run drives.
void readInterface(const Config& cfg, bool geometry, Scene& scene) {
  if (const Config itf = cfg.child("interface")) {
    // One {face, mode} map or a list of them.
    std::vector<Config> entries = itf.isSequence() ? itf.elements() : std::vector<Config>{itf};
    if (entries.empty()) itf.fail("list at least one {face: x_min|x_max|y_min|y_max|z_min|z_max, mode: dirichlet|neumann}.");
    const std::vector<std::string> faces{"x_min", "x_max", "y_min", "y_max", "z_min", "z_max"};
    bool dirichlet = false;
    for (const auto& e : entries) {
      if (!e.isMap()) e.fail("expected {face: x_min|x_max|y_min|y_max|z_min|z_max, mode: dirichlet|neumann}.");
      const std::string name = e.choice("face", faces);
      CoupledFace cf;
      cf.face.axis = name[0] - 'x';
      cf.face.side = name.substr(2) == "max" ? 1 : 0;
      cf.mode = e.choice("mode", {"dirichlet", "neumann"}) == "dirichlet" ? FaceMode::kDirichlet : FaceMode::kNeumann;
      for (const auto& other : scene.supports.coupled)
        if (other.face.axis == cf.face.axis && other.face.side == cf.face.side)
          e.failAt("face", fmt::format("\"{}\" is listed twice.", name));
      dirichlet = dirichlet || cf.mode == FaceMode::kDirichlet;
      scene.supports.coupled.push_back(cf);
    }
    if (geometry) itf.fail("is not available with specimen.geometry yet: participant mode couples the faces of a box specimen.");
    if (!dirichlet)
      itf.fail("has no dirichlet face: with only neumann faces nothing holds the lattice (its stiffness would be singular). "
               "Make at least one face `mode: dirichlet`.");
  }

}

// `loading:` (participant mode, with an `interface`, needs none; a standalone run does, checked when it
// starts). Returns it.
Config readLoading(const Config& cfg, Scene& scene) {
  const Config ld = scene.supports.coupled.empty() ? cfg.at("loading") : cfg.child("loading");
  scene.hasLoading = ld.valid();
  if (ld) {
    const std::string type = ld.choice("type", {"tension", "compression"}, "tension");
    scene.loading.direction = type == "tension" ? 1.0 : -1.0;
    const std::string axis = ld.choice("axis", {"x", "y", "z"}, "z");
    scene.supports.axis = axis[0] - 'x';
    scene.supports.lateralFixed = ld.choice("lateral", {"fixed", "free"}, "fixed") == "fixed";
    scene.loading.strainIncrement = ld.get("strain_increment", Interval::positive());
    scene.loading.maxStrain = ld.get("max_strain", Interval::positive());
    if (scene.loading.maxStrain < scene.loading.strainIncrement)
      ld.failAt("max_strain", fmt::format("is below strain_increment = {}.", scene.loading.strainIncrement));
    scene.loading.stopFraction = ld.get("stop_fraction", 0.0, Interval{0, 1, false, true});
  }
  // The axis of the coupled faces (the first listed) is the one nominal strain and crack band refer to.
  if (!scene.supports.coupled.empty() && !ld) scene.supports.axis = scene.supports.coupled.front().face.axis;
  return ld;
}

// `fracture:`, `solver:` and `output:`.
void readFractureSolverOutput(const Config& cfg, Scene& scene) {
  if (const Config fr = cfg.child("fracture")) {
    scene.loading.removal = fr.choice("removal", {"all", "one"}, "all") == "all" ? RemovalStrategy::kAll : RemovalStrategy::kOne;
    scene.loading.maxRounds = static_cast<int>(fr.get("max_rounds", 1e6, Interval::closed(1, 1e9)));
    scene.coupledRemoval = fr.choice("coupled", {"settled", "iterate"}, "settled") == "settled" ? CoupledRemoval::kSettled
                                                                                             : CoupledRemoval::kIterate;
    scene.settleTolerance = fr.get("settle_tolerance", 1e-3, Interval::positive());
  }

  const Config so = cfg.child("solver");
  if (so) {
    scene.solver.type = so.choice("type", solverNames(), "cg");
    scene.solver.settings.tolerance = so.get("tolerance", 1e-6, Interval::open(0, 1));
    scene.solver.settings.maxIterations = static_cast<int>(so.get("max_iterations", 0.0, Interval::closed(0, 2e9)));
    // cg's products are fastest rod by rod (docs/performance.md); the averaging solver's node updates
    // read K a block row at a time, which the assembled blocks serve directly.
    const char* defaultOp = scene.solver.type == "averaging" ? "assembled" : "matrix_free";
    scene.op = so.choice("operator", {"assembled", "matrix_free"}, defaultOp) == "assembled" ? Operator::kAssembled
                                                                                          : Operator::kMatrixFree;
  }
  // Without `solver:`: cg on the matrix-free operator, in mixed precision.
  scene.solver.make = readSolverKeys(scene.solver.type, so, scene.op == Operator::kMatrixFree);
  if (const Config out = cfg.child("output")) {
    scene.snapshotEvery = static_cast<int>(out.get("snapshot_every", 0.0, Interval::closed(0, 1e9)));
    scene.checkpointEvery = static_cast<int>(out.get("checkpoint_every", 0.0, Interval::closed(0, 1e9)));
  }
}

// The specimen from its keys: nodes, rods, aggregates, the rods' phases and area.
void generateSpecimen(const SpecimenKeys& k, const AggregateKeys& a, const Config& ld, bool autoArea, Scene& scene) {
  Box box = k.box;
  std::optional<ClosedSurface> solid;
  if (k.geo) {
    VolumeGeometry geometry;
    try {
      // Surface mesh at half the rod length: the facets then cut off < 0.1 % of a curved specimen
      // (README "Specimen from a gmsh volume").
      geometry = readVolumeGeometry(k.geometryFile, k.volumeTag, 0.5 * k.rodLength, k.geometryScale);
      solid.emplace(geometry.closedSurface());
    } catch (const VolumeTagError& e) {
      k.geo.failAt("volume", fmt::format("{}.", e.what()));
    } catch (const std::invalid_argument& e) {
      k.geo.failAt("file", fmt::format("{}.", e.what()));
    }
    box = solid->bounds();
    if (k.rodLength >= box.size.minCoeff())
      k.sp.failAt("rod_length", fmt::format("is not below the smallest side {:.4g} m of the volume's bounding box (specimen.geometry): "
                                          "the specimen would have no inner node. Lower rod_length.",
                                          box.size.minCoeff()));
    k.refuseUnfitting(box);
    if (ld) scene.supports.loadedArea = loadedFaceArea(*solid, scene.supports.axis, ld);
    try {
      scene.specimen = randomSpecimen(geometry, k.rodLength, k.minDistance, k.nodeSeed);
    } catch (const std::invalid_argument& e) {
      k.sp.fail(fmt::format("{}.", e.what()));
    }
  } else if (k.kind == "random") {
    try {
      scene.specimen = randomSpecimen(box, k.rodLength, k.minDistance, k.nodeSeed);
    } catch (const std::invalid_argument& e) {
      k.sp.fail(fmt::format("{}.", e.what()));
    }
  } else {
    scene.specimen = cubicLattice(box, k.rodLength);
  }
  if (a.sieve) {
    try {
      scene.specimen.aggregates = placeAggregates(box, *a.sieve, a.settings, solid ? &*solid : nullptr);
    } catch (const PackingError& e) {
      a.ag.failAt("volume_fraction", fmt::format("cannot be packed: {}. Lower volume_fraction, widen the sieve curve towards "
                                               "smaller diameters, or lower the gap.",
                                               e.what()));
    }
    double volume = 0.0;
    for (const auto& a : scene.specimen.aggregates) volume += 4.0 / 3.0 * std::numbers::pi * std::pow(a.radius, 3);
    scene.aggregateFraction = volume / scene.specimen.volume();
    if (a.sieve->maxDiameter() < 2 * k.rodLength)
      common::logger("lattice")->warn("aggregates.sieve: the largest aggregate ({} m) is below two rod lengths ({} m): few "
                                      "rods will lie inside aggregates",
                                      a.sieve->maxDiameter(), 2 * k.rodLength);
  }
  classifyRods(scene.specimen);
  if (autoArea) {
    // Rods fill the volume: Σ A L = 3V. A simple cubic lattice then has E = k_l E₀ exactly (README).
    double sum = 0.0;
    for (const auto& [a, b] : scene.specimen.rods) sum += (scene.specimen.nodes[b] - scene.specimen.nodes[a]).norm();
    scene.section.area = 3.0 * scene.specimen.volume() / sum;
  }
}

}  // namespace

Scene loadScene(const Config& cfg) {
  Scene scene;
  const auto start = Clock::now();
  const SpecimenKeys specimen = readSpecimenKeys(cfg);
  const AggregateKeys aggregates = readAggregateKeys(cfg);
  const bool autoArea = readPhasesAndRod(cfg, scene);
  readInterface(cfg, specimen.geo.valid(), scene);
  const Config loading = readLoading(cfg, scene);
  readFractureSolverOutput(cfg, scene);
  // Every key is read and checked before generating: a typo should not wait for a large specimen.
  cfg.checkUnknownKeys();
  generateSpecimen(specimen, aggregates, loading, autoArea, scene);
  scene.generationSeconds = since(start);
  return scene;
}

Model buildModel(const Scene& scene, bool coupled) {
  Supports supports = scene.supports;
  if (!coupled) supports.coupled.clear();
  return Model(scene.specimen, makeRodLaw(scene.law), scene.phases, scene.section, supports, scene.op);
}

void logSpecimen(const Scene& scene) {
  const Specimen& sp = scene.specimen;
  std::array<std::int64_t, kPhaseCount> perPhase{};
  for (auto p : sp.phases) ++perPhase[static_cast<std::size_t>(p)];
  common::logger("lattice")->info("{} nodes, {} rods (matrix {}, aggregate {}, interface {}), mean rod length {:.4g} m, {} "
                                  "aggregates ({:.1f} % of the volume), generated in {:.2f} s",
                                  sp.nodes.size(), sp.rods.size(), perPhase[0], perPhase[1], perPhase[2], sp.meanRodLength(),
                                  sp.aggregates.size(), 100 * scene.aggregateFraction, scene.generationSeconds);
}

std::string faceName(const Face& f) { return fmt::format("{}_{}", static_cast<char>('x' + f.axis), f.side == 0 ? "min" : "max"); }

LatticeOutput::LatticeOutput(common::H5Writer& h5, const Specimen& sp) : specimen_(sp), h5_(h5) {
  nodes_.reserve(3 * sp.nodes.size());
  for (const auto& x : sp.nodes) nodes_.insert(nodes_.end(), {x.x(), x.y(), x.z()});
  std::vector<std::int64_t> cells;
  cells.reserve(2 * sp.rods.size());
  for (const auto& [a, b] : sp.rods) cells.insert(cells.end(), {a, b});
  h5_.addMesh("rods", nodes_, cells, common::CellType::kLine);
  phase_.resize(sp.rods.size());
  for (std::size_t r = 0; r < sp.rods.size(); ++r) phase_[r] = static_cast<double>(sp.phases[r]);
  if (!sp.aggregates.empty()) {
    std::vector<double> ag;
    for (const auto& a : sp.aggregates) ag.insert(ag.end(), {a.center.x(), a.center.y(), a.center.z(), a.radius});
    h5_.writeArray("/specimen/aggregates", ag, 4);
  }
}

void LatticeOutput::snapshot(const Model& model, std::span<const double> u, std::span<const int> removedAt, double time) {
  const std::size_t N = specimen_.nodes.size(), R = specimen_.rods.size();
  std::vector<double> disp(3 * N), rot(3 * N), strain(R), removed(R);
  for (std::size_t n = 0; n < N; ++n)
    for (std::size_t k = 0; k < 3; ++k) {
      disp[3 * n + k] = u[6 * n + k];
      rot[3 * n + k] = u[6 * n + 3 + k];
    }
  for (std::size_t r = 0; r < R; ++r) {
    strain[r] = model.rodStrain(r, u);
    removed[r] = removedAt[r];
  }
  h5_.writeMeshSnapshot("rods", time, {}, {{"displacement", 3, disp}, {"rotation", 3, rot}},
                         {{"strain", 1, strain}, {"removed_at", 1, removed}, {"phase", 1, phase_}});
}

void LatticeOutput::cracks(const std::vector<Crack>& removed, double time) {
  if (removed.empty()) return;
  std::vector<std::int64_t> cells;
  std::vector<double> inc, applied, rodStrain, phase;
  for (const auto& rec : removed) {
    cells.insert(cells.end(), {specimen_.rods[rec.rod][0], specimen_.rods[rec.rod][1]});
    inc.push_back(rec.increment);
    applied.push_back(rec.appliedStrain);
    rodStrain.push_back(rec.rodStrain);
    phase.push_back(phase_[rec.rod]);
  }
  h5_.addMesh("cracks", nodes_, cells, common::CellType::kLine);
  h5_.writeMeshSnapshot("cracks", time, {}, {},
                         {{"increment", 1, inc}, {"applied_strain", 1, applied}, {"rod_strain", 1, rodStrain}, {"phase", 1, phase}});
}

void reportSpecimen(const Scene& scene, const Model& model, std::span<const std::uint32_t> removed, int axis,
                    common::Summary& summary) {
  const Specimen& sp = scene.specimen;
  std::array<std::int64_t, kPhaseCount> perPhase{};
  for (auto p : sp.phases) ++perPhase[static_cast<std::size_t>(p)];
  summary.set("rods_removed", static_cast<std::int64_t>(removed.size()));
  summary.set("rods", static_cast<std::int64_t>(sp.rods.size()));
  summary.set("nodes", static_cast<std::int64_t>(sp.nodes.size()));
  summary.set("rods_matrix", perPhase[0]);
  summary.set("rods_aggregate", perPhase[1]);
  summary.set("rods_interface", perPhase[2]);
  summary.set("aggregates", static_cast<std::int64_t>(sp.aggregates.size()));
  summary.set("aggregate_fraction", scene.aggregateFraction);
  summary.set("mean_rod_length", sp.meanRodLength());
  summary.set("specimen_volume", sp.volume());
  summary.set("loaded_area", model.loadedArea());
  summary.set("rod_area", scene.section.area);
  summary.set("generation_time_s", scene.generationSeconds);
  summary.set("free_dofs", static_cast<std::int64_t>(model.freeDofs()));
  summary.set("held_nodes", static_cast<std::int64_t>(model.heldNodes()));
  const CrackBand band = crackBand(model, removed, axis, 2 * sp.meanRodLength());
  summary.set("crack_plane", band.plane);
  summary.set("crack_band_fraction", band.fraction);
}

CrackBand crackBand(const Model& model, std::span<const std::uint32_t> removed, int axis, double halfWidth) {
  CrackBand band;
  if (removed.empty()) return band;
  std::vector<double> pos;
  pos.reserve(removed.size());
  const auto& nodes = model.referenceNodes();
  for (auto r : removed) pos.push_back(0.5 * (nodes[model.rod(r)[0]][axis] + nodes[model.rod(r)[1]][axis]));
  std::sort(pos.begin(), pos.end());
  // Sliding window of width 2 halfWidth over the sorted midpoints: the densest one.
  std::size_t best = 0, lo = 0;
  for (std::size_t hi = 0; hi < pos.size(); ++hi) {
    while (pos[hi] - pos[lo] > 2 * halfWidth) ++lo;
    if (hi - lo + 1 > best) {
      best = hi - lo + 1;
      band.plane = 0.5 * (pos[lo] + pos[hi]);
    }
  }
  band.fraction = static_cast<double>(best) / static_cast<double>(pos.size());
  return band;
}

namespace {

const std::string kStandaloneKind = common::standaloneKind("lattice_solver");

/// A fracture test as common::runLoop drives it: the clock is the increment, each step one increment of
/// the applied strain with its removals; the series is the stress–strain curve, a row per increment.
class FractureRun final : public common::SteppedRun {
 public:
  FractureRun(const Scene& scene, Model& model, EquilibriumSolver& solver, common::H5Writer& h5, double assembleSeconds)
      : scene_(scene), model_(model), solver_(solver), test_(model, solver, scene.loading), out_(h5, scene.specimen),
        assembleSeconds_(assembleSeconds) {
    h5.addSeries("curve", {"strain", "stress", "removed", "removed_total", "rounds", "iterations"});
  }

  double clock() const override { return static_cast<double>(test_.curve().size()); }
  double clockStep() const override { return 1.0; }
  std::int64_t steps() const override { return static_cast<std::int64_t>(test_.curve().size()); }
  bool finished() const override { return test_.finished(); }

  void step() override {
    test_.step();
    const IncrementResult& row = test_.curve().back();
    if (row.removedNow > 0)
      common::logger("lattice")->debug(
          "increment {}: ε = {:.4g}, σ = {:.4g} Pa, {} rods removed in {} rounds ({} total), {} iterations, {:.2f} s",
          row.increment, row.strain, row.stress, row.removedNow, row.rounds - 1, row.removedTotal, row.iterations,
          row.seconds);
  }

  void writeSeries(common::SeriesRow) override {
    const IncrementResult& row = test_.curve().back();
    out_.h5().append("curve", row.increment,
                     std::vector<double>{row.strain, row.stress, static_cast<double>(row.removedNow),
                                         static_cast<double>(row.removedTotal), static_cast<double>(row.rounds),
                                         static_cast<double>(row.iterations)});
  }
  void writeSnapshot(bool) override {
    out_.snapshot(model_, test_.displacement(), test_.removedAt(), std::abs(test_.appliedStrain()));
  }

  void archive(common::StateArchive& a) override {
    a.shape(model_.shape());
    model_.archive(a);
    a.io("test", test_);
    if (a.reading()) solver_.update(model_);  // the solver's history is read into what update() rebuilt
    auto scope = a.scope("solver");
    solver_.archive(a);
  }

  std::string status() const override {
    const auto& curve = test_.curve();
    if (curve.empty()) return fmt::format("ε = 0 of {:.4g}", scene_.loading.direction * scene_.loading.maxStrain);
    const IncrementResult& row = curve.back();
    const double done = std::abs(row.strain) / scene_.loading.maxStrain, elapsed = since(start_);
    return fmt::format("ε = {:.4g} of {:.4g} ({:.0f} %), σ = {:.4g} MPa, {} rods removed, {} increments, {} solves, {} "
                       "iterations, {:.0f} s, ETA ≤ {:.0f} s",
                       row.strain, scene_.loading.direction * scene_.loading.maxStrain, 100 * done, row.stress / 1e6,
                       row.removedTotal, row.increment, test_.solves(), test_.totalIterations(), elapsed,
                       elapsed * (1 - done) / done);
  }

  void report(common::Summary& summary, double, bool failed) override {
    if (failed || test_.curve().empty()) return;
    std::vector<LatticeOutput::Crack> cracks;
    std::vector<std::uint32_t> removedRods;
    for (const auto& rec : test_.removals()) {
      cracks.push_back({rec.rod, rec.increment, rec.appliedStrain, rec.rodStrain});
      removedRods.push_back(rec.rod);
    }
    out_.cracks(cracks, std::abs(test_.appliedStrain()));
    out_.h5().flush();
    reportCurve(summary, removedRods);
  }

 private:
  void reportCurve(common::Summary& summary, const std::vector<std::uint32_t>& removedRods) const {
    const auto& curve = test_.curve();
    const IncrementResult& peak = curve[static_cast<std::size_t>(test_.peakIndex())];
    const double dir = scene_.loading.direction;
    summary.set("peak_stress", dir * peak.stress);
    summary.set("strain_at_peak", dir * peak.strain);
    summary.set("youngs_modulus", test_.youngsModulus());
    reportSpecimen(scene_, model_, removedRods, scene_.supports.axis, summary);
    summary.set("first_critical_strain", dir * test_.firstCriticalStrain());
    summary.set("final_strain", dir * test_.appliedStrain());
    summary.set("final_stress", dir * curve.back().stress);
    summary.set("increments", static_cast<std::int64_t>(curve.size()));
    summary.set("solves", static_cast<std::int64_t>(test_.solves()));
    summary.set("solver_iterations", static_cast<std::int64_t>(test_.totalIterations()));
    summary.set("solve_time_s", test_.solveSeconds());
    summary.set("removal_time_s", test_.removalSeconds());
    summary.set("preconditioner_time_s", test_.updateSeconds());
    summary.set("check_time_s", test_.checkSeconds());
    summary.set("assembly_time_s", assembleSeconds_);
    summary.setCost("time_per_increment_s", test_.solveSeconds() / static_cast<double>(curve.size()));
    summary.setCost("phase_seconds", std::vector<double>{assembleSeconds_, test_.solveSeconds(), test_.removalSeconds(),
                                                         test_.updateSeconds(), test_.checkSeconds()});
    summary.setCost("phase_names", std::string("assembly, solve, removal, preconditioner, check"));
    common::logger("lattice")->info(
        "peak stress {:.4g} MPa at strain {:.4g}; E = {:.4g} GPa; {} of {} rods removed; {} increments, {} solves, {} "
        "iterations, solver {:.2f} s",
        dir * peak.stress / 1e6, dir * peak.strain, test_.youngsModulus() / 1e9, test_.removals().size(),
        scene_.specimen.rods.size(), curve.size(), test_.solves(), test_.totalIterations(), test_.solveSeconds());
  }

  const Scene& scene_;
  Model& model_;
  EquilibriumSolver& solver_;
  FractureTest test_;
  LatticeOutput out_;
  double assembleSeconds_;
  Clock::time_point start_ = Clock::now();
};

}  // namespace

void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart) {
  if (!scene.hasLoading)
    throw common::ConfigError("a standalone lattice_solver run needs a `loading` section (this scene has only `interface`, "
                              "which is for coupled runs started by cosim).");
  logSpecimen(scene);
  auto t0 = Clock::now();
  Model model = buildModel(scene, false);
  const double assembleSeconds = since(t0);
  common::logger("lattice")->info("{} free dofs, {} operator ({} non-zeros), rod area {:.4g} m², set up in {:.2f} s",
                                  model.freeDofs(), scene.op == Operator::kAssembled ? "assembled" : "matrix-free",
                                  model.nonZeros(), scene.section.area, assembleSeconds);
  auto solver = scene.solver.build();
  common::RunLoopSettings s;
  s.label = "lattice";
  s.kind = kStandaloneKind;
  s.end = std::ceil(scene.loading.maxStrain / scene.loading.strainIncrement);
  s.stepName = "increment";
  s.series = common::Cadence::after(1.0);
  s.snapshots = common::Cadence::after(scene.snapshotEvery);
  s.checkpoints = common::Cadence::after(scene.checkpointEvery);
  s.snapshotAtEnd = true;
  s.checkpointFile = outDir / "checkpoint" / "lattice.h5";
  s.progress = progress;
  common::ResultsFile results = common::openResults(outDir / "lattice.h5", restart, kStandaloneKind, model.shape(), s.checkpointFile);
  FractureRun run(scene, model, *solver, *results.h5, assembleSeconds);
  common::runLoop(run, std::move(s), results.h5.get(), results.restart, restart, summary);
}

}  // namespace lattice
