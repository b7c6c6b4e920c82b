#include "coupler.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/h5_writer.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "interface_energy.hpp"
#include "launcher.hpp"
#include "router.hpp"
#include "schemes/scheme.hpp"
#include "window_control.hpp"
#include "cosim/mapping.hpp"
#include "cosim/protocol.hpp"

namespace cosim {

namespace fs = std::filesystem;
namespace pr = protocol;
using common::Config;
using common::ExitCode;
using common::Interval;
using common::SimulationError;
using Clock = std::chrono::steady_clock;

namespace {

volatile std::sig_atomic_t gInterrupted = 0;

void onSignal(int signal) { gInterrupted = signal; }

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A window's coupling iteration diverged: the loop repeats the window as two halves, or ends the run at
// the floor (WindowControl).
struct WindowDiverged {
  double first, now;
  std::uint32_t iteration;
};
// A participant's solver diverged in the window and it can repeat it (RESULT flagged kDiverged).
struct ParticipantDiverged {
  std::string who, text;
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

}  // namespace

namespace {

struct Live {
  ParticipantSpec spec;
  pid_t pid = -1;
  fs::path log;
  // From HELLO.
  std::map<std::string, InterfaceMesh> meshes;
  std::map<std::string, int> reads, writes;  // "mesh/field" → components
  std::set<std::string> unused;               // writes no exchange reads: the participant may leave them out
  bool hello = false;
  // Inputs to send with the next ADVANCE ("mesh/field" → values), and those of the last ADVANCE sent.
  std::map<std::string, std::vector<double>> inputs, advanced;
  // Last RESULT.
  std::map<std::string, std::vector<double>> outputs;
  double solverSeconds = 0.0, waitSeconds = 0.0, stableDt = 0.0;
  std::string diverged;  // its last RESULT said its solver diverged: why
  bool finished = false;
  fs::path restart;  // its checkpoint, when the run restarts
};

// A map of interface fields in a checkpoint: the names, then the values by position (names hold '/').
void archiveFields(common::StateArchive& a, const std::string& name, std::map<std::string, std::vector<double>>& fields) {
  auto scope = a.scope(name);
  std::vector<std::string> names;
  for (const auto& [key, values] : fields) names.push_back(key);
  a.io("names", names);
  for (std::size_t i = 0; i < names.size(); ++i) a.io(std::to_string(i), fields[names[i]]);
}

class Loop final : public SchemeHost {
 public:
  Loop(const CoupledScene& scene, const fs::path& outDir, const fs::path& binDir, bool restart)
      : scene_(scene), outDir_(fs::absolute(outDir)), binDir_(binDir), log_(common::logger("cosim")),
        router_(names(scene), log_), restart_(restart) {}

  ~Loop() { shutdown(); }

  void run(common::Summary& summary, bool progress);

 private:
  [[noreturn]] void fail(const std::string& what) {
    log_->error("{}", what);
    abortAll(what);
    throw SimulationError(what, ExitCode::kCoupling);
  }

  // A participant's solver diverged: exit 3 with the coupling's share of the diagnosis. Its own fix
  // (a smaller step) rarely helps when the interface data it was fed had already gone wrong: a weak
  // scheme's added-mass instability, or windows that stopped converging.
  [[noreturn]] void failDiverged(const std::string& who, const std::string& text) {
    const auto& c = scene_.coupling;
    const bool weak = !scheme_->strong();
    std::string evidence = fmt::format("{} reported: {}", who, text);
    std::string fix;
    if (weak) {
      fix = fmt::format("coupling.scheme: implicit with coupling.acceleration.type: iqn_ils (a weak scheme diverges when "
                        "the side that receives forces is light against the other: added mass), or coupling.time_window "
                        "= {:.3g} s (half)",
                        0.5 * c.window);
    } else if (halvedThisWindow_ && control_->atFloor()) {
      fix = fmt::format("coupling.min_time_window = {:.3g} s (a quarter of the floor {:.3g} s the window was halved "
                        "down to: the participant diverged in each shorter window too), or the participant's own fix "
                        "above",
                        0.25 * control_->size(), control_->size());
    } else if (recentUnconverged_ > 0) {
      evidence += fmt::format("; {} of the last {} windows did not converge (last residual {:.3e}, relative {:.3e})",
                              recentUnconverged_, kRecentWindows, lastResidual_, lastRelative_);
      fix = fmt::format("coupling.time_window = {:.3g} s (half of {:.3g} s): the windows stopped converging before the "
                        "participant diverged, so the interface moved too far within one window",
                        0.5 * c.window, c.window);
    } else {
      fix = "the participant's own fix above (the coupling converged in every recent window)";
    }
    const std::string what = fmt::format("participant \"{}\" diverged (t = {:.6g} s, window {}, iteration {})", who,
                                         time_, window_, iteration_);
    log_->error("{}: {}", what, text);
    abortAll(what);
    throw common::InstabilityError({"participant diverged", fmt::format("participant {}, window {}, iteration {}", who,
                                                                        window_, iteration_),
                                    time_, evidence, fix});
  }

  // The implicit iteration of a window grew instead of converging: the acceleration is too bold for this
  // interface (constant relaxation above 2 / (1 + the added-mass ratio)) or the window too long.
  // SchemeHost: what a scheme drives.
  std::size_t participants() const override { return live_.size(); }
  void send(std::size_t p, std::uint32_t flags) override;
  void collect(std::span<const std::size_t> ps) override;
  void deliver(std::size_t p) override { deliver(live_[p]); }
  std::map<std::string, std::vector<double>>& outputs(std::size_t p) override { return live_[p].outputs; }
  std::vector<std::string> readFields(std::size_t p) const override {
    std::vector<std::string> fields;
    for (const auto& [name, comps] : live_[p].writes)
      for (const auto& r : routes_)
        if (r.from == p && r.spec->fromMesh + "/" + r.spec->field == name) {
          fields.push_back(name);
          break;
        }
    return fields;
  }
  void setIteration(std::uint32_t k) override { iteration_ = k; }
  std::uint64_t window() const override { return window_; }
  void addAccelerationSeconds(double s) override { accelerationSeconds_ += s; }
  [[noreturn]] void iterationDiverged(double first, double now, std::uint32_t k) override {
    throw WindowDiverged{first, now, k};
  }
  double windowSize() const override { return control_->size(); }

  [[noreturn]] void failIterationDiverged(double first, double now, std::uint32_t k) {
    const auto& c = scene_.coupling;
    const bool constant = c.acceleration == "constant";
    // Halving did not help down to the floor: a constant relaxation too bold for the interface does not
    // care for the window; otherwise the window must get shorter still.
    const std::string fix =
        constant ? fmt::format("coupling.acceleration.relaxation = {:.3g} (a quarter), or coupling.acceleration.type: "
                               "iqn_ils (it learns the interface's stiffness)",
                               0.25 * c.accelerationParams.relaxation)
                 : fmt::format("coupling.min_time_window = {:.3g} s (a quarter of the floor {:.3g} s the window was "
                               "halved down to)",
                               0.25 * control_->size(), control_->size());
    const std::string what = fmt::format("the coupling iteration diverged in window {} (t = {:.6g} s)", window_, time_);
    log_->error("{}", what);
    abortAll(what);
    throw common::InstabilityError(
        {"coupling iteration diverged", fmt::format("window {}, iteration {}", window_, k), time_,
         fmt::format("the interface residual grew from {:.3e} at the window's first iteration to {:.3e} at iteration {} "
                     "({} acceleration, a window of {:.3g} s after {} halvings in the run)",
                     first, now, k, c.acceleration, control_->size(), control_->halvings()),
         fix});
  }

