#include "connections.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "launcher.hpp"

namespace cosim {

namespace fs = std::filesystem;
namespace pr = protocol;
using Clock = std::chrono::steady_clock;
using common::ExitCode;
using common::SimulationError;

namespace {
volatile std::sig_atomic_t gInterrupted = 0;
void onSignal(int signal) { gInterrupted = signal; }

// How long a participant may take to act on SIGTERM (write its summary, flush its files) before
// SIGKILL: it may be stopped (SIGSTOP) or ignore the signal.
constexpr std::chrono::seconds kStopGrace{5};

template <class TimePoint>
std::chrono::milliseconds until(TimePoint t) {
  return std::max(std::chrono::duration_cast<std::chrono::milliseconds>(t - Clock::now()), std::chrono::milliseconds(0));
}
}  // namespace

void watchSignals() {
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
}

Connections::Connections(const CoupledScene& scene, fs::path outDir, fs::path binDir, const Position& at,
                         std::function<void(const std::string&, const std::string&)> onDiverged)
    : scene_(scene), outDir_(std::move(outDir)), binDir_(std::move(binDir)), at_(at),
      onDiverged_(std::move(onDiverged)), log_(common::logger("cosim")), router_(names(scene), log_) {
  for (const auto& spec : scene.participants) all_.emplace_back().spec = spec;
}

Connections::~Connections() {
  for (auto& p : all_)
    if (p.pid > 0) {
      stop(p.pid, kStopGrace);
      p.pid = -1;
    }
}

std::vector<std::string> Connections::names(const CoupledScene& scene) {
  std::vector<std::string> n;
  for (const auto& p : scene.participants) n.push_back(p.name);
  return n;
}

std::string Connections::listen() {
  // Launched participants share one client key pair made for this run, admitted with the scene's keys.
  // The handshake admits the launched participants' run key and the scene's (CURVE), or each participant's
  // name with its token (PLAIN): both are fixed before the bind.
  CurveSettings curve{scene_.coupling.curveSecretKey, scene_.coupling.curveAllowedKeys};
  if (!curve.secretKey.empty()) {
    auto [pub, sec] = newCurveKeyPair();
    launchedClientSecret_ = sec;
    curve.allowedKeys.push_back(pub);
  }
  for (std::size_t i = 0; i < all_.size(); ++i)
    router_.setToken(i, tokens_.emplace_back(all_[i].spec.token.empty() ? Router::newToken() : all_[i].spec.token));
  const std::string bound = router_.bind(scene_.coupling.endpoint, outDir_, curve);
  log_->info("coupler listening on {}", bound);
  for (std::size_t i = 0; i < all_.size(); ++i) {
    const auto& spec = all_[i].spec;
    const std::string& token = tokens_[i];
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
  return bound;
}

void Connections::launchAll(const std::string& endpoint) {
  for (std::size_t i = 0; i < all_.size(); ++i)
    if (!all_[i].spec.external) launch(all_[i], endpoint, tokens_[i]);
}

void Connections::launch(Participant& p, const std::string& ep, const std::string& token) {
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
  // A launcher in the command ([mpirun, -np, "8", dem_solver, …]) finds this build's solvers first, as the
  // coupler finds the command's own program.
  std::string path = "PATH=" + binDir_.string();
  if (const char* inherited = std::getenv("PATH"); inherited && *inherited) path.append(":").append(inherited);
  env.push_back(std::move(path));
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
void Connections::checkAlive(Participant& p, bool finishing) {
  if (p.pid <= 0 || p.finished) return;
  if (const auto end = pollExit(p.pid)) {
    p.pid = -1;
    if (finishing && end->exited && end->code == 0) {
      p.finished = true;
      return;
    }
    fail(fmt::format("participant \"{}\" {} (t = {:.6g} s, window {}, iteration {}); see {}", p.spec.name,
                     end->describe(), at_.time, at_.window, at_.iteration, p.log.string()));
  }
}

void Connections::checkInterrupted() {
  if (gInterrupted)
    fail(fmt::format("interrupted ({}) at t = {:.6g} s, window {}, iteration {}: stopping every participant",
                     gInterrupted == SIGINT ? "Ctrl-C" : ::strsignal(gInterrupted), at_.time, at_.window,
                     at_.iteration));
}

// The one receive path: a message of an authenticated participant within 200 ms, its protocol errors
// and ERROR messages turned into the run's end.
std::optional<Router::Incoming> Connections::next() {
  checkInterrupted();
  std::optional<Router::Incoming> in;
  try {
    in = router_.receive(std::chrono::milliseconds(200));
  } catch (const pr::ProtocolError& e) {
    fail(fmt::format("{} (phase {}, t = {:.6g} s, window {}, iteration {})", e.what(), phaseName(), at_.time,
                     at_.window, at_.iteration));
  }
  checkInterrupted();
  if (!in) return in;
  const pr::Message& m = in->message;
  const std::string& who = all_[in->peer].spec.name;
  if (m.header.type == pr::Type::kError && (m.header.flags & pr::kErrorInstability)) {
    onDiverged_(who, m.text);
    fail(fmt::format("participant \"{}\" diverged: {}", who, m.text));  // onDiverged_ does not return
  }
  if (m.header.type == pr::Type::kError)
    fail(fmt::format("participant \"{}\" failed (t = {:.6g} s, window {}, iteration {}): {}", who, at_.time, at_.window,
                     at_.iteration, m.text));
  return in;
}

// The answer's deadline: a participant's first answers may include a long setup (a static pre-stress,
// a large specimen), so they get coupling.first_answer_timeout; every later one coupling.timeout.
// Heartbeats show the process lives; they never extend the deadline.
double Connections::answerTimeout() const {
  return at_.firstWindow ? scene_.coupling.firstAnswerTimeoutSeconds : scene_.coupling.timeoutSeconds;
}

void Connections::failSilent(const Participant& p, const char* waitingFor, double limit) {
  const double heard = router_.secondsSinceHeard(indexOf(p));
  const std::string alive =
      heard < 0 ? "it never connected"
      : heard < 3.0
          ? fmt::format("its process still sent heartbeats {:.1f} s ago: its solver is stuck or slower than the limit "
                        "(coupling.{} raises it)",
                        heard, at_.firstWindow ? "first_answer_timeout" : "timeout")
          : fmt::format("nothing at all for {:.1f} s: its process is stopped, hung or gone", heard);
  fail(fmt::format("participant \"{}\" sent no {} within {} s (phase {}, t = {:.6g} s, window {}, iteration {}); {} — "
                   "see {}",
                   p.spec.name, waitingFor, limit, phaseName(), at_.time, at_.window, at_.iteration, alive,
                   p.log.string()));
}

const char* Connections::phaseName() const {
  return at_.phase == Position::Phase::kFinalize ? "finalize" : at_.phase == Position::Phase::kStart ? "start" : "window";
}

void Connections::send(Participant& p, pr::Message m) {
  const pr::Type type = m.header.type;
  if (router_.send(indexOf(p), std::move(m))) return;
  // Its connection is gone: most often its process ended (a signal) a moment ago; wait for it briefly, so
  // the message names that cause rather than only the failed send.
  if (p.pid > 0)
    if (const auto end = waitExit(p.pid, std::chrono::milliseconds(1000))) {
      p.pid = -1;
      fail(fmt::format("participant \"{}\" {} (phase {}, t = {:.6g} s, window {}, iteration {}); see {}", p.spec.name,
                       end->describe(), phaseName(), at_.time, at_.window, at_.iteration, p.log.string()));
    }
  fail(fmt::format("cannot send {} to \"{}\": its connection is gone (phase {}, t = {:.6g} s, window {}, iteration {}); "
                   "see {}",
                   pr::toString(type), p.spec.name, phaseName(), at_.time, at_.window, at_.iteration, p.log.string()));
}

void Connections::collect(std::span<const std::size_t> ps,
                          const std::function<void(Participant&, pr::Message)>& take) {
  std::vector<std::size_t> pending(ps.begin(), ps.end());
  const double limit = answerTimeout();
  const auto deadline = Clock::now() + std::chrono::duration<double>(limit);
  while (!pending.empty()) {
    for (auto& q : all_) checkAlive(q);
    if (Clock::now() > deadline) failSilent(all_[pending.front()], "RESULT", limit);
    auto in = next();
    if (!in) continue;
    const auto it = std::find(pending.begin(), pending.end(), in->peer);
    const std::string& who = all_[in->peer].spec.name;
    if (it == pending.end())
      fail(pending.size() == 1 && ps.size() == 1
               ? fmt::format("participant \"{}\" sent {} while the coupler waited for \"{}\"", who,
                             pr::toString(in->message.header.type), all_[pending.front()].spec.name)
               : fmt::format("participant \"{}\" sent {} while the coupler waited for the others' RESULT", who,
                             pr::toString(in->message.header.type)));
    if (in->message.header.type != pr::Type::kResult)
      fail(fmt::format("participant \"{}\" sent {} where RESULT was expected", who, pr::toString(in->message.header.type)));
    pending.erase(it);
    take(all_[in->peer], std::move(in->message));
  }
}

void Connections::handshake() {
  std::size_t pending = all_.size();
  const double limit = scene_.coupling.firstAnswerTimeoutSeconds;
  const auto deadline = Clock::now() + std::chrono::duration<double>(limit);
  while (pending > 0) {
    for (auto& q : all_) checkAlive(q);
    if (Clock::now() > deadline) {
      std::string missing;
      for (const auto& q : all_)
        if (!q.hello) missing += (missing.empty() ? "" : ", ") + q.spec.name;
      std::string refused;
      if (const auto refusals = router_.refusals(); !refusals.empty())
        refused = fmt::format("; {} connection(s) were refused, the last because: {}", refusals.size(), refusals.back());
      fail(fmt::format("no HELLO from {} within {} s (coupling.first_answer_timeout){}", missing, limit, refused));
    }
    auto in = next();
    if (!in) continue;
    Participant& p = all_[in->peer];
    const pr::Message& m = in->message;
    if (p.hello && m.header.type == pr::Type::kHello)
      fail(fmt::format("participant \"{}\" sent a second HELLO", p.spec.name));
    if (m.header.type != pr::Type::kHello || p.hello)
      fail(fmt::format("participant \"{}\" sent {} before every participant had said HELLO", p.spec.name,
                       pr::toString(m.header.type)));
    p.hello = true;
    router_.setFeatures(in->peer, m.header.features & pr::kAllFeatures);
    for (const auto& f : m.fields) {
      if (f.name.rfind("mesh:", 0) == 0) {
        const auto slash = f.name.rfind('/');
        const std::string what = slash == std::string::npos ? std::string() : f.name.substr(slash + 1);
        // Values per entry: coordinates of a node, node indices of a cell.
        const std::size_t per = what == "nodes" || what == "triangles" ? 3 : what == "tetrahedra" ? 4 : what == "segments" ? 2 : 0;
        if (slash == std::string::npos || slash < 5 || per == 0)
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" is not mesh:MESH/ followed by nodes, triangles, "
                           "tetrahedra or segments",
                           p.spec.name, f.name));
        const std::string mesh = f.name.substr(5, slash - 5);
        InterfaceMesh& im = p.meshes[mesh];
        if (f.data.size() % per != 0)
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" holds {} values, not a multiple of {}", p.spec.name,
                           f.name, f.data.size(), per));
        if (what == "nodes") {
          for (std::size_t k = 0; k + 2 < f.data.size(); k += 3) im.nodes.emplace_back(f.data[k], f.data[k + 1], f.data[k + 2]);
          continue;
        }
        for (std::size_t k = 0; k < f.data.size(); ++k) {
          const double v = f.data[k];
          if (!(v >= 0) || v != std::floor(v) || v > 4e9)
            fail(fmt::format("participant \"{}\": HELLO field \"{}\" entry {} is {}, not a 0-based node index",
                             p.spec.name, f.name, k, v));
        }
        auto at = [&](std::size_t k) { return static_cast<std::uint32_t>(f.data[k]); };
        for (std::size_t k = 0; k < f.data.size(); k += per) {
          if (per == 3) im.triangles.push_back({at(k), at(k + 1), at(k + 2)});
          else if (per == 4) im.tetrahedra.push_back({at(k), at(k + 1), at(k + 2), at(k + 3)});
          else im.segments.push_back({at(k), at(k + 1)});
        }
      } else if (f.name.rfind("read:", 0) == 0 || f.name.rfind("write:", 0) == 0) {
        const double c = f.data.size() == 1 ? f.data[0] : 0.0;
        if (!(c >= 1 && c <= 9 && c == std::floor(c)))
          fail(fmt::format("participant \"{}\": HELLO field \"{}\" must hold one value, the components per node "
                           "(1 to 9)",
                           p.spec.name, f.name));
        const bool read = f.name[0] == 'r';
        (read ? p.reads : p.writes)[f.name.substr(read ? 5 : 6)] = static_cast<int>(c);
      } else {
        fail(fmt::format("participant \"{}\": HELLO field \"{}\" is not one a HELLO carries (mesh:, read:, write:, "
                         "name:, token:)",
                         p.spec.name, f.name));
      }
    }
    for (const auto& [mesh, im] : p.meshes) {
      auto check = [&](const auto& cells, const char* kind) {
        for (const auto& c : cells)
          for (auto v : c)
            if (v >= im.nodes.size())
              fail(fmt::format("participant \"{}\": a {} of mesh \"{}\" names node {}, but the mesh has {} nodes "
                               "(indices are 0-based)",
                               p.spec.name, kind, mesh, v, im.nodes.size()));
      };
      check(im.triangles, "triangle");
      check(im.tetrahedra, "tetrahedron");
      check(im.segments, "segment");
    }
    log_->info("HELLO from {}: meshes {}, reads {}, writes {}", p.spec.name, p.meshes.size(), p.reads.size(),
               p.writes.size());
    --pending;
  }
}

