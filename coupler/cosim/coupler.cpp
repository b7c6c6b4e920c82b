#include "coupler.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <optional>

#include <fmt/format.h>

#include "checkpoints.hpp"
#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "connections.hpp"
#include "coupling_record.hpp"
#include "data_path.hpp"
#include "interface_ledger.hpp"
#include "round_trip.hpp"
#include "schemes/scheme.hpp"
#include "window_control.hpp"
#include "cosim/protocol.hpp"

namespace cosim {

namespace fs = std::filesystem;
namespace pr = protocol;
using common::ExitCode;
using common::SimulationError;
using Clock = std::chrono::steady_clock;

namespace {

// A window's coupling iteration diverged: the loop repeats the window as two halves, or ends the run at
// the floor (WindowControl).
struct WindowDiverged {
  double first, now;
  std::uint32_t iteration;
};

// Every coupling message wakes a process that sleeps on a socket, and a halted (virtual) CPU takes
// 50–300 µs to wake: more than a rockfall window's solver work. A PM QoS request of zero wake-up
// latency, held while this file stays open, makes the kernel's idle loop poll instead of halting; a
// polling CPU gives way at once to any runnable thread, so no solver loses its core (measured in
// docs/performance.md). Needs write access to /dev/cpu_dma_latency (root); without it the run goes on.
class PollingIdleRequest {
 public:
  explicit PollingIdleRequest(bool wanted) {
    if (!wanted) return;
    fd_ = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
    const std::int32_t zero = 0;
    if (fd_ >= 0 && ::write(fd_, &zero, sizeof zero) == static_cast<ssize_t>(sizeof zero)) return;
    error_ = std::strerror(errno);
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  ~PollingIdleRequest() {
    if (fd_ >= 0) ::close(fd_);
  }
  PollingIdleRequest(const PollingIdleRequest&) = delete;
  PollingIdleRequest& operator=(const PollingIdleRequest&) = delete;
  bool held() const { return fd_ >= 0; }
  const std::string& error() const { return error_; }

 private:
  int fd_ = -1;
  std::string error_;
};

// The coupled run: the windows from the first to end_time, each through the scheme, repeated shorter when
// it diverges (WindowControl); the diagnosis when the run cannot go on; the summary. Processes and
// messages are Connections', interface data DataPath's, the interface energy InterfaceLedger's,
// coupling.h5 CouplingRecord's, checkpoints Checkpoints'.
class Loop final : public SchemeHost {
 public:
  Loop(const CoupledScene& scene, const fs::path& outDir, const fs::path& binDir, bool restart)
      : scene_(scene), outDir_(fs::absolute(outDir)), log_(common::logger("cosim")),
        peers_(scene, outDir_, binDir, at_, [this](const std::string& who, const std::string& text) { failDiverged(who, text); }),
        data_(scene, peers_, at_), record_(peers_), checkpoints_(outDir_, scene.coupling), restart_(restart) {}

  void run(common::Summary& summary, bool progress);

 private:
  // SchemeHost: what a scheme drives.
  std::size_t participants() const override { return peers_.size(); }
  void send(std::size_t p, std::uint32_t flags) override;
  void collect(std::span<const std::size_t> ps) override { data_.collect(ps); }
  void deliver(std::size_t p) override { data_.deliver(p); }
  std::map<std::string, std::vector<double>>& outputs(std::size_t p) override { return peers_[p].outputs; }
  std::map<std::string, std::vector<double>>& inputs(std::size_t p) override { return peers_[p].inputs; }
  const std::map<std::string, InterfaceMesh>& meshes(std::size_t p) const override { return peers_[p].meshes; }
  const std::string& name(std::size_t p) const override { return peers_[p].spec.name; }
  double stableStep(std::size_t p) const override { return peers_[p].stableDt; }
  std::vector<std::string> readFields(std::size_t p) const override { return data_.readFields(p); }
  void setIteration(std::uint32_t k) override { at_.iteration = k; }
  std::uint64_t window() const override { return at_.window; }
  double windowSize() const override { return control_->size(); }
  void addAccelerationSeconds(double s) override { record_.addAccelerationSeconds(s); }
  [[noreturn]] void iterationDiverged(double first, double now, std::uint32_t k) override {
    throw WindowDiverged{first, now, k};
  }