  static std::vector<std::string> names(const CoupledScene& scene) {
    std::vector<std::string> n;
    for (const auto& p : scene.participants) n.push_back(p.name);
    return n;
  }
  std::size_t indexOf(const Live& p) const { return static_cast<std::size_t>(&p - live_.data()); }

  void launch(Live& p, const std::string& ep, const std::string& token) {
    std::vector<std::string> args = p.spec.command;
    fs::path program = args[0];
    if (program.filename() == program && fs::exists(binDir_ / program)) program = binDir_ / program;
    args[0] = program.string();
    args.insert(args.end(), {"--couple", ep, "--name", p.spec.name, "--out", (outDir_ / p.spec.name).string(), "--quiet"});
    if (!p.restart.empty()) args.insert(args.end(), {"--restart", p.restart.string()});
    if (p.spec.threads > 0) args.insert(args.end(), {"--threads", std::to_string(p.spec.threads)});
    p.log = outDir_ / (p.spec.name + ".console.log");
    // The token and the coupler's pid travel in the environment (readable by this user only, unlike the
    // command line): the participant proves who it is with the one and watches the other.
    std::vector<std::string> env{"COSIM_TOKEN=" + token, fmt::format("COSIM_COUPLER_PID={}", ::getpid())};
    if (!scene_.coupling.curveSecretKey.empty()) {
      env.push_back("COSIM_CURVE_SERVER_KEY=" + CurveSettings{scene_.coupling.curveSecretKey, {}}.publicKey());
      env.push_back("COSIM_CURVE_SECRET_KEY=" + launchedClientSecret_);
    } else {  // what the coupler's own environment may hold is not this run's
      env.insert(env.end(), {"COSIM_CURVE_SERVER_KEY=", "COSIM_CURVE_SECRET_KEY=", "COSIM_CURVE_SECRET_KEY_FILE="});
    }
    // Participants take turns (Gauss–Seidel) or wait on each other: idle OpenMP threads must sleep
    // instead of spinning on the cores the working participant needs (measured: the rockfall c5 run
    // spent 68 % of its CPU samples in libgomp spin loops). A user's own setting wins.
    if (!std::getenv("OMP_WAIT_POLICY")) env.emplace_back("OMP_WAIT_POLICY=passive");
    try {
      p.pid = cosim::launch({args, p.spec.workDir, p.log, env});
    } catch (const std::exception& e) {
      throw common::ConfigError(fmt::format("participants.{}.command: cannot start {}: {}", p.spec.name, args[0], e.what()));
    }
    log_->info("started {} (pid {}): {}", p.spec.name, p.pid, fmt::join(args, " "));
  }

  // The participant's process ended? Then the run cannot go on.
  // `finishing`: after FINALIZE a participant may exit with code 0 before its BYE is read — that is a
  // normal end (a fast participant raced its own BYE), not a failure.
  void checkAlive(Live& p, bool finishing = false) {
    if (p.pid <= 0 || p.finished) return;
    if (const auto end = pollExit(p.pid)) {
      p.pid = -1;
      if (finishing && end->exited && end->code == 0) {
        p.finished = true;
        return;
      }
      fail(fmt::format("participant \"{}\" {} (t = {:.6g} s, window {}, iteration {}); see {}", p.spec.name,
                       end->describe(), time_, window_, iteration_, p.log.string()));
    }
  }

  void checkInterrupted() {
    if (gInterrupted)
      fail(fmt::format("interrupted ({}) at t = {:.6g} s, window {}, iteration {}: stopping every participant",
                       gInterrupted == SIGINT ? "Ctrl-C" : ::strsignal(gInterrupted), time_, window_, iteration_));
  }

  // The one receive path for the loop: a message of an authenticated participant within 200 ms, its
  // protocol errors and ERROR messages turned into the run's end.
  std::optional<Router::Incoming> next() {
    checkInterrupted();
    std::optional<Router::Incoming> in;
    try {
      in = router_.receive(std::chrono::milliseconds(200));
    } catch (const pr::ProtocolError& e) {
      fail(e.what());
    }
    checkInterrupted();
    if (!in) return in;
    const pr::Message& m = in->message;
    const std::string& who = live_[in->peer].spec.name;
    if (m.header.type == pr::Type::kError && (m.header.flags & pr::kErrorInstability)) failDiverged(who, m.text);
    if (m.header.type == pr::Type::kError)
      fail(fmt::format("participant \"{}\" failed (t = {:.6g} s, window {}, iteration {}): {}", who, time_, window_,
                       iteration_, m.text));
    return in;
  }

  // The answer's deadline: a participant's first answers may include a long setup (a static
  // pre-stress, a large specimen), so they get coupling.first_answer_timeout; every later one
  // coupling.timeout. Heartbeats show the process lives; they never extend the deadline.
  double answerTimeout() const {
    return window_ == startWindow_ ? scene_.coupling.firstAnswerTimeoutSeconds : scene_.coupling.timeoutSeconds;
  }

  [[noreturn]] void failSilent(const Live& p, const char* waitingFor, double limit) {
    const double heard = router_.secondsSinceHeard(indexOf(p));
    const std::string alive =
        heard < 0 ? "it never connected"
        : heard < 3.0
            ? fmt::format("its process still sent heartbeats {:.1f} s ago: its solver is stuck or slower than the "
                          "limit (coupling.{} raises it)",
                          heard, window_ == startWindow_ ? "first_answer_timeout" : "timeout")
            : fmt::format("nothing at all for {:.1f} s: its process is stopped, hung or gone", heard);
    fail(fmt::format("participant \"{}\" sent no {} within {} s (phase {}, t = {:.6g} s, window {}, iteration {}); {} "
                     "— see {}",
                     p.spec.name, waitingFor, limit, finalizing_ ? "finalize" : window_ == 0 && !welcomed_ ? "start" : "window",
                     time_, window_, iteration_, alive, p.log.string()));
  }

  // Waits for `expected` from `p`; any other participant's message is an error.
  pr::Message await(Live& p, pr::Type expected) {
    const double limit = answerTimeout();
    const auto deadline = Clock::now() + std::chrono::duration<double>(limit);
    while (true) {
      for (auto& q : live_) checkAlive(q);
      if (Clock::now() > deadline) failSilent(p, pr::toString(expected), limit);
      auto in = next();
      if (!in) continue;
      const std::string& who = live_[in->peer].spec.name;
      if (&live_[in->peer] != &p)
        fail(fmt::format("participant \"{}\" sent {} while the coupler waited for \"{}\"", who,
                         pr::toString(in->message.header.type), p.spec.name));
      if (in->message.header.type != expected)
        fail(fmt::format("participant \"{}\" sent {} where {} was expected", who, pr::toString(in->message.header.type),
                         pr::toString(expected)));
      return std::move(in->message);
    }
  }

