#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <optional>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/results_file.hpp"
#include "common/run_loop.hpp"
#include "common/log.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "dem/contact_queries.hpp"
#include "dem/ranked_run.hpp"
#include "dem/scene.hpp"
#include "dem/stability_monitor.hpp"
#include "dem/time_steps.hpp"
#include "stepped_dem.hpp"

namespace dem {

namespace {

/// Head-on impact measurement: contact start and end (interpolated where the signed overlap crosses
/// zero), largest overlap, normal velocity before and after.
class ImpactProbe {
 public:
  explicit ImpactProbe(std::uint32_t body) : body_(body) {}

  void update(const Simulation& sim) {
    const BodyContacts c = sim.bodyContacts(body_);
    const double tGeom = sim.time() - sim.settings().dt;  // contacts are evaluated at the step's start
    if (state_ == State::kBefore) {
      if (c.maxOverlap > 0.0) {
        state_ = State::kIn;
        start_ = interpolate(tGeom, c.maxOverlap, sim.settings().dt);
        law_ = c.law;
        effRadius_ = c.effRadius;
        effMass_ = c.effMass;
      } else {
        velocityBefore_ = sim.bodies().velocity[body_];
      }
    }
    // The step that found the contact counts too: a contact too short for the step lasts only that one.
    if (state_ == State::kIn) {
      if (c.count > 0) {
        maxOverlap_ = std::max(maxOverlap_, c.maxOverlap);
        if (c.force.norm() > maxForce_) {
          maxForce_ = c.force.norm();
          normal_ = c.force.normalized();
        }
      } else {
        state_ = State::kAfter;
        end_ = interpolate(tGeom, c.maxOverlap, sim.settings().dt);
      }
    } else if (state_ == State::kAfter && !afterTaken_) {
      velocityAfter_ = sim.bodies().velocity[body_];
      afterTaken_ = true;
    }
    lastOverlap_ = c.maxOverlap;
  }

  void report(common::Summary& summary) const {
    if (state_ != State::kBefore) {  // peaks so far, whether or not the contact ended
      summary.set("max_overlap", maxOverlap_);
      summary.set("peak_contact_force", maxForce_);
    }
    if (state_ != State::kAfter || !afterTaken_ || !law_) {
      summary.set("impact", std::string(state_ == State::kBefore ? "no contact" : "contact did not end"));
      return;
    }
    const double vin = -velocityBefore_.dot(normal_);
    const double vout = velocityAfter_.dot(normal_);
    const ImpactPrediction theory = law_->elasticImpact(effRadius_, effMass_, vin);
    summary.set("contact_duration", end_ - start_);
    summary.set("contact_duration_analytic", theory.contactDuration);
    summary.set("max_overlap_analytic", theory.maxOverlap);
    summary.set("restitution", vout / vin);
    summary.set("restitution_requested", law_->restitution());
    // The validation's own error, so a study needs no formula: against theory where theory holds (the
    // analytic duration and overlap are those of the elastic, undamped impact).
    summary.set("restitution_error", std::abs(vout / vin - law_->restitution()) / law_->restitution());
    if (law_->restitution() == 1.0) {
      summary.set("contact_duration_error", std::abs(end_ - start_ - theory.contactDuration) / theory.contactDuration);
      summary.set("max_overlap_error", std::abs(maxOverlap_ - theory.maxOverlap) / theory.maxOverlap);
    }
    summary.set("impact_velocity", vin);
  }

  void archive(common::StateArchive& a, const Simulation& sim) {
    int law = sim.interactions().indexOf(law_);
    a.io("state", state_), a.io("start", start_), a.io("end", end_), a.io("max_overlap", maxOverlap_);
    a.io("max_force", maxForce_), a.io("last_overlap", lastOverlap_), a.io("velocity_before", velocityBefore_);
    a.io("velocity_after", velocityAfter_), a.io("normal", normal_), a.io("after_taken", afterTaken_), a.io("law", law);
    a.io("eff_radius", effRadius_), a.io("eff_mass", effMass_);
    law_ = sim.interactions().at(law);
  }

 private:
  enum class State { kBefore, kIn, kAfter };
  // Time at which the signed overlap crossed zero between the previous geometry and this one.
  double interpolate(double t, double overlap, double dt) const {
    if (!std::isfinite(lastOverlap_) || !std::isfinite(overlap) || overlap == lastOverlap_) return t;
    return t - dt + dt * (0.0 - lastOverlap_) / (overlap - lastOverlap_);
  }