void Connections::welcome() {
  for (auto& p : all_) {
    pr::Message w;
    w.header.type = pr::Type::kWelcome;
    w.header.dt = scene_.coupling.window;
    w.header.value0 = scene_.coupling.endTime;
    w.header.features = router_.features(indexOf(p));
    for (const auto& name : p.unused) w.fields.push_back({"unused:" + name, {0.0}});
    send(p, std::move(w));
  }
}

// After FINALIZE: a BYE from every participant, in whatever order they arrive.
void Connections::collectByes() {
  const auto deadline = Clock::now() + std::chrono::duration<double>(scene_.coupling.timeoutSeconds);
  auto pending = [&] { return std::count_if(all_.begin(), all_.end(), [](const Participant& l) { return !l.finished; }); };
  while (pending() > 0) {
    for (auto& q : all_)
      if (!q.finished) checkAlive(q, true);
    if (Clock::now() > deadline)
      for (const auto& q : all_)
        if (!q.finished) failSilent(q, "BYE", scene_.coupling.timeoutSeconds);
    auto in = next();
    if (!in) continue;
    if (in->message.header.type == pr::Type::kBye) all_[in->peer].finished = true;
  }
}

void Connections::finish() {
  for (auto& p : all_) {
    pr::Message f;
    f.header.type = pr::Type::kFinalize;
    send(p, std::move(f));
  }
  collectByes();
  finalized_ = true;
  // A participant still works after its BYE (its last window's record, its final checks): its exit
  // code is its last word, and a failure there fails the run. One that acknowledged but does not end
  // within coupling.timeout is stopped, and the run fails: its files and summary may be incomplete.
  const auto deadline = Clock::now() + std::chrono::duration<double>(scene_.coupling.timeoutSeconds);
  for (auto& p : all_) {
    if (p.pid <= 0) continue;
    auto end = waitExit(p.pid, until(deadline));
    if (!end) {
      const ProcessEnd stopped = stop(p.pid, kStopGrace);
      hungAtEnd_.push_back(fmt::format("participant \"{}\" acknowledged FINALIZE but had not exited {} s later "
                                       "(coupling.timeout); stopped, it {}; see {}",
                                       p.spec.name, scene_.coupling.timeoutSeconds, stopped.describe(), p.log.string()));
    } else if (!end->exited || end->code != 0) {
      failedAtEnd_.emplace_back(p.spec.name, end->exited ? end->code : 128 + end->signal);
    }
    p.pid = -1;
  }
}

void Connections::checkEnds() const {
  if (!hungAtEnd_.empty()) throw SimulationError(hungAtEnd_.front(), ExitCode::kCoupling);
  for (const auto& [name, code] : failedAtEnd_) {
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
}

void Connections::fail(const std::string& raw) {
  // What a peer sent may be quoted (a field name): the log, the ERROR and the summary stay UTF-8.
  const std::string what = common::cleanUtf8(raw);
  log_->error("{}", what);
  abortAll(what);
  throw SimulationError(what, ExitCode::kCoupling);
}

void Connections::abortAll(const std::string& why) {
  if (finalized_) return;
  finalized_ = true;
  router_.errorToAll(why);
  // Give them a moment to write what they have (their summary, their files' last rows), then make sure
  // nothing is left running: SIGTERM, and SIGKILL after a grace.
  const auto deadline = Clock::now() + std::chrono::seconds(3);
  for (auto& p : all_) {
    if (p.pid <= 0) continue;
    if (!waitExit(p.pid, until(deadline))) {
      const ProcessEnd end = stop(p.pid, kStopGrace);
      log_->warn("participant {} did not stop by itself; it {}", p.spec.name, end.describe());
    }
    p.pid = -1;
  }
}

}  // namespace cosim