  void send(Live& p, pr::Message m) {
    const pr::Type type = m.header.type;
    if (!router_.send(indexOf(p), std::move(m))) fail(fmt::format("cannot send {} to \"{}\"", pr::toString(type), p.spec.name));
  }

  // After FINALIZE: a BYE from every participant, in whatever order they arrive.
  void collectByes() {
    finalizing_ = true;
    const auto deadline = Clock::now() + std::chrono::duration<double>(scene_.coupling.timeoutSeconds);
    auto pending = [&] { return std::count_if(live_.begin(), live_.end(), [](const Live& l) { return !l.finished; }); };
    while (pending() > 0) {
      for (auto& q : live_)
        if (!q.finished) checkAlive(q, true);
      if (Clock::now() > deadline) {
        for (const auto& q : live_)
          if (!q.finished) failSilent(q, "BYE", scene_.coupling.timeoutSeconds);
      }
      auto in = next();
      if (!in) continue;
      if (in->message.header.type == pr::Type::kBye) live_[in->peer].finished = true;
    }
  }

  void handshake();
  void buildMappings();
  WindowOutcome runWindow(std::uint32_t firstFlags);
  // Restart (coupling.checkpoint_interval): the coupler's checkpoint names the window and each
  // participant's own file; the state between windows is archived by one function for both ways.
  fs::path checkpointDir() const { return outDir_ / "checkpoint"; }
  fs::path participantCheckpoint(const Live& p, std::uint64_t window) const {
    return checkpointDir() / fmt::format("{}_{:08d}.h5", p.spec.name, window);
  }
  void openRestart();                // reads the window and the participants' files, before the launch
  void archiveState(common::StateArchive& a);
  void takeResult(Live& p, pr::Message r);  // a RESULT's outputs and timings, checked
  void deliver(const Live& p);  // map p's outputs into the inputs of the participants that read them
  void abortAll(const std::string& why);
  void shutdown();
  // How long a participant may take to act on SIGTERM (write its summary, flush its files) before
  // SIGKILL: it may be stopped (SIGSTOP) or ignore the signal.
  static constexpr std::chrono::seconds kStopGrace{5};

  const CoupledScene& scene_;
  fs::path outDir_, binDir_;
  std::shared_ptr<spdlog::logger> log_;
  Router router_;
  std::vector<Live> live_;
  struct Route {
    const ExchangeSpec* spec;
    std::size_t from, to;
    std::unique_ptr<Mapping> map;
    int components;
  };
  std::vector<Route> routes_;
  // A force route and the displacement route back on the same interface, with the work on both sides.
  struct EnergyPair {
    std::size_t force, displacement;  // indices in routes_
    InterfaceEnergy energy;
  };
  std::vector<EnergyPair> energyPairs_;
  void pairInterfaces();
  void recordInterfaceEnergy();         // after each final window
  void verifyInterfaceEnergy() const;   // at the end: exit 3 if the coupling made or lost energy
  double time_ = 0.0;
  // Windows that did not converge among the last kRecentWindows, and the last window's residual: the
  // evidence when a participant then diverges.
  static constexpr int kRecentWindows = 20;
  std::uint64_t recentMask_ = 0;
  int recentUnconverged_ = 0;
  double lastResidual_ = 0.0, lastRelative_ = 0.0;
  std::uint64_t window_ = 0;
  std::uint32_t iteration_ = 0;
  // Carried from window to window (and through a restart).
  std::int64_t totalIterations_ = 0, unconverged_ = 0;
  double maxResidual_ = 0.0;
  std::unique_ptr<Scheme> scheme_;
  std::optional<WindowControl> control_;
  std::vector<Clock::time_point> sentAt_;  // per participant: its last ADVANCE
  std::vector<bool> started_;              // per participant: got this window's first ADVANCE
  std::uint32_t windowFlags_ = 0;          // the window's first flags (on-disk checkpoint)
  bool halvedThisWindow_ = false;
  bool restart_ = false;
  std::optional<common::StateArchive> resume_;
  std::uint64_t startWindow_ = 0;  // the first window this process runs (a restart's checkpoint window)
  std::int64_t checkpointsWritten_ = 0;
  double mappingSeconds_ = 0.0, accelerationSeconds_ = 0.0;
  bool finalized_ = false, finalizing_ = false, welcomed_ = false;
  std::string launchedClientSecret_;  // CURVE: the launched participants' secret key (Z85)
};

// One window through the scheme. A diverging iteration repeats it from its start (every participant
// restores its checkpoint, the coupler its interface data) as a window of half the length, down to
// coupling.min_time_window; there the run ends with exit 3.
WindowOutcome Loop::runWindow(std::uint32_t firstFlags) {
  started_.assign(live_.size(), false);
  windowFlags_ = firstFlags;
  halvedThisWindow_ = false;
  // The interface data a repeat starts from; only a strong scheme repeats a window.
  std::vector<std::pair<std::map<std::string, std::vector<double>>, std::map<std::string, std::vector<double>>>> start;
  if (scheme_->strong())
    for (const auto& p : live_) start.emplace_back(p.inputs, p.outputs);
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
                 window_, time_, was, w.iterations, w.residual, w.relative, control_->size());
    } catch (const WindowDiverged& d) {
      const double was = control_->size();
      if (!control_->halve()) failIterationDiverged(d.first, d.now, d.iteration);
      log_->warn("window {} (t = {:.6g} s, {:.3g} s long) diverged at iteration {} (residual {:.3e} → {:.3e}): repeated "
                 "as a window of {:.3g} s",
                 window_, time_, was, d.iteration, d.first, d.now, control_->size());
    } catch (const ParticipantDiverged& d) {
      // Only a strong scheme saved every participant's state at the window's start.
      const double was = control_->size();
      if (!scheme_->strong() || !control_->halve()) failDiverged(d.who, d.text);
      log_->warn("window {} (t = {:.6g} s, {:.3g} s long): participant \"{}\" diverged ({}): repeated as a window of "
                 "{:.3g} s",
                 window_, time_, was, d.who, d.text, control_->size());
    }
    halvedThisWindow_ = true;
    for (std::size_t i = 0; i < live_.size(); ++i) std::tie(live_[i].inputs, live_[i].outputs) = start[i];
    scheme_->abandonWindow();
    // Its on-disk checkpoint was written at the first try; a repeat only restores.
    firstFlags = pr::kRestoreCheckpoint;
  }
}

