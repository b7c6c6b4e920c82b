// A FEM scene run on its own: a static solve, or explicit dynamics through common::runLoop (optionally
// from a static start).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/run_loop.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "fem/scene.hpp"
#include "fem/static_cache.hpp"
#include "element_registry.hpp"

namespace fem {

namespace {

const std::string kStandaloneKind = common::standaloneKind("fem_solver");

std::string physicsOf(const Scene& scene, bool enabled) {
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

void reportPhysics(const Scene& scene, common::Summary& summary) {
  summary.setCost("physics", physicsOf(scene, true));
  summary.setCost("physics_left_out", physicsOf(scene, false));
}

/// The static solve (analysis: static), or an explicit run's static start (explicit.initial_state: static).
void solveStatic(Scene& scene, common::H5Writer& h5, common::Summary& summary) {
  Model& model = scene.model;
  const auto start = std::chrono::steady_clock::now();
  // An explicit run's initial static state is the same for every run of this structure and load:
  // solved once, then reused (fem/static_cache.hpp).
  StaticReport rep;
  if (scene.analysis == "static") {
    rep = model.solveStatic(scene.staticSettings);
  } else {
    const CachedStatic cached = solveStaticCached(model, scene.staticSettings);
    rep = cached.report;
    summary.set("static_reused", static_cast<std::int64_t>(cached.reused));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  common::logger("fem")->info("static: {} stages, {} load steps, {} Newton iterations, residual {:.3g}, {:.3f} s",
                              rep.stages, rep.loadSteps, rep.iterations, rep.residual, seconds);
  summary.set("static_iterations", static_cast<std::int64_t>(rep.iterations));
  summary.set("relaxation_iterations", static_cast<std::int64_t>(rep.relaxationIterations));
  // The static state, for explicit runs that start from it (explicit.initial_state: file).
  h5.writeArray("/state/displacement", model.displacement(), 3);
  summary.set("static_residual", rep.residual);
  summary.set("static_time_s", seconds);
  summary.set("strain_energy_static", model.strainEnergy());
  reportProbesAndReactions(scene, summary, scene.analysis == "static" ? "" : "_static");
}

/// Explicit dynamics as common::runLoop drives it: the clock is the time; each step checks the energy
/// balance, and the deformed state (stable step, most compressed element) is checked at every series row
/// and at least every kCheckEvery steps, where a followed step (explicit.dt_fraction) changes.
class ExplicitRun final : public common::SteppedRun {
 public:
  ExplicitRun(Scene& scene, common::H5Writer& h5, common::Summary& summary)
      : scene_(scene),
        model_(scene.model),
        h5_(h5),
        summary_(summary),
        series_(h5, scene),
        referenceCritical_(model_.criticalTimeStep()),
        criticalMin_(referenceCritical_),
        dtMin_(scene.dt),
        dtMax_(scene.dt),
        maxReaction_(scene.reactionGroups.size(), 0.0) {
    initial_ = model_.energy().kinetic + model_.energy().strain;
  }

  double clock() const override { return model_.time(); }
  double clockStep() const override { return model_.dt(); }
  std::int64_t steps() const override { return model_.steps(); }
  // The same tolerance as requireWholeSteps: an end_time within 1e-6 steps of a whole number is reached
  // after exactly that number of steps.
  bool finished() const override { return model_.time() >= scene_.endTime - 1e-6 * scene_.dt; }

  void step() override {
    if (model_.steps() - lastCheck_ >= kCheckEvery) checkCurrent(true);
    model_.stepExplicit();
    checkEnergy();
    for (const auto& p : scene_.probes) {
      const auto& u = model_.displacement();
      maxSag_[p.name] = std::max(maxSag_[p.name], -u[3 * p.node + 2]);
    }
    const auto r = groupReactions(scene_);
    for (std::size_t i = 0; i < r.size(); ++i) maxReaction_[i] = std::max(maxReaction_[i], r[i].norm());
  }

  // The deformed state is checked with each row, but not the one that failed a check: a blown-up
  // state's stable step says nothing of the step to take.
  void writeSeries(common::SeriesRow row) override {
    series_.write(series_.sample(model_.time(), initial_));
    if (row != common::SeriesRow::kFailed) checkCurrent(row == common::SeriesRow::kScheduled);
  }
  void writeSnapshot(bool) override { fem::writeSnapshot(h5_, scene_, model_.time(), false); }

  void archive(common::StateArchive& a) override {
    a.shape(model_.shape());
    Model::State state = model_.saveState();
    a.io("model", state);
    if (a.reading()) model_.restoreState(state);
    std::vector<std::string> sagNames;
    std::vector<double> sagValues;
    for (const auto& [name, s] : maxSag_) sagNames.push_back(name), sagValues.push_back(s);
    a.io("max_sag_names", sagNames), a.io("max_sag", sagValues);
    for (std::size_t i = 0; i < sagNames.size() && i < sagValues.size(); ++i) maxSag_[sagNames[i]] = sagValues[i];
    a.io("max_reaction", maxReaction_), a.io("initial", initial_), a.io("max_residual", maxResidual_);
    a.io("scale", scale_), a.io("critical_min", criticalMin_), a.io("jacobian_min", jacobianMin_);
    a.io("dt_min", dtMin_), a.io("dt_max", dtMax_), a.io("last_check", lastCheck_), a.io("warned_dt", warnedDt_);
    a.io("summary", summary_);  // what the static start reported
  }

  void report(common::Summary& summary, double loopSeconds, bool failed) override {
    summary.set("end_time", model_.time());
    summary.set("energy_balance_error", scale_ > 0 ? maxResidual_ / scale_ : 0.0);
    summary.set("critical_dt", referenceCritical_);
    // The stable step of the deformed states checked (a stretched net's is shorter) and the most
    // compressed element's Jacobian.
    summary.set("critical_dt_min", criticalMin_);
    if (failed) return;
    summary.set("loop_wall_time_s", loopSeconds);
    summary.set("steps_per_s", loopSeconds > 0 ? static_cast<double>(model_.steps()) / loopSeconds : 0.0);
    summary.setCost("time_per_step_s", model_.steps() > 0 ? loopSeconds / static_cast<double>(model_.steps()) : 0.0);
    reportPhysics(scene_, summary);
    summary.set("dt", scene_.dt);
    if (scene_.dtFraction > 0.0) summary.set("dt_min", dtMin_), summary.set("dt_max", dtMax_);
    summary.set("jacobian_min", jacobianMin_);
    for (const auto& [name, s] : maxSag_) summary.set(name + "_sag_max", s);
    for (std::size_t i = 0; i < maxReaction_.size(); ++i)
      summary.set("reaction_" + scene_.reactionGroups[i].name + "_max", maxReaction_[i]);
    reportProbesAndReactions(scene_, summary, "");
  }

 private:
  static constexpr std::int64_t kCheckEvery = 64;  // about one internal-force pass each

  std::string where(std::size_t block, std::size_t element) const {
    return fmt::format("{} element {} of block {}", model_.blocks[block]->name(), element, scene_.blockGroups[block]);
  }

  void checkCurrent(bool follow) {
    lastCheck_ = model_.steps();
    const Model::Current now = model_.current();
    criticalMin_ = std::min(criticalMin_, now.criticalTimeStep);
    jacobianMin_ = std::min(jacobianMin_, now.jacobian);
    if (now.jacobian <= 0.0)
      throw common::InstabilityError(
          {"element inverted", where(now.block, now.element), model_.time(),
           fmt::format("its volume ratio det F = {:.3g} ≤ 0: the element turned inside out under the load", now.jacobian),
           "a smaller load, or a finer mesh where the solid is crushed: St. Venant–Kirchhoff offers no resistance to "
           "compression beyond det F → 0, so a strongly compressed solid needs another material law"});
    if (scene_.dtFraction > 0.0) {
      if (follow) followStableStep(now);
    } else if (model_.dt() > now.criticalTimeStep && !warnedDt_) {
      warnedDt_ = true;
      common::logger("fem")->warn(
          "t = {:.4g} s: dt = {:.4g} s is above the stable step of the deformed state, {:.4g} s (reference {:.4g} s; "
          "{}, the most compressed element, has Jacobian {:.3g}). The energy check stops the run if it diverges; "
          "leave explicit.dt out to follow the stable step.",
          model_.time(), model_.dt(), now.criticalTimeStep, referenceCritical_, where(now.block, now.element),
          now.jacobian);
    }
  }

  // A stretched membrane or cable is stiffer and its waves faster. Each change of step costs the scheme a
  // little of its energy conservation, so the step changes only when the stable step moved by a few per
  // cent (and never stays above 0.99 of it).
  void followStableStep(const Model::Current& now) {
    const double follow = std::min(scene_.dtFraction * now.criticalTimeStep, scene_.dtFraction * referenceCritical_);
    const double dt = model_.dt();
    if (dt > std::min(1.02 * follow, 0.99 * now.criticalTimeStep) || follow > 1.05 * dt) {
      // The remaining time in whole steps: the run lands on end_time exactly.
      const double remaining = scene_.endTime - model_.time();
      model_.setTimeStep(remaining / std::ceil(remaining / follow - 1e-9));
      dtMin_ = std::min(dtMin_, model_.dt()), dtMax_ = std::max(dtMax_, model_.dt());
    }
  }

  void checkEnergy() {
    const EnergyState& e = model_.energy();
    scale_ = std::max(scale_, std::abs(e.externalWork) + std::abs(initial_) + e.kinetic);
    const double residual = e.kinetic + e.strain + e.damping - e.externalWork - initial_ - e.initialShift;
    maxResidual_ = std::max(maxResidual_, std::abs(residual));
    // Round-off: the balance subtracts terms as large as each of them.
    const double roundOff = 1e-9 * (std::abs(e.kinetic) + std::abs(e.strain) + std::abs(e.externalWork) +
                                    std::abs(initial_) + std::abs(e.initialShift));
    if (std::abs(residual) > scene_.energyTolerance * scale_ + roundOff) throw energyError(residual);
  }

  common::InstabilityError energyError(double residual) const {
    const Model::Current now = model_.current();
    const auto& v = model_.velocity();
    std::size_t fastest = 0;
    double kinetic = 0.0;  // ½ m v² at the half step: the shadow form turns negative when steps alternate
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (std::abs(v[i]) > std::abs(v[fastest])) fastest = i;
      kinetic += 0.5 * model_.nodeMass()[i / 3] * v[i] * v[i];
    }
    const bool growth = residual > 0 || kinetic > scale_;
    // The deformed state's stable step once the run has blown up says little: the smallest seen does.
    const double safe = scene_.dtSafety * std::min({now.criticalTimeStep, referenceCritical_, criticalMin_});
    const std::string dtFix = common::wholeStepValue(scene_.bySteps ? 0.0 : scene_.endTime, safe);
    return common::InstabilityError(
        {growth ? "energy growth" : "energy loss", fmt::format("node {}", fastest / 3), model_.time(),
         fmt::format("the energy balance is off by {:.4g} J, {:.3g} of the run's energy scale {:.4g} J (allowed {:.3g}, "
                     "key explicit.energy_tolerance); node {} moves at {:.4g} m/s; dt = {:.4g} s, the stable step now "
                     "{:.4g} s (reference {:.4g} s)",
                     residual, std::abs(residual) / std::max(scale_, 1e-300), scale_, scene_.energyTolerance,
                     fastest / 3, std::abs(v[fastest]), model_.dt(), now.criticalTimeStep, referenceCritical_),
         safe < model_.dt()
             ? fmt::format("explicit.dt = {} s (at most dt_safety {} × the smallest stable step seen{}), or leave "
                           "explicit.dt out so that explicit.dt_fraction follows the stable step",
                           dtFix, scene_.dtSafety, scene_.bySteps ? "" : "; end_time in whole steps")
             : fmt::format("not the time step (dt = {:.4g} s is below dt_safety × the smallest stable step seen, {:.4g} "
                           "s): the energy came with the loads or, in a coupled run, with the interface forces (a "
                           "smaller coupling.time_window, a tighter coupling tolerance or an implicit scheme)",
                           model_.dt(), safe),
         safe < model_.dt() ? std::vector<std::string>{"explicit.dt=" + dtFix} : std::vector<std::string>{}});
  }

  Scene& scene_;
  Model& model_;
  common::H5Writer& h5_;
  common::Summary& summary_;
  SeriesRecorder series_;
  double initial_ = 0.0;
  const double referenceCritical_;
  double maxResidual_ = 0.0, scale_ = 0.0;
  double criticalMin_, jacobianMin_ = std::numeric_limits<double>::infinity();
  double dtMin_, dtMax_;
  std::int64_t lastCheck_ = -kCheckEvery;
  bool warnedDt_ = false;
  std::map<std::string, double> maxSag_;
  std::vector<double> maxReaction_;
};

}  // namespace

void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart) {
  Model& model = scene.model;
  std::size_t elements = 0;
  for (const auto& b : model.blocks) elements += b->size();
  common::logger("fem")->info("{} nodes, {} element blocks ({} elements), analysis {}", model.nodes(),
                              model.blocks.size(), elements, scene.analysis);
  // A restart reopens the results where the checkpoint left them; the state is read by the loop.
  if (!restart.empty() && scene.analysis != "explicit")
    throw common::ConfigError(fmt::format("--restart: a {} analysis has no steps to continue from", scene.analysis));
  common::ResultsFile results =
      common::openResults(outDir / "fem.h5", restart, kStandaloneKind, model.shape(), outDir / "checkpoint" / "fem.h5");
  common::H5Writer& h5 = *results.h5;
  addMeshes(h5, scene);

  if (!results.restart && (scene.analysis == "static" || scene.initialStatic)) {
    solveStatic(scene, h5, summary);
    if (scene.analysis == "static") {
      fem::writeSnapshot(h5, scene, 0.0, false);
      SeriesRecorder series(h5, scene);
      series.write(series.sample(0.0, 0.0));
      reportPhysics(scene, summary);
      return;
    }
  }

  model.initializeExplicit(scene.dt);
  ExplicitRun run(scene, h5, summary);
  common::RunLoopSettings s;
  s.label = "fem";
  s.kind = kStandaloneKind;
  s.end = scene.endTime;
  s.series = common::Cadence::every(scene.seriesInterval > 0 ? scene.seriesInterval
                                                              : std::max(scene.dt, scene.endTime / 2000));
  s.snapshots = common::Cadence::every(scene.outputInterval);
  s.checkpoints = common::Cadence::after(scene.checkpointInterval);
  s.seriesAtEnd = true;
  s.snapshotAtEnd = scene.outputInterval > 0;
  s.checkpointFile = outDir / "checkpoint" / "fem.h5";
  s.progress = progress;
  common::runLoop(run, std::move(s), &h5, results.restart, restart, summary);
}

}  // namespace fem