  std::uint32_t body_;
  State state_ = State::kBefore;
  double start_ = 0, end_ = 0, maxOverlap_ = 0, maxForce_ = 0;
  double lastOverlap_ = -std::numeric_limits<double>::infinity();
  Vec3 velocityBefore_ = Vec3::Zero(), velocityAfter_ = Vec3::Zero(), normal_ = Vec3::UnitZ();
  bool afterTaken_ = false;
  const ContactLaw* law_ = nullptr;
  double effRadius_ = 0, effMass_ = 0;
};

/// Least-squares slope of the body's velocity along an axis over t ≥ from.
class AccelerationProbe {
 public:
  explicit AccelerationProbe(const ProbeSettings& s) : s_(s) {}
  void update(const Simulation& sim) {
    if (sim.time() < s_.from) return;
    const double t = sim.time(), v = bodyVelocity(sim, s_.body).dot(s_.direction);
    n_ += 1;
    st_ += t;
    sv_ += v;
    stt_ += t * t;
    stv_ += t * v;
  }
  void report(const Simulation& sim, common::Summary& summary) const {
    if (n_ < 2) return;
    summary.set("acceleration", (n_ * stv_ - st_ * sv_) / (n_ * stt_ - st_ * st_));
    const auto b = s_.body;
    const Vec3 v = bodyVelocity(sim, b);
    const double r = sim.spheres().radius[sim.bodies().firstSphere[b]];
    if (v.norm() > 0) summary.set("rolling_ratio", sim.bodies().angularVelocity[b].norm() * r / v.norm());
  }

  void archive(common::StateArchive& a) {
    a.io("n", n_), a.io("st", st_), a.io("sv", sv_), a.io("stt", stt_), a.io("stv", stv_);
  }

 private:
  ProbeSettings s_;
  double n_ = 0, st_ = 0, sv_ = 0, stt_ = 0, stv_ = 0;
};

/// A DEM scene run on its own, as common::runLoop drives it: the clock is the time, a step Simulation::step
/// with the energy and stability checks and the probes.
class StandaloneDem final : public SteppedDem {
 public:
  StandaloneDem(Scene& scene, common::H5Writer& h5)
      : SteppedDem(*scene.sim, scene.endTime),
        scene_(scene),
        sim_(*scene.sim),
        h5_(h5),
        series_(h5, sim_, scene.output.track),
        impact_(scene.probe.body),
        accel_(scene.probe),
        monitor_(sim_, scene.energyTolerance),
        observe_(common::Cadence::after(
            std::max(scene.endTime / 200, std::min(kStepsPerObserve * scene.sim->settings().dt, scene.endTime / 20)))),
        momentum0_(totalAngularMomentum(sim_.bodies())) {}

  /// Before the first step of a fresh run (a restart reads it from its checkpoint instead).
  void start() { monitor_.observe(sim_); }

  void step() override {
    sim_.step();
    if (scene_.probe.kind == ProbeSettings::Kind::kImpact) impact_.update(sim_);
    if (scene_.probe.kind == ProbeSettings::Kind::kAcceleration) accel_.update(sim_);
    monitor_.check(sim_);
    if (momentum0_.norm() > 0)
      maxMomentumDrift_ = std::max(maxMomentumDrift_, (totalAngularMomentum(sim_.bodies()) - momentum0_).norm() / momentum0_.norm());
    // 200 samples a run, at most one every kStepsPerObserve steps but at least 20: each is a pass over the
    // bodies and the contacts (a 50,000-sphere pour has 175,000 candidates), too much for every series row.
    if (observe_.due(clock(), 0.5 * clockStep())) {
      monitor_.observe(sim_);
      observe_.advance();
    }
  }

  void writeSeries(common::SeriesRow) override { series_.write(series_.sample()); }
  void writeSnapshot(bool) override { writeParticleSnapshot(h5_, sim_, sim_.time()); }

  void archive(common::StateArchive& a) override {
    sim_.archive(a);
    a.io("monitor", monitor_), a.io("observe", observe_);
    { auto s = a.scope("impact"); impact_.archive(a, sim_); }
    a.io("acceleration", accel_);
    a.io("momentum0", momentum0_), a.io("max_momentum_drift", maxMomentumDrift_);
  }