void Loop::handshake() {
  std::size_t pending = live_.size();
  const double limit = scene_.coupling.firstAnswerTimeoutSeconds;
  auto deadline = Clock::now() + std::chrono::duration<double>(limit);
  while (pending > 0) {
    for (auto& q : live_) checkAlive(q);
    if (Clock::now() > deadline) {
      std::string missing;
      for (const auto& q : live_)
        if (!q.hello) missing += (missing.empty() ? "" : ", ") + q.spec.name;
      std::string refused;
      if (!router_.refusals().empty())
        refused = fmt::format("; {} connection(s) were refused, the last because: {}", router_.refusals().size(),
                              router_.refusals().back());
      fail(fmt::format("no HELLO from {} within {} s (coupling.first_answer_timeout){}", missing, limit, refused));
    }
    auto in = next();
    if (!in) continue;
    Live& p = live_[in->peer];
    const pr::Message& m = in->message;
    if (m.header.type != pr::Type::kHello || p.hello)
      fail(fmt::format("participant \"{}\" sent {} before every participant had said HELLO", p.spec.name,
                       pr::toString(m.header.type)));
    p.hello = true;
    router_.setFeatures(in->peer, m.header.features & pr::kAllFeatures);
    auto* it = &p;
    for (const auto& f : m.fields) {
      if (f.name.rfind("mesh:", 0) == 0) {
        const auto slash = f.name.rfind('/');
        if (slash == std::string::npos || slash < 5) fail(fmt::format("participant \"{}\": HELLO field \"{}\" is not mesh:MESH/nodes or mesh:MESH/triangles", p.spec.name, f.name));
        const std::string mesh = f.name.substr(5, slash - 5), what = f.name.substr(slash + 1);
        InterfaceMesh& im = it->meshes[mesh];
        if (f.data.size() % 3 != 0)
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" holds {} values, not a multiple of 3", p.spec.name,
                           f.name, f.data.size()));
        if (what == "nodes") {
          for (std::size_t k = 0; k + 2 < f.data.size(); k += 3) im.nodes.emplace_back(f.data[k], f.data[k + 1], f.data[k + 2]);
        } else if (what == "triangles") {
          for (std::size_t k = 0; k + 2 < f.data.size(); k += 3) {
            for (int c = 0; c < 3; ++c) {
              const double v = f.data[k + static_cast<std::size_t>(c)];
              if (!(v >= 0) || v != std::floor(v) || v > 4e9)
                fail(fmt::format("participant \"{}\": HELLO field \"{}\" entry {} is {}, not a 0-based node index",
                                 p.spec.name, f.name, k + static_cast<std::size_t>(c), v));
            }
            im.triangles.push_back({static_cast<std::uint32_t>(f.data[k]), static_cast<std::uint32_t>(f.data[k + 1]),
                                    static_cast<std::uint32_t>(f.data[k + 2])});
          }
        } else {
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" is not mesh:MESH/nodes or mesh:MESH/triangles",
                           p.spec.name, f.name));
        }
      } else if (f.name.rfind("read:", 0) == 0 || f.name.rfind("write:", 0) == 0) {
        const double c = f.data.size() == 1 ? f.data[0] : 0.0;
        if (!(c >= 1 && c <= 9 && c == std::floor(c)))
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" must hold one value, the components per node "
                           "(1 to 9)",
                           p.spec.name, f.name));
        const bool read = f.name[0] == 'r';
        (read ? it->reads : it->writes)[f.name.substr(read ? 5 : 6)] = static_cast<int>(c);
      } else {
        fail(fmt::format("participant \"{}\": HELLO field \"{}\" is not one a HELLO carries (mesh:, read:, write:, "
                         "name:, token:)",
                         p.spec.name, f.name));
      }
    }
    for (const auto& [mesh, im] : it->meshes)
      for (const auto& t : im.triangles)
        for (auto v : t)
          if (v >= im.nodes.size())
            fail(fmt::format("participant \"{}\": a triangle of mesh \"{}\" names node {}, but the mesh has {} nodes "
                             "(indices are 0-based)",
                             p.spec.name, mesh, v, im.nodes.size()));
    log_->info("HELLO from {}: meshes {}, reads {}, writes {}", p.spec.name, it->meshes.size(), it->reads.size(), it->writes.size());
    --pending;
  }
}

void Loop::buildMappings() {
  const auto t0 = Clock::now();
  auto index = [&](const std::string& n) {
    return static_cast<std::size_t>(
        std::find_if(live_.begin(), live_.end(), [&](const Live& l) { return l.spec.name == n; }) - live_.begin());
  };
  for (const auto& x : scene_.exchanges) {
    Route r{&x, index(x.from), index(x.to), nullptr, 0};
    Live &from = live_[r.from], &to = live_[r.to];
    const std::string wname = x.fromMesh + "/" + x.field, rname = x.toMesh + "/" + x.field;
    if (!from.writes.count(wname))
      fail(fmt::format("exchange {} → {}: participant \"{}\" does not write {} (it writes: {})", x.from, x.to, x.from,
                       wname, fmt::join([&] {
                         std::vector<std::string> v;
                         for (const auto& [k, c] : from.writes) v.push_back(k);
                         return v;
                       }(), ", ")));
    if (!to.reads.count(rname))
      fail(fmt::format("exchange {} → {}: participant \"{}\" does not read {}", x.from, x.to, x.to, rname));
    r.components = from.writes[wname];
    if (to.reads[rname] != r.components)
      fail(fmt::format("exchange {}: {} writes {} components, {} reads {}", x.field, x.from, r.components, x.to, to.reads[rname]));
    if (!from.meshes.count(x.fromMesh) || !to.meshes.count(x.toMesh))
      fail(fmt::format("exchange {}: mesh {} of {} or {} of {} was not declared", x.field, x.fromMesh, x.from, x.toMesh, x.to));
    try {
      // Consistent: from → to. Conservative: the transpose of the consistent map to → from.
      r.map = x.conservative ? makeMapping(x.mapping, to.meshes[x.toMesh], from.meshes[x.fromMesh])
                             : makeMapping(x.mapping, from.meshes[x.fromMesh], to.meshes[x.toMesh]);
    } catch (const std::exception& e) {
      fail(fmt::format("exchange {} ({} → {}): {}", x.field, x.from, x.to, e.what()));
    }
    if (r.map->copies() && x.mapping != "identity")
      log_->info("exchange {} ({} → {}): every node of one mesh is a node of the other: {} copies values", x.field,
                 x.from, x.to, x.mapping);
    to.inputs[rname].assign(to.meshes[x.toMesh].nodes.size() * static_cast<std::size_t>(r.components), 0.0);
    routes_.push_back(std::move(r));
  }
  for (auto& p : live_)
    for (const auto& [name, comps] : p.writes)
      if (std::none_of(routes_.begin(), routes_.end(), [&](const Route& r) {
            return &live_[r.from] == &p && r.spec->fromMesh + "/" + r.spec->field == name;
          }))
        p.unused.insert(name);
  for (auto& p : live_)
    for (const auto& [name, comps] : p.reads)
      if (!p.inputs.count(name)) fail(fmt::format("participant \"{}\" reads {} but no exchange provides it", p.spec.name, name));
  mappingSeconds_ += seconds(Clock::now() - t0);
}

void Loop::pairInterfaces() {
  for (std::size_t f = 0; f < routes_.size(); ++f) {
    const Route& rf = routes_[f];
    if (!rf.spec->conservative) continue;
    for (std::size_t u = 0; u < routes_.size(); ++u) {
      const Route& ru = routes_[u];
      if (ru.spec->conservative || ru.from != rf.to || ru.to != rf.from || ru.spec->fromMesh != rf.spec->toMesh ||
          ru.spec->toMesh != rf.spec->fromMesh || ru.spec->field != "displacement" || ru.components != rf.components)
        continue;
      energyPairs_.push_back({f, u, {}});
      break;
    }
  }
}