  [[noreturn]] void failDiverged(const std::string& who, const std::string& text);
  [[noreturn]] void failIterationDiverged(double first, double now, std::uint32_t k);
  /// Launches and greets the participants, builds the data path; a restart's checkpoint opened first.
  std::optional<common::StateArchive> connect(const std::string& bound, common::Summary& summary);
  /// Checks that every participant can write the checkpoints asked for; the window control, the scheme,
  /// and coupling.h5 (cut back to the checkpoint on a restart).
  void prepareWindows(std::optional<common::StateArchive>& resume);
  void runWindows(common::Progress& bar);
  WindowOutcome runWindow(std::uint32_t firstFlags);
  /// The summary's times and cost after a run that went through: `wall` the whole run's, `loopWall` its
  /// windows', `passes` the participants' passes in them.
  void reportTimes(common::Summary& summary, double wall, double loopWall, double passes, bool polling,
                   double roundTrip) const;
  void archiveState(common::StateArchive& a);
  void report(common::Summary& summary) const;

  const CoupledScene& scene_;
  fs::path outDir_;
  std::shared_ptr<spdlog::logger> log_;
  Position at_;
  Connections peers_;
  DataPath data_;
  CouplingRecord record_;
  Checkpoints checkpoints_;
  std::optional<InterfaceLedger> ledger_;
  std::unique_ptr<Scheme> scheme_;
  std::optional<WindowControl> control_;
  std::vector<bool> started_;      // per participant: got this window's first ADVANCE
  std::uint32_t windowFlags_ = 0;  // the window's first flags (on-disk checkpoint)
  bool halvedThisWindow_ = false;
  bool restart_ = false;
  std::uint64_t startWindow_ = 0;  // the first window this process runs (a restart's checkpoint window)
};

// A participant's instability message ends with its fix as settings (common::rerunWith); on the
// coupler's command line each belongs to that participant ("dem:dt=…").
std::vector<std::string> participantSettings(const std::string& who, const std::string& text) {
  const auto at = text.rfind(common::kRerunWith);
  if (at == std::string::npos) return {};
  const std::string rest = text.substr(at + common::kRerunWith.size());
  std::vector<std::string> settings;
  for (std::size_t from = 0;;) {
    const auto next = rest.find(common::kSetSeparator, from);
    settings.push_back(who + ":" + rest.substr(from, next == std::string::npos ? next : next - from));
    if (next == std::string::npos) return settings;
    from = next + common::kSetSeparator.size();
  }
}

// A participant's solver diverged: exit 3 with the coupling's share of the diagnosis. Its own fix (a
// smaller step) rarely helps when the interface data it was fed had already gone wrong: a weak scheme's
// added-mass instability, or windows that stopped converging.
void Loop::failDiverged(const std::string& who, const std::string& text) {
  const auto& c = scene_.coupling;
  std::string evidence = fmt::format("{} reported: {}", who, text);
  std::string fix;
  std::vector<std::string> settings;
  if (scheme_ && !scheme_->strong()) {
    const std::string half = common::wholeStepValue(c.endTime, 0.5 * c.window);
    fix = fmt::format("coupling.scheme: implicit with coupling.acceleration.type: iqn_ils (a weak scheme diverges when "
                      "the side that receives forces is light against the other: added mass), or coupling.time_window "
                      "= {} s (half)",
                      half);
    settings = {"coupling.scheme=implicit", "coupling.acceleration.type=iqn_ils"};
  } else if (halvedThisWindow_ && control_ && control_->atFloor()) {
    const std::string quarter = common::fixValue(0.25 * control_->size());
    fix = fmt::format("coupling.min_time_window = {} s (a quarter of the floor {:.3g} s the window was halved down "
                      "to: the participant diverged in each shorter window too), or the participant's own fix above",
                      quarter, control_->size());
    settings = {"coupling.min_time_window=" + quarter};
  } else if (record_.recentUnconverged() > 0) {
    evidence += fmt::format("; {} of the last {} windows did not converge (last residual {:.3e}, relative {:.3e})",
                            record_.recentUnconverged(), CouplingRecord::kRecentWindows, record_.lastResidual(),
                            record_.lastRelative());
    const std::string half = common::wholeStepValue(c.endTime, 0.5 * c.window);
    fix = fmt::format("coupling.time_window = {} s (half of {:.3g} s): the windows stopped converging before the "
                      "participant diverged, so the interface moved too far within one window",
                      half, c.window);
    settings = {"coupling.time_window=" + half};
  } else {
    fix = "the participant's own fix above (the coupling converged in every recent window)";
    settings = participantSettings(who, text);
  }
  const std::string what = fmt::format("participant \"{}\" diverged (t = {:.6g} s, window {}, iteration {})", who,
                                       at_.time, at_.window, at_.iteration);
  log_->error("{}: {}", what, common::cleanUtf8(text));
  peers_.abortAll(what);
  throw common::InstabilityError({"participant diverged",
                                  fmt::format("participant {}, window {}, iteration {}", who, at_.window, at_.iteration),
                                  at_.time, evidence, fix, settings});
}

// Halving did not help down to the floor: a constant relaxation too bold for the interface (above
// 2 / (1 + the added-mass ratio)) does not care for the window; otherwise the window must get shorter.
void Loop::failIterationDiverged(double first, double now, std::uint32_t k) {
  COSIM_ASSERT(scheme_->iteration(), "a coupling iteration diverged under a scheme that does not iterate");
  const AccelerationSpec& acceleration = scheme_->iteration()->acceleration;
  const bool constant = acceleration.type == "constant";
  const std::string quarter = common::fixValue(0.25 * (constant ? acceleration.relaxation : control_->size()));
  const std::string fix =
      constant ? fmt::format("coupling.acceleration.relaxation = {} (a quarter), or coupling.acceleration.type: "
                             "iqn_ils (it learns the interface's stiffness)",
                             quarter)
               : fmt::format("coupling.min_time_window = {} s (a quarter of the floor {:.3g} s the window was halved "
                             "down to)",
                             quarter, control_->size());
  const std::string what = fmt::format("the coupling iteration diverged in window {} (t = {:.6g} s)", at_.window, at_.time);
  log_->error("{}", what);
  peers_.abortAll(what);
  throw common::InstabilityError(
      {"coupling iteration diverged", fmt::format("window {}, iteration {}", at_.window, k), at_.time,
       fmt::format("the interface residual grew from {:.3e} at the window's first iteration to {:.3e} at iteration {} "
                   "({} acceleration, a window of {:.3g} s after {} halvings in the run)",
                   first, now, k, acceleration.type, control_->size(), control_->halvings()),
       fix,
       {(constant ? "coupling.acceleration.relaxation=" : "coupling.min_time_window=") + quarter}});
}

void Loop::send(std::size_t p, std::uint32_t flags) {
  // A repeat of the window restores what each participant saved at its first ADVANCE of the window; one
  // that a divergence before it in the serial order kept from getting that ADVANCE has saved nothing of
  // this window yet: it gets the window's first flags instead (save, and the on-disk checkpoint).
  if (flags & pr::kSaveCheckpoint) {
    if (!started_[p]) flags = (flags & ~static_cast<std::uint32_t>(pr::kRestoreCheckpoint)) | windowFlags_;
    started_[p] = true;
  }
  data_.advance(p, flags, control_->size(),
                flags & pr::kWriteCheckpoint ? checkpoints_.participantFile(peers_[p], at_.window) : fs::path());
}

// One window through the scheme. A diverging iteration repeats it from its start (every participant
// restores its checkpoint, the coupler its interface data) as a window of half the length, down to
// coupling.min_time_window; there the run ends with exit 3.
WindowOutcome Loop::runWindow(std::uint32_t firstFlags) {
  started_.assign(peers_.size(), false);
  windowFlags_ = firstFlags;
  halvedThisWindow_ = false;
  // The interface data a repeat starts from; only a strong scheme repeats a window.
  std::vector<std::pair<Fields, Fields>> start;
  if (scheme_->strong())
    for (const auto& p : peers_.all()) start.emplace_back(p.inputs, p.outputs);
  while (true) {
    try {
      const WindowOutcome w = scheme_->window(*this, firstFlags);
      // A window that stopped far from converged is repeated shorter too: accepted, its interface would do
      // work no physics does (c3 at 4e-4 s: 108 % of the energy that crossed). Near its tolerance, or at
      // the floor, it stands, with a warning.
      const double was = control_->size();
      if (w.converged || w.near || !scheme_->strong() || !control_->halve()) {
        scheme_->acceptWindow(*this, w);
        return w;
      }
      log_->warn("window {} (t = {:.6g} s, {:.3g} s long) did not converge in {} iterations (residual {:.3e}, relative "
                 "{:.3e}): repeated as a window of {:.3g} s",
                 at_.window, at_.time, was, w.iterations, w.residual, w.relative, control_->size());
    } catch (const WindowDiverged& d) {
      const double was = control_->size();
      if (!control_->halve()) failIterationDiverged(d.first, d.now, d.iteration);
      log_->warn("window {} (t = {:.6g} s, {:.3g} s long) diverged at iteration {} (residual {:.3e} → {:.3e}): repeated "
                 "as a window of {:.3g} s",
                 at_.window, at_.time, was, d.iteration, d.first, d.now, control_->size());
    } catch (const ParticipantDiverged& d) {
      // Only a strong scheme saved every participant's state at the window's start.
      const double was = control_->size();
      if (!scheme_->strong() || !control_->halve()) failDiverged(d.who, d.text);
      log_->warn("window {} (t = {:.6g} s, {:.3g} s long): participant \"{}\" diverged ({}): repeated as a window of "
                 "{:.3g} s",
                 at_.window, at_.time, was, d.who, d.text, control_->size());
    }
    halvedThisWindow_ = true;
    for (std::size_t i = 0; i < peers_.size(); ++i) std::tie(peers_[i].inputs, peers_[i].outputs) = start[i];
    scheme_->abandonWindow();
    // Its on-disk checkpoint was written at the first try; a repeat only restores.
    firstFlags = pr::kRestoreCheckpoint;
  }
}

void Loop::archiveState(common::StateArchive& a) {
  auto scope = a.scope("state");
  record_.archive(a);
  data_.archive(a);
  ledger_->archive(a);
  {
    auto windows = a.scope("windows");
    control_->archive(a);
  }
  auto own = a.scope("scheme");
  scheme_->archive(a);
}

void Loop::runWindows(common::Progress& bar) {
  for (at_.window = startWindow_; !control_->finished(); ++at_.window) {
    at_.time = control_->time();
    at_.firstWindow = at_.window == startWindow_;
    // A checkpoint of the state at this window's start: the coupler's is written now and committed once
    // the window is done (the participants wrote theirs before their first RESULT of the window).
    std::optional<common::StateArchive> checkpoint;
    if (checkpoints_.due(at_.window, startWindow_)) {
      checkpoint.emplace(checkpoints_.begin(at_.window, peers_.all(), record_.file()));
      archiveState(*checkpoint);
    }
    record_.begin(data_.mappingSeconds());
    const WindowOutcome w = runWindow(checkpoint ? pr::kWriteCheckpoint : 0u);
    if (!w.converged) {
      const std::string msg = fmt::format("window {} (t = {:.6g} s) did not converge in {} iterations: residual {:.3e} "
                                          "(relative {:.3e})",
                                          at_.window, at_.time, w.iterations, w.residual, w.relative);
      if (const IterationSettings* it = scheme_->iteration(); it && it->requireConvergence) peers_.fail(msg);
      log_->warn("{}", msg);
    }
    ledger_->record(at_.window);
    const double size = control_->size();
    record_.end(w, at_.time + size, size, data_.mappingSeconds());
    control_->accept();
    if (checkpoint) checkpoints_.commit(*checkpoint, at_.window, peers_.all());
    bar.update(at_.time + size, static_cast<std::int64_t>(at_.window + 1));
  }
}

// What the summary says of the windows run so far (a run that fails still reports how far it got).
void Loop::report(common::Summary& summary) const {
  record_.report(summary, at_.window, *control_);
  ledger_->report(summary);
  if (scheme_) scheme_->report(summary);
}

std::optional<common::StateArchive> Loop::connect(const std::string& bound, common::Summary& summary) {
  std::optional<common::StateArchive> resume;
  if (restart_) {
    resume.emplace(checkpoints_.open(peers_.all(), startWindow_));
    at_.window = startWindow_;
  }
  try {
    peers_.launchAll(bound);
    peers_.handshake();
    data_.build(schemeMeshes(scene_.coupling));
    ledger_.emplace(data_, peers_);
    peers_.welcome();
  } catch (const std::exception&) {  // a run that ends before its windows still says whom it refused
    summary.set("refused_connections", static_cast<std::int64_t>(peers_.router().refusals().size()));
    throw;
  }
  return resume;
}

void Loop::prepareWindows(std::optional<common::StateArchive>& resume) {
  if (scene_.coupling.checkpointInterval > 0)
    for (const auto& p : peers_.all())
      if (!(peers_.router().features(peers_.indexOf(p)) & pr::kCheckpoints)) {
        const std::string what = fmt::format("coupling.checkpoint_interval: participant \"{}\" cannot write on-disk "
                                             "checkpoints (it did not offer them in HELLO); leave checkpoint_interval "
                                             "out, or replace it by a participant that can",
                                             p.spec.name);
        peers_.abortAll(what);
        throw common::ConfigError(what);
      }
  const auto windows = static_cast<std::uint64_t>(std::llround(scene_.coupling.endTime / scene_.coupling.window));
  control_.emplace(scene_.coupling.window, scene_.coupling.minWindow, scene_.coupling.growAfter, windows);
  scheme_ = scene_.coupling.makeScheme(scene_.coupling, *this);
  if (resume) {
    archiveState(*resume);  // checked against this scene before coupling.h5 is cut back to it
    record_.open(outDir_, &*resume);
    log_->info("restarted from the checkpoint of window {} (t = {:.6g} s)", startWindow_, control_->time());
  } else {
    checkpoints_.clear();
    record_.open(outDir_, nullptr);
  }
  resume.reset();
}

void Loop::run(common::Summary& summary, bool progress) {
  const auto start = Clock::now();
  watchSignals();
  fs::create_directories(outDir_);
  const std::string bound = peers_.listen();
  const PollingIdleRequest pollingIdle(scene_.coupling.pollingIdle);
  if (pollingIdle.held())
    log_->info("idle CPUs poll while the run lasts (zero wake-up latency requested on /dev/cpu_dma_latency)");
  else if (scene_.coupling.pollingIdle)
    log_->info("idle CPUs may halt between messages: /dev/cpu_dma_latency: {} (root can request zero wake-up "
               "latency; coupling.idle_cpus: sleep silences this)",
               pollingIdle.error());
  std::optional<common::StateArchive> resume = connect(bound, summary);
  at_.phase = Position::Phase::kWindows;
  const double roundTrip = measureRoundTrip(bound, peers_.router().runDir().empty() ? outDir_ : peers_.router().runDir(),
                                            data_.largestAdvance());
  prepareWindows(resume);

  common::Progress bar("cosim", scene_.coupling.endTime, progress);
  const auto loopStart = Clock::now();
  const std::int64_t passes0 = record_.passes();
  try {
    runWindows(bar);
  } catch (const SimulationError&) {
    record_.flush();
    report(summary);
    throw;
  }
  bar.finish(control_->time(), static_cast<std::int64_t>(at_.window));
  record_.flush();
  const double loopWall = std::chrono::duration<double>(Clock::now() - loopStart).count();
  const auto passes = static_cast<double>(std::max<std::int64_t>(record_.passes() - passes0, 1));

  at_.phase = Position::Phase::kFinalize;
  peers_.finish();
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  for (const auto& p : peers_.all()) summary.set("solver_time_" + p.spec.name, p.solverSeconds);
  report(summary);
  reportTimes(summary, wall, loopWall, passes, pollingIdle.held(), roundTrip);
  peers_.checkEnds();
  ledger_->verify(scene_.coupling, *scheme_);
}

void Loop::reportTimes(common::Summary& summary, double wall, double loopWall, double passes, bool polling,
                       double roundTrip) const {
  double solverSum = 0.0, waitSum = 0.0;
  for (const auto& p : peers_.all()) {
    solverSum += p.solverSeconds;
    waitSum += p.waitSeconds;
  }
  summary.set("mapping_time_s", data_.mappingSeconds());
  summary.set("acceleration_time_s", record_.accelerationSeconds());
  summary.set("idle_cpus", std::string(polling ? "poll" : "sleep"));
  // Time in the participants' solvers vs everything else the coupled run spent (exchange, mapping,
  // acceleration, waiting), as a share of the coupler's wall time.
  const double outside = (waitSum - solverSum) + data_.mappingSeconds() + record_.accelerationSeconds();
  summary.set("coupling_overhead_share", wall > 0 ? std::max(0.0, outside) / wall : 0.0);
  // Per pass, what the windows cost beyond the solvers' work on the critical path (messages, waking up,
  // mapping, acceleration, output), beside the machine's bare round trip of a message of that size.
  summary.set("outside_solvers_per_pass_s", std::max(0.0, loopWall - data_.criticalSolverSeconds()) / passes);
  if (roundTrip > 0) summary.set("zmq_round_trip_s", roundTrip);
  // What the coupled run started and computed (each participant's own cost is in its summary.yaml).
  std::int64_t launched = 0;
  for (const auto& p : peers_.all()) launched += p.spec.external ? 0 : 1;
  summary.setCost("processes", 1 + launched);
  summary.setCost("coupling", fmt::format("{}, {} exchanges, {} interface pairs checked for energy", scheme_->describe(),
                                          data_.routes().size(), ledger_->size()));
  summary.setCost("time_per_window_s", wall / static_cast<double>(std::max<std::uint64_t>(at_.window - startWindow_, 1)));
  if (scene_.coupling.checkpointInterval > 0) summary.setCost("checkpoints_written", checkpoints_.written());
  if (restart_) summary.setCost("restarted_from_window", static_cast<std::int64_t>(startWindow_));
}

}  // namespace

void runCoupled(const CoupledScene& scene, const fs::path& outDir, const fs::path& binDir, common::Summary& summary,
                bool progress, bool restart) {
  Loop loop(scene, outDir, binDir, restart);
  loop.run(summary, progress);
}

}  // namespace cosim