  void report(common::Summary& summary, double loopSeconds, bool failed) override {
    summary.set("end_time", sim_.time());
    summary.set("energy_balance_error", monitor_.energyError());
    reportTimeSteps(summary);
    reportSheets(sim_, summary);
    if (scene_.probe.kind == ProbeSettings::Kind::kImpact) impact_.report(summary);
    if (failed) return;
    reportRun(summary, loopSeconds);
    if (scene_.probe.kind == ProbeSettings::Kind::kAcceleration) accel_.report(sim_, summary);
    if (scene_.probe.kind == ProbeSettings::Kind::kPacking) reportPacking(summary);
  }

 private:
  void reportTimeSteps(common::Summary& out) const {
    out.set("dt", sim_.settings().dt);
    out.set("critical_dt", criticalTimeStep(sim_));
    // The step that resolves the fastest approach (estimated before the run, or seen in it if faster).
    const double contact = contactDuration(sim_, monitor_.approachSpeed());
    out.set("approach_speed_max", monitor_.approachSpeed());
    out.set("contact_duration_min", contact);
    out.set("impact_dt", contact / sim_.settings().stepsPerContact);
    out.set("safe_dt", safeTimeStep(sim_, monitor_.approachSpeed()));
    // The contact network's stable step at the sampled steps (compressed contacts stiffen), and the step
    // a rerun should take.
    if (std::isfinite(monitor_.contactStableStep())) out.set("contact_stable_dt_min", monitor_.contactStableStep());
    out.set("recommended_dt", monitor_.recommendedTimeStep(sim_));
  }

  void reportRun(common::Summary& summary, double loopSeconds) const {
    const Simulation& sim = sim_;
    summary.set("skin", sim.settings().skin);
    if (!sim.meshWalls().walls().empty()) summary.set("mesh_skin", sim.settings().meshSkin);
    summary.set("bodies", static_cast<std::int64_t>(sim.bodies().size()));
    summary.set("spheres", static_cast<std::int64_t>(sim.spheres().size()));
    summary.set("neighbor_rebuilds", sim.profile().neighbourRebuilds);
    const auto contacts = contactCounts(sim);
    summary.set("sphere_pair_candidates_final", contacts.pairCandidates);
    summary.set("sphere_contacts_final", contacts.pairs);
    summary.set("wall_contacts_final", contacts.walls);
    // Mean contacts per sphere, walls included (each sphere pair counts for both spheres).
    if (sim.spheres().size() > 0)
      summary.set("coordination_number_final",
                  static_cast<double>(2 * contacts.pairs + contacts.walls) / static_cast<double>(sim.spheres().size()));
    summary.set("loop_wall_time_s", loopSeconds);
    reportCost(sim, summary, loopSeconds);
    summary.set("particle_steps_per_s",
                loopSeconds > 0 ? static_cast<double>(sim.spheres().size() * sim.steps()) / loopSeconds : 0.0);
    const Simulation::Profile phase = sim.profile();
    summary.set("time_neighbour_s", phase.neighbour);
    summary.set("time_sphere_contacts_s", phase.sphereContacts);
    summary.set("time_wall_contacts_s", phase.wallContacts);
    summary.set("time_integrate_s", phase.integrate);
    summary.set("time_other_s", phase.other);
    summary.set("sphere_contacts_thread_wait",
                phase.sphereContacts > 0 ? phase.sphereContactsWait / phase.sphereContacts : 0.0);
    summary.set("kinetic_energy_final", sim.energy().kinetic);
    reportBonds(sim, summary);
    // Meaningful when nothing exerts an external torque (free flight): conserved to round-off.
    summary.set("angular_momentum_drift", maxMomentumDrift_);
    const std::uint32_t b = scene_.probe.body;
    summary.set("spin_final", sim.bodies().angularVelocity[b].norm());
    const Vec3 v = bodyVelocity(sim, b);
    summary.set("velocity_final", std::vector<double>{v.x(), v.y(), v.z()});
  }

  // Solid fraction: volume of the spheres whose centres lie in the region, over the region's volume.
  void reportPacking(common::Summary& summary) const {
    const auto& S = sim_.spheres();
    const ProbeSettings& p = scene_.probe;
    double solid = 0.0, top = -1e300;
    for (std::size_t s = 0; s < S.size(); ++s) {
      top = std::max(top, S.position[s].z() + S.radius[s]);
      if ((S.position[s].array() >= p.regionMin.array()).all() && (S.position[s].array() <= p.regionMax.array()).all())
        solid += 4.0 / 3.0 * 3.14159265358979323846 * std::pow(S.radius[s], 3);
    }
    summary.set("packing_fraction", solid / (p.regionMax - p.regionMin).prod());
    summary.set("bed_height", top);
  }