void Loop::recordInterfaceEnergy() {
  auto field = [](const std::map<std::string, std::vector<double>>& m, const std::string& key) {
    const auto it = m.find(key);
    return it == m.end() ? std::span<const double>() : std::span<const double>(it->second);
  };
  for (auto& pair : energyPairs_) {
    const Route &rf = routes_[pair.force], &ru = routes_[pair.displacement];
    const Live &a = live_[rf.from], &b = live_[rf.to];
    const auto fA = field(a.outputs, rf.spec->fromMesh + "/" + rf.spec->field);
    const auto uA = field(a.advanced, ru.spec->toMesh + "/" + ru.spec->field);
    const auto fB = field(b.advanced, rf.spec->toMesh + "/" + rf.spec->field);
    const auto uB = field(b.outputs, ru.spec->fromMesh + "/" + ru.spec->field);
    const auto [dA, dB] = pair.energy.window(fA, uA, fB, uB);
    log_->debug("window {}: interface work {} {:.6e} J, {} {:.6e} J (so far {:.6e} / {:.6e} J)", window_, a.spec.name, dA,
                b.spec.name, dB, pair.energy.workA(), pair.energy.workB());
  }
}

// At the end of the run, over everything that crossed the interface: a window-by-window check would
// trip on the first contact windows, where little has crossed and a one-window lag is all of it.
void Loop::verifyInterfaceEnergy() const {
  for (const auto& pair : energyPairs_) {
    const InterfaceEnergy& e = pair.energy;
    const double tolerance = scene_.coupling.energyTolerance;
    // Where nothing reached the interface both works are round-off and their ratio means nothing: below
    // 1e-18 J crossing (a millionth of the energy of a 1 µg grain at 1 mm/s) the check stands aside.
    if (!(std::abs(e.mismatch()) > tolerance * e.scale()) || e.scale() < 1e-18) continue;
    const Route& rf = routes_[pair.force];
    const Live &a = live_[rf.from], &b = live_[rf.to];
    const bool weak = !scheme_->strong();
    const std::string fix =
        weak ? fmt::format("coupling.scheme: implicit with coupling.acceleration.type: iqn_ils: a weak scheme feeds one "
                           "side the interface a window late, and the lag does work")
             : fmt::format("coupling.tolerance.relative = {:.1e} (a tenth), or coupling.time_window = {:.3g} s (half)",
                           0.1 * scene_.coupling.relativeTolerance, 0.5 * scene_.coupling.window);
    throw common::InstabilityError(
        {e.mismatch() > 0 ? "interface energy created by the coupling" : "interface energy lost by the coupling",
         fmt::format("interface {}/{} ↔ {}/{}", a.spec.name, rf.spec->fromMesh, b.spec.name, rf.spec->toMesh),
         scene_.coupling.endTime,
         fmt::format("over the run the interface forces did {:.4g} J of work on {}'s side and {:.4g} J on {}'s: {:.4g} J "
                     "that no physics made, {:.3g} of the energy that crossed the interface (allowed {:.3g}, key "
                     "coupling.energy_tolerance); the results are not trustworthy",
                     e.workA(), a.spec.name, e.workB(), b.spec.name, e.mismatch(), std::abs(e.mismatch()) / e.scale(),
                     tolerance),
         fix});
  }
}

void Loop::send(std::size_t index, std::uint32_t flags) {
  Live& p = live_[index];
  // A repeat of the window restores what each participant saved at its first ADVANCE of the window; one
  // that a divergence before it in the serial order kept from getting that ADVANCE has saved nothing of
  // this window yet: it gets the window's first flags instead (save, and the on-disk checkpoint).
  if (flags & pr::kSaveCheckpoint) {
    if (!started_[index]) flags = (flags & ~static_cast<std::uint32_t>(pr::kRestoreCheckpoint)) | windowFlags_;
    started_[index] = true;
  }
  pr::Message m;
  m.header.type = pr::Type::kAdvance;
  m.header.window = window_;
  m.header.iteration = iteration_;
  m.header.flags = flags;
  m.header.time = time_;
  m.header.dt = control_->size();
  for (const auto& [name, values] : p.inputs) m.fields.push_back({name, values});
  if (flags & pr::kWriteCheckpoint) m.fields.push_back({"checkpoint:" + participantCheckpoint(p, window_).string(), {}});
  p.advanced = p.inputs;
  sentAt_.resize(live_.size());
  sentAt_[index] = Clock::now();
  send(p, std::move(m));
}

void Loop::collect(std::span<const std::size_t> ps) {
  if (ps.size() == 1) {  // the common case of a serial scheme: its own wait, with its own message
    Live& p = live_[ps[0]];
    takeResult(p, await(p, pr::Type::kResult));
    if (!p.diverged.empty()) throw ParticipantDiverged{p.spec.name, p.diverged};
    return;
  }
  std::vector<std::size_t> pending(ps.begin(), ps.end());
  const double limit = answerTimeout();
  const auto deadline = Clock::now() + std::chrono::duration<double>(limit);
  while (!pending.empty()) {
    for (auto& q : live_) checkAlive(q);
    if (Clock::now() > deadline) failSilent(live_[pending.front()], "RESULT", limit);
    auto in = next();
    if (!in) continue;
    const auto it = std::find(pending.begin(), pending.end(), in->peer);
    const std::string& who = live_[in->peer].spec.name;
    if (it == pending.end())
      fail(fmt::format("participant \"{}\" sent {} while the coupler waited for the others' RESULT", who,
                       pr::toString(in->message.header.type)));
    if (in->message.header.type != pr::Type::kResult)
      fail(fmt::format("participant \"{}\" sent {} where RESULT was expected", who, pr::toString(in->message.header.type)));
    pending.erase(it);
    takeResult(live_[in->peer], std::move(in->message));
  }
  // Every answer is in before the window is repeated: none may arrive late into the repeat.
  for (std::size_t p : ps)
    if (!live_[p].diverged.empty()) throw ParticipantDiverged{live_[p].spec.name, live_[p].diverged};
}