  Scene& scene_;
  Simulation& sim_;
  common::H5Writer& h5_;
  SeriesRecorder series_;
  ImpactProbe impact_;
  AccelerationProbe accel_;
  StabilityMonitor monitor_;
  // A sample of the monitor costs about half a step (docs/performance.md, "The stability checks' cost"):
  // one every 50 steps at most keeps it near 1 % of a run. A run of fewer than 1,000 steps still takes 20.
  static constexpr double kStepsPerObserve = 50;
  common::Cadence observe_;
  Vec3 momentum0_;
  double maxMomentumDrift_ = 0.0;
};

}  // namespace

void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart) {
  Simulation& sim = *scene.sim;
  const double dt = sim.settings().dt;
  common::logger("dem")->info("{} bodies, {} spheres, {} walls; dt = {:.4g} s, end {:.4g} s ({} steps)",
                              sim.bodies().size(), sim.spheres().size(), sim.planeWalls().walls().size(), dt, scene.endTime,
                              std::llround(scene.endTime / dt));
  // A restart reopens the results where the checkpoint left them; the state is read by the loop, once
  // every part that holds some exists.
  common::ResultsFile results =
      common::openResults(outDir / "dem.h5", restart, kStandaloneKind, sim.shape(), outDir / "checkpoint" / "dem.h5");
  if (results.restart && results.restart->has(std::string(kRanksCheckpointScope) + "/ranks")) {
    std::int64_t ranks = 0;
    auto scope = results.restart->scope(kRanksCheckpointScope);
    results.restart->io("ranks", ranks);
    throw common::ConfigError(fmt::format("{}: a checkpoint of a run on {} ranks; restart it on 2 ranks or more "
                                          "(mpirun -np {} takes up the same shares)",
                                          restart.string(), ranks, ranks));
  }
  addMeshWalls(*results.h5, sim);
  StandaloneDem run(scene, *results.h5);
  if (!results.restart) run.start();
  common::runLoop(run, loopSettings(scene, outDir, kStandaloneKind, progress), results.h5.get(), results.restart, restart, summary);
}