void Loop::takeResult(Live& p, pr::Message r) {
  p.waitSeconds += seconds(Clock::now() - sentAt_[indexOf(p)]);
  p.diverged.clear();
  if (r.header.flags & pr::kDiverged) {
    const auto why = std::find_if(r.fields.begin(), r.fields.end(),
                                  [](const pr::Field& f) { return f.name.rfind("diverged:", 0) == 0; });
    if (!(router_.features(indexOf(p)) & pr::kRetries) || why == r.fields.end() || r.fields.size() != 1)
      fail(fmt::format("participant \"{}\" sent a RESULT flagged diverged {} (window {}, iteration {})", p.spec.name,
                       why == r.fields.end() ? "without its diverged:REASON field"
                                             : "with outputs, or without having offered retries in HELLO",
                       window_, iteration_));
    p.diverged = why->name.substr(9);
    if (p.diverged.empty()) p.diverged = "(no reason given)";
    return;
  }
  p.solverSeconds += r.header.value0;
  p.stableDt = r.header.value1;
  p.outputs.clear();
  for (auto& f : r.fields) {
    const auto w = p.writes.find(f.name);
    if (w == p.writes.end())
      fail(fmt::format("participant \"{}\" sent the field {} in RESULT, which it did not declare as a write (window {}, "
                       "iteration {})",
                       p.spec.name, f.name, window_, iteration_));
    const auto mesh = p.meshes.find(f.name.substr(0, f.name.rfind('/')));
    const std::size_t expected = (mesh == p.meshes.end() ? 0 : mesh->second.nodes.size()) * static_cast<std::size_t>(w->second);
    if (f.data.size() != expected)
      fail(fmt::format("participant \"{}\" sent {} values of {} in RESULT; its mesh has {} nodes × {} components = {} "
                       "(window {}, iteration {})",
                       p.spec.name, f.data.size(), f.name, expected / static_cast<std::size_t>(w->second), w->second,
                       expected, window_, iteration_));
    p.outputs[f.name] = std::move(f.data);
  }
  for (const auto& [name, comps] : p.writes)
    if (!p.outputs.count(name) && !p.unused.count(name)) fail(fmt::format("participant \"{}\" sent RESULT without its write {}", p.spec.name, name));
}

void Loop::deliver(const Live& p) {
  const auto t0 = Clock::now();
  for (auto& r : routes_) {
    if (&live_[r.from] != &p) continue;
    const auto& data = p.outputs.at(r.spec->fromMesh + "/" + r.spec->field);
    auto& target = live_[r.to].inputs[r.spec->toMesh + "/" + r.spec->field];
    try {
      if (r.spec->conservative) r.map->conservative(data, target, r.components);
      else r.map->consistent(data, target, r.components);
    } catch (const std::exception& e) {
      fail(fmt::format("exchange {} ({} → {}): {}", r.spec->field, r.spec->from, r.spec->to, e.what()));
    }
  }
  mappingSeconds_ += seconds(Clock::now() - t0);
}

void Loop::abortAll(const std::string& why) {
  if (finalized_) return;
  finalized_ = true;
  router_.errorToAll(why);
  // Give them a moment to write what they have (their summary, their files' last rows), then make sure
  // nothing is left running: SIGTERM, and SIGKILL after a grace.
  const auto until = Clock::now() + std::chrono::seconds(3);
  for (auto& p : live_) {
    if (p.pid <= 0) continue;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    if (!waitExit(p.pid, std::max(left, std::chrono::milliseconds(0)))) {
      const ProcessEnd end = stop(p.pid, kStopGrace);
      log_->warn("participant {} did not stop by itself; it {}", p.spec.name, end.describe());
    }
    p.pid = -1;
  }
}

void Loop::shutdown() {
  for (auto& p : live_)
    if (p.pid > 0) {
      stop(p.pid, kStopGrace);
      p.pid = -1;
    }
}

std::string describeSizes(const std::map<std::string, std::size_t>& sizes) {
  std::string text;
  for (const auto& [name, n] : sizes) text += fmt::format("{}{} ({} values)", text.empty() ? "" : ", ", name, n);
  return text;
}

void Loop::openRestart() {
  const fs::path file = checkpointDir() / "cosim.h5";
  if (!fs::exists(file))
    throw common::ConfigError(fmt::format("--restart: {} holds no checkpoint ({} is missing); a run writes them with "
                                          "coupling.checkpoint_interval",
                                          outDir_.string(), file.string()));
  common::StateArchive::verify(file);
  resume_ = common::StateArchive::open(file, "cosim");
  double windowSize = 0.0;
  resume_->io("window", startWindow_);
  resume_->io("time_window", windowSize);
  if (windowSize != scene_.coupling.window)
    throw common::ConfigError(fmt::format("--restart: the checkpoint {} is of a run with coupling.time_window = {} s; "
                                          "this scene has {} s",
                                          file.string(), windowSize, scene_.coupling.window));
  for (auto& p : live_) {
    if (p.spec.external)
      throw common::ConfigError(fmt::format("--restart: participant \"{}\" is external: the coupler cannot start it from "
                                            "its checkpoint",
                                            p.spec.name));
    if (!resume_->has("participants/" + p.spec.name))
      throw common::ConfigError(fmt::format("--restart: the checkpoint {} has no participant \"{}\"", file.string(),
                                            p.spec.name));
    std::string name;
    resume_->io("participants/" + p.spec.name, name);
    p.restart = checkpointDir() / name;
    try {
      common::StateArchive::verify(p.restart);
    } catch (const common::ConfigError& e) {
      throw common::ConfigError(fmt::format("--restart: participant \"{}\"'s checkpoint: {}", p.spec.name, e.what()));
    }
  }
  window_ = startWindow_;
}

void Loop::archiveState(common::StateArchive& a) {
  // What this scene's participants exchange: a checkpoint's interface data must have the same fields and
  // sizes (a changed mesh or exchange is another run).
  std::map<std::string, std::size_t> expected;
  for (const auto& p : live_)
    for (const auto& [name, values] : p.inputs) expected[p.spec.name + " reads " + name] = values.size();
  auto scope = a.scope("state");
  a.io("total_iterations", totalIterations_);
  a.io("unconverged", unconverged_), a.io("max_residual", maxResidual_), a.io("recent_mask", recentMask_);
  a.io("recent_unconverged", recentUnconverged_), a.io("last_residual", lastResidual_);
  a.io("last_relative", lastRelative_), a.io("mapping_s", mappingSeconds_), a.io("acceleration_s", accelerationSeconds_);
  for (auto& p : live_) {
    auto own = a.scope("participants/" + p.spec.name);
    archiveFields(a, "inputs", p.inputs);
    archiveFields(a, "outputs", p.outputs);
    a.io("solver_s", p.solverSeconds), a.io("wait_s", p.waitSeconds);
  }
  for (std::size_t i = 0; i < energyPairs_.size(); ++i) a.io(fmt::format("interface_energy_{}", i), energyPairs_[i].energy);
  {
    auto windows = a.scope("windows");
    control_->archive(a);
  }
  auto own = a.scope("scheme");
  scheme_->archive(a);
  if (!a.reading()) return;
  std::map<std::string, std::size_t> found;
  for (const auto& p : live_)
    for (const auto& [name, values] : p.inputs) found[p.spec.name + " reads " + name] = values.size();
  if (found != expected)
    throw common::ConfigError(fmt::format("{}: a checkpoint of another coupled scene: its interface data are {}; this "
                                          "scene's are {}",
                                          a.path().string(), describeSizes(found), describeSizes(expected)));
  for (const auto& p : live_)
    for (const auto& [name, values] : p.outputs) {
      const auto mesh = p.meshes.find(name.substr(0, name.rfind('/')));
      const auto w = p.writes.find(name);
      if (w == p.writes.end() || mesh == p.meshes.end() ||
          values.size() != mesh->second.nodes.size() * static_cast<std::size_t>(w->second))
        throw common::ConfigError(fmt::format("{}: a checkpoint of another coupled scene: participant \"{}\"'s {} holds "
                                              "{} values",
                                              a.path().string(), p.spec.name, name, values.size()));
    }
}