SeriesRecorder::SeriesRecorder(common::H5Writer& h5, const Simulation& sim, std::vector<std::uint32_t> bodies)
    : h5_(h5), sim_(sim), bodies_(std::move(bodies)) {
  // Scenes with bonds also book what the broken ones released (a column only they need).
  bonds_ = sim.interactions().anyBonding();
  std::vector<std::string> energyColumns = {"kinetic", "potential", "elastic",       "damping", "friction",
                                            "cundall", "wall_work", "external_work", "residual"};
  if (bonds_) energyColumns.insert(energyColumns.begin() + 6, "bond_fracture");
  h5.addSeries("energy", energyColumns);
  for (auto b : bodies_)
    h5.addSeries(fmt::format("body_{}", b),
                 {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz", "contacts"});
  std::vector<std::string> wallColumns;
  for (const auto& p : sim.planeWalls().walls())
    for (const char* c : {"_fx", "_fy", "_fz"}) wallColumns.push_back(p.name + c);
  for (const auto& m : sim.meshWalls().walls())
    for (const char* c : {"_fx", "_fy", "_fz", "_mx", "_my", "_mz"}) wallColumns.push_back(m.name + c);
  walls_ = !wallColumns.empty();
  if (walls_) h5.addSeries("walls", wallColumns);
}

SeriesRecorder::Row SeriesRecorder::sample() const {
  Row row;
  row.time = sim_.time();
  row.energy = energyRow(sim_.energy(), sim_.initialEnergy());
  for (auto b : bodies_) row.bodies.push_back(bodyRow(sim_, b, sim_.bodyContacts(b).count));
  if (walls_) row.walls = wallRow(sim_);
  return row;
}

std::vector<double> SeriesRecorder::energyRow(const EnergyLedger& e, double initialEnergy) const {
  std::vector<double> row = {e.kinetic,  e.potential, e.elastic,  e.damping,
                             e.friction, e.cundall,   e.wallWork, e.externalWork,
                             e.residual(initialEnergy)};
  if (bonds_) row.insert(row.begin() + 6, e.bondFracture);
  return row;
}

std::vector<double> SeriesRecorder::bodyRow(const Simulation& sim, std::uint32_t b, double contacts) {
  const Vec3 v = bodyVelocity(sim, b);
  const Vec3 &x = sim.bodies().position[b], &w = sim.bodies().angularVelocity[b], &f = sim.bodies().force[b];
  return {x.x(), x.y(), x.z(), v.x(), v.y(), v.z(), w.x(), w.y(), w.z(), f.x(), f.y(), f.z(), contacts};
}

std::vector<double> SeriesRecorder::wallRow(const Simulation& sim) {
  std::vector<double> row;
  for (const auto& f : sim.planeWalls().forces()) row.insert(row.end(), {f.x(), f.y(), f.z()});
  for (const auto& m : sim.meshWalls().walls())
    row.insert(row.end(), {m.force.x(), m.force.y(), m.force.z(), m.moment.x(), m.moment.y(), m.moment.z()});
  return row;
}

void SeriesRecorder::write(const Row& row) {
  if (row.time < 0) return;
  h5_.append("energy", row.time, row.energy);
  for (std::size_t i = 0; i < bodies_.size(); ++i) h5_.append(fmt::format("body_{}", bodies_[i]), row.time, row.bodies[i]);
  if (walls_) h5_.append("walls", row.time, row.walls);
}

void addMeshWalls(common::H5Writer& h5, const Simulation& sim) {
  for (const auto& m : sim.meshWalls().walls()) {
    std::vector<double> nodes;
    std::vector<std::int64_t> cells;
    for (const auto& x : m.nodes) nodes.insert(nodes.end(), {x.x(), x.y(), x.z()});
    for (const auto& t : m.triangles) cells.insert(cells.end(), {t[0], t[1], t[2]});
    h5.addMesh(m.name, nodes, cells, common::CellType::kTriangle);
  }
}

ParticleSnapshot particleSnapshot(const Simulation& sim) {
  const auto& S = sim.spheres();
  const auto n = S.size();
  ParticleSnapshot out;
  out.position.resize(3 * n), out.velocity.resize(3 * n), out.bodyForce.resize(3 * n), out.body.resize(n);
  out.radius = S.radius;
  for (std::size_t s = 0; s < n; ++s) {
    const auto b = S.body[s];
    const Vec3 v = sim.bodies().velocity[b], f = sim.bodies().force[b];
    for (int k = 0; k < 3; ++k) {
      const auto i = 3 * s + static_cast<std::size_t>(k);
      out.position[i] = S.position[s][k];
      out.velocity[i] = v[k];
      out.bodyForce[i] = f[k];  // the contact force on the sphere's body (a cluster's members share it)
    }
    out.body[s] = b;
  }
  for (const auto& l : contactNetwork(sim)) {
    out.lineEnds.insert(out.lineEnds.end(), {l.a.x(), l.a.y(), l.a.z(), l.b.x(), l.b.y(), l.b.z()});
    out.normalForce.push_back(l.normalForce);
  }
  return out;
}

void writeParticleSnapshot(common::H5Writer& h5, double time, const ParticleSnapshot& p) {
  // Points with a `radius` array: ParaView's Point Gaussian and Glyph filters scale by it directly.
  h5.writeParticles("spheres", time, p.position,
                    {{"radius", 1, p.radius}, {"velocity", 3, p.velocity}, {"body_force", 3, p.bodyForce},
                     {"body", 1, p.body}});
  // The normal force network (a line per touching pair, ParaView: Tube by normal_force), when there is one.
  if (p.normalForce.empty()) return;
  std::vector<std::int64_t> lines(2 * p.normalForce.size());
  std::iota(lines.begin(), lines.end(), std::int64_t{0});
  h5.writeLines("contacts", time, p.lineEnds, lines, {{"normal_force", 1, p.normalForce}});
}

void writeParticleSnapshot(common::H5Writer& h5, const Simulation& sim, double time) {
  writeParticleSnapshot(h5, time, particleSnapshot(sim));
  writeMeshSnapshots(h5, sim.meshWalls().walls(), time);
}

void writeMeshSnapshots(common::H5Writer& h5, const std::vector<MeshWall>& meshes, double time) {
  for (const auto& m : meshes) {
    std::vector<double> nodes, f;
    for (const auto& x : m.nodes) nodes.insert(nodes.end(), {x.x(), x.y(), x.z()});
    for (const auto& v : m.nodeForce) f.insert(f.end(), {v.x(), v.y(), v.z()});
    h5.writeMeshSnapshot(m.name, time, nodes, {{"force", 3, f}});
  }
}

void reportBonds(const Simulation& sim, common::Summary& summary) {
  if (sim.bonds().created() == 0) return;
  summary.set("bonds_created", sim.bonds().created());
  summary.set("broken_bonds", sim.bonds().broken());
  summary.set("bond_fracture_energy", sim.energy().bondFracture);
  // The pieces of what was bonded (bodies joined by an unbroken bond, directly or through others).
  const Spheres& S = sim.spheres();
  std::vector<std::pair<std::uint64_t, std::uint64_t>> links;
  for (const Bond& b : sim.bonds().bonds()) links.emplace_back(S.body[b.a], S.body[b.b]);
  std::vector<std::pair<std::uint64_t, double>> masses;
  std::vector<std::uint8_t> counted(sim.bodies().size(), 0);
  const auto& ever = sim.bonds().everBonded();
  for (std::size_t s = 0; s < ever.size(); ++s)
    if (const auto b = S.body[s]; ever[s] && !counted[b]) counted[b] = 1, masses.emplace_back(b, sim.bodies().mass[b]);
  reportPieces(pieceMasses(sim.bodies().size(), links, masses), summary);
}

void reportPieces(const std::vector<double>& pieces, common::Summary& summary) {
  if (pieces.empty()) return;
  summary.set("fragments", static_cast<std::int64_t>(pieces.size()));
  summary.set("largest_fragment_mass_fraction", pieces.front() / std::accumulate(pieces.begin(), pieces.end(), 0.0));
}

void reportCost(const Simulation& sim, common::Summary& summary, double loopSeconds) {
  std::string on, off;
  for (const auto& [name, enabled] : sim.physics()) (enabled ? on : off) += (enabled ? on : off).empty() ? name : ", " + name;
  summary.setCost("physics", on);
  summary.setCost("physics_left_out", off);
  const Simulation::Profile p = sim.profile();
  summary.setCost("time_per_step_s", sim.steps() > 0 ? loopSeconds / static_cast<double>(sim.steps()) : 0.0);
  // The phases sum to the loop: what the step's timers do not cover (the stability monitor's samples,
  // probes, output, and on several ranks the exchanges) is the last. A serial fraction from the phases
  // then counts all of a step's time.
  const double stepped = p.neighbour + p.sphereContacts + p.wallContacts + p.integrate + p.other;
  summary.setCost("phase_seconds", std::vector<double>{p.neighbour, p.sphereContacts, p.wallContacts, p.integrate, p.other,
                                                       std::max(loopSeconds - stepped, 0.0)});
  summary.setCost("phase_names", std::string("neighbour, sphere_contacts, wall_contacts, integrate, other, rest_of_loop"));
  // Where the memory is (Simulation::memoryUse), at the end of the run, and per sphere.
  std::string names;
  std::vector<double> megabytes;
  double total = 0.0;
  for (const auto& [name, bytes] : sim.memoryUse()) {
    names += (names.empty() ? "" : ", ") + name;
    megabytes.push_back(static_cast<double>(bytes) / (1 << 20));
    total += static_cast<double>(bytes);
  }
  summary.setCost("memory_names", names);
  summary.setCost("memory_mb", megabytes);
  if (!sim.spheres().radius.empty())
    summary.setCost("memory_bytes_per_sphere", total / static_cast<double>(sim.spheres().size()));
}

void reportSheets(const Simulation& sim, common::Summary& summary) {
  for (const auto& w : sim.meshWalls().walls()) {
    if (!w.oneSided) continue;
    summary.set(w.name + "_max_depth_radii", w.maxDepthRadii);
    summary.set(w.name + "_lost_contact_steps", w.lostThroughSheet);
    if (w.lostThroughSheet > 0 || w.maxDepthRadii > 0.98 * w.depthRadii)
      common::logger("dem")->warn("wall {}: sphere centres reached {:.2f} radii behind the one-sided sheet (limit `depth` "
                                  "{}; {} sphere-steps counted beyond it): contacts were lost there, with their "
                                  "elastic energy. The contact is too soft for these spheres.",
                                  w.name, w.maxDepthRadii, w.depthRadii, w.lostThroughSheet);
  }
}

}  // namespace dem