void Loop::run(common::Summary& summary, bool progress) {
  const auto start = Clock::now();
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  fs::create_directories(outDir_);
  // Launched participants share one client key pair made for this run, admitted with the scene's keys.
  CurveSettings curve{scene_.coupling.curveSecretKey, scene_.coupling.curveAllowedKeys};
  if (!curve.secretKey.empty()) {
    auto [pub, sec] = newCurveKeyPair();
    launchedClientSecret_ = sec;
    if (!curve.allowedKeys.empty()) curve.allowedKeys.push_back(pub);
  }
  const std::string bound = router_.bind(scene_.coupling.endpoint, outDir_, curve);
  log_->info("coupler listening on {}", bound);
  const PollingIdleRequest pollingIdle(scene_.coupling.pollingIdle);
  if (pollingIdle.held())
    log_->info("idle CPUs poll while the run lasts (zero wake-up latency requested on /dev/cpu_dma_latency)");
  else if (scene_.coupling.pollingIdle)
    log_->info("idle CPUs may halt between messages: /dev/cpu_dma_latency: {} (root can request zero wake-up "
               "latency; coupling.idle_cpus: sleep silences this)",
               pollingIdle.error());
  std::vector<std::string> tokens;
  for (std::size_t i = 0; i < scene_.participants.size(); ++i) {
    const auto& spec = scene_.participants[i];
    live_.emplace_back().spec = spec;
    const std::string token = tokens.emplace_back(spec.token.empty() ? Router::newToken() : spec.token);
    router_.setToken(i, token);
    if (!spec.external) continue;
    if (!spec.token.empty()) {
      log_->info("waiting for external participant {}: connect to {} with --name {} and its token from the scene",
                 spec.name, bound, spec.name);
      continue;
    }
    // Written for its owner only, in the run folder (itself 0700) or the results folder.
    const fs::path file = (router_.runDir().empty() ? outDir_ : router_.runDir()) / (spec.name + ".token");
    writeSecretFile(file, token + "\n");
    log_->info("waiting for external participant {}: connect to {} with --name {} and the token in {} "
               "(COSIM_TOKEN_FILE={})",
               spec.name, bound, spec.name, file.string(), file.string());
  }
  if (restart_) openRestart();
  for (std::size_t i = 0; i < live_.size(); ++i)
    if (!live_[i].spec.external) launch(live_[i], bound, tokens[i]);
  handshake();
  buildMappings();
  pairInterfaces();
  for (auto& p : live_) {
    pr::Message w;
    w.header.type = pr::Type::kWelcome;
    w.header.dt = scene_.coupling.window;
    w.header.value0 = scene_.coupling.endTime;
    w.header.features = router_.features(indexOf(p));
    for (const auto& name : p.unused) w.fields.push_back({"unused:" + name, {0.0}});
    send(p, std::move(w));
  }
  welcomed_ = true;
  if (scene_.coupling.checkpointInterval > 0)
    for (const auto& p : live_)
      if (!(router_.features(indexOf(p)) & pr::kCheckpoints)) {
        const std::string what = fmt::format("coupling.checkpoint_interval: participant \"{}\" cannot write on-disk "
                                             "checkpoints (it did not offer them in HELLO); leave checkpoint_interval "
                                             "out, or replace it by a participant that can",
                                             p.spec.name);
        abortAll(what);
        throw common::ConfigError(what);
      }

  const auto windows = static_cast<std::uint64_t>(std::llround(scene_.coupling.endTime / scene_.coupling.window));
  control_.emplace(scene_.coupling.window, scene_.coupling.minWindow, scene_.coupling.growAfter, windows);
  scheme_ = makeScheme(scene_.coupling, *this);

  std::unique_ptr<common::H5Writer> file;
  if (resume_) {
    archiveState(*resume_);  // checked against this scene before coupling.h5 is cut back to it
    common::H5Extent extent;
    resume_->io(common::kResultsExtent, extent);
    file = std::make_unique<common::H5Writer>(outDir_ / "coupling.h5", extent);
    log_->info("restarted from the checkpoint of window {} (t = {:.6g} s)", startWindow_, control_->time());
  } else {
    std::error_code ec;  // an earlier run's checkpoints are not this run's to restart from
    fs::remove_all(checkpointDir(), ec);
    file = std::make_unique<common::H5Writer>(outDir_ / "coupling.h5");
  }
  common::H5Writer& h5 = *file;
  std::vector<std::string> cols{"iterations", "residual",  "residual_relative", "converged",
                                "mapping_s",  "acceleration_s", "window_s"};
  for (const auto& p : live_) cols.insert(cols.end(), {p.spec.name + "_solver_s", p.spec.name + "_wait_s"});
  h5.addSeries("windows", cols);

  common::Progress bar("cosim", scene_.coupling.endTime, progress);
  auto& totalIterations = totalIterations_;
  auto& unconverged = unconverged_;
  auto& maxResidual = maxResidual_;
  std::uint64_t lastCheckpoint = resume_ ? startWindow_ : 0;
  resume_.reset();
  // A run that fails still reports how far it got.
  auto reportWindows = [&](std::uint64_t done) {
    summary.setSteps(static_cast<std::int64_t>(done));
    summary.set("windows", static_cast<std::int64_t>(done));
    summary.set("mean_coupling_iterations",
                static_cast<double>(totalIterations) / static_cast<double>(std::max<std::uint64_t>(done, 1)));
    summary.set("unconverged_windows", unconverged);
    summary.set("max_final_residual", maxResidual);
    summary.set("refused_connections", static_cast<std::int64_t>(router_.refusals().size()));
    summary.set("windows_halved", control_->halvings());
    summary.set("smallest_window", control_->smallest());
    for (const auto& pair : energyPairs_) {
      const Route& rf = routes_[pair.force];
      const std::string name = live_[rf.from].spec.name + "_" + live_[rf.to].spec.name;
      summary.set("interface_work_" + live_[rf.from].spec.name, pair.energy.workA());
      summary.set("interface_work_" + live_[rf.to].spec.name, pair.energy.workB());
      summary.set("interface_energy_error_" + name,
                  pair.energy.scale() > 0 ? std::abs(pair.energy.mismatch()) / pair.energy.scale() : 0.0);
    }
  };
  try {
  for (window_ = startWindow_; !control_->finished(); ++window_) {
    time_ = control_->time();
    // A checkpoint of the state at this window's start: the coupler's is written now and committed once
    // the window is done (the participants wrote theirs before their first RESULT of the window).
    std::optional<common::StateArchive> checkpoint;
    const int interval = scene_.coupling.checkpointInterval;
    if (interval > 0 && window_ > 0 && window_ % static_cast<std::uint64_t>(interval) == 0 && window_ != startWindow_) {
      checkpoint = common::StateArchive::create(checkpointDir() / "cosim.h5", "cosim");
      std::uint64_t w = window_;
      double windowSize = scene_.coupling.window;
      checkpoint->io("window", w);
      checkpoint->io("time_window", windowSize);
      for (const auto& p : live_) {
        std::string f = participantCheckpoint(p, window_).filename().string();
        checkpoint->io("participants/" + p.spec.name, f);
      }
      common::archiveExtent(*checkpoint, h5);
      archiveState(*checkpoint);
    }
    const double map0 = mappingSeconds_, acc0 = accelerationSeconds_;
    std::vector<double> solver0, wait0;
    for (const auto& p : live_) {
      solver0.push_back(p.solverSeconds);
      wait0.push_back(p.waitSeconds);
    }
    const WindowOutcome w = runWindow(checkpoint ? pr::kWriteCheckpoint : 0u);
    const double residual = w.residual, relative = w.relative;
    const bool converged = w.converged;
    const std::uint32_t k = w.iterations - 1;
    if (!converged) {
      ++unconverged;
      const std::string msg = fmt::format("window {} (t = {:.6g} s) did not converge in {} iterations: residual {:.3e} "
                                          "(relative {:.3e})",
                                          window_, time_, w.iterations, residual, relative);
      if (scene_.coupling.requireConvergence) fail(msg);
      log_->warn("{}", msg);
    }
    recordInterfaceEnergy();
    totalIterations += k + 1;
    maxResidual = std::max(maxResidual, residual);
    recentMask_ = ((recentMask_ << 1) | (converged ? 0u : 1u)) & ((1ull << kRecentWindows) - 1);
    recentUnconverged_ = __builtin_popcountll(recentMask_);
    lastResidual_ = residual, lastRelative_ = relative;
    std::vector<double> row{static_cast<double>(k + 1),  residual, relative, converged ? 1.0 : 0.0,
                            mappingSeconds_ - map0, accelerationSeconds_ - acc0, control_->size()};
    for (std::size_t i = 0; i < live_.size(); ++i)
      row.insert(row.end(), {live_[i].solverSeconds - solver0[i], live_[i].waitSeconds - wait0[i]});
    const double size = control_->size();
    control_->accept();
    h5.append("windows", time_ + size, row);
    if (window_ % 16 == 0) h5.flush();
    if (checkpoint) {
      checkpoint->commit();
      ++checkpointsWritten_;
      log_->info("checkpoint at window {} (t = {:.6g} s): {}", window_, time_, checkpointDir().string());
      // The previous checkpoint's participant files: no coupler checkpoint names them any more.
      if (lastCheckpoint > 0 && lastCheckpoint != window_)
        for (const auto& p : live_) {
          std::error_code ec;
          fs::remove(participantCheckpoint(p, lastCheckpoint), ec);
        }
      lastCheckpoint = window_;
    }
    bar.update(time_ + size, static_cast<std::int64_t>(window_ + 1));
  }
  } catch (const SimulationError&) {
    h5.flush();
    reportWindows(window_);
    throw;
  }
  bar.finish(control_->time(), static_cast<std::int64_t>(window_));
  h5.flush();

  // FINALIZE, then BYE from everyone.
  for (auto& p : live_) {
    pr::Message f;
    f.header.type = pr::Type::kFinalize;
    send(p, std::move(f));
  }
  collectByes();
  finalized_ = true;
  // A participant still works after its BYE (its last window's record, its final checks): its exit
  // code is its last word, and a failure there fails the run.
  // One that acknowledged but does not end within coupling.timeout is stopped, and the run fails: its
  // files and summary may be incomplete.
  std::vector<std::pair<std::string, int>> failedAtEnd;
  std::vector<std::string> hungAtEnd;
  const auto until = Clock::now() + std::chrono::duration<double>(scene_.coupling.timeoutSeconds);
  for (auto& p : live_) {
    if (p.pid <= 0) continue;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    auto end = waitExit(p.pid, std::max(left, std::chrono::milliseconds(0)));
    if (!end) {
      const ProcessEnd stopped = stop(p.pid, kStopGrace);
      hungAtEnd.push_back(fmt::format("participant \"{}\" acknowledged FINALIZE but had not exited {} s later "
                                      "(coupling.timeout); stopped, it {}; see {}",
                                      p.spec.name, scene_.coupling.timeoutSeconds, stopped.describe(), p.log.string()));
    } else if (!end->exited || end->code != 0) {
      failedAtEnd.emplace_back(p.spec.name, end->exited ? end->code : 128 + end->signal);
    }
    p.pid = -1;
  }
  const double wall = seconds(Clock::now() - start);
  double solverMax = 0.0, waitSum = 0.0;
  for (const auto& p : live_) {
    solverMax = std::max(solverMax, p.solverSeconds);
    waitSum += p.waitSeconds;
    summary.set("solver_time_" + p.spec.name, p.solverSeconds);
  }
  reportWindows(window_);
  summary.set("mapping_time_s", mappingSeconds_);
  summary.set("acceleration_time_s", accelerationSeconds_);
  summary.set("idle_cpus", std::string(pollingIdle.held() ? "poll" : "sleep"));
  // Time in the participants' solvers vs everything else the coupled run spent (exchange, mapping,
  // acceleration, waiting), as a share of the coupler's wall time.
  double solverSum = 0.0;
  for (const auto& p : live_) solverSum += p.solverSeconds;
  summary.set("coupling_overhead_share", wall > 0 ? std::max(0.0, (waitSum - solverSum) + mappingSeconds_ + accelerationSeconds_) / wall : 0.0);
  // What the coupled run started and computed (each participant's own cost is in its summary.yaml).
  std::int64_t launched = 0;
  for (const auto& p : live_) launched += p.spec.external ? 0 : 1;
  summary.setCost("processes", 1 + launched);
  summary.setCost("coupling", fmt::format("{}, {} exchanges, {} interface pairs checked for energy", scheme_->describe(),
                                          routes_.size(), energyPairs_.size()));
  summary.setCost("time_per_window_s",
                  wall / static_cast<double>(std::max<std::uint64_t>(window_ - startWindow_, 1)));
  if (scene_.coupling.checkpointInterval > 0) summary.setCost("checkpoints_written", checkpointsWritten_);
  if (restart_) summary.setCost("restarted_from_window", static_cast<std::int64_t>(startWindow_));
  if (!hungAtEnd.empty()) throw SimulationError(hungAtEnd.front(), ExitCode::kCoupling);
  for (const auto& [name, code] : failedAtEnd) {
    const std::string where = (outDir_ / name / "summary.yaml").string();
    if (code == static_cast<int>(ExitCode::kInstability))
      throw common::InstabilityError({"participant diverged", fmt::format("participant {}, after the last window", name),
                                      scene_.coupling.endTime,
                                      fmt::format("it exited {} after acknowledging the end (its final checks): {}", code,
                                                  where),
                                      fmt::format("the participant's own fix, under failure: in {}", where)});
    throw SimulationError(fmt::format("participant \"{}\" exited with code {} after the last window; see {}", name, code,
                                      where),
                          ExitCode::kCoupling);
  }
  verifyInterfaceEnergy();
}

}  // namespace

void runCoupled(const CoupledScene& scene, const fs::path& outDir, const fs::path& binDir, common::Summary& summary,
                bool progress, bool restart) {
  Loop loop(scene, outDir, binDir, restart);
  loop.run(summary, progress);
}

}  // namespace cosim
