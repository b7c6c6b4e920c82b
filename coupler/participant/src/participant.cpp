#include "cosim/participant.hpp"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <condition_variable>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <set>
#include <thread>

#include <fmt/format.h>

#include "cosim/protocol.hpp"

namespace cosim {

namespace pr = protocol;

using Clock = std::chrono::steady_clock;

namespace {
// SIGTERM or SIGINT to a participant (the coupler stopping a run, a user's Ctrl-C, a batch system):
// noticed at its next wait for the coupler, so the process ends like any failed run, its summary and
// files written (exit 4), instead of vanishing mid-window. Installed only where the program left the
// default action in place, and put back when the participant goes.
volatile std::sig_atomic_t gStopSignal = 0;
void onStopSignal(int signal) { gStopSignal = signal; }

struct StopSignals {
  struct sigaction termBefore {}, intBefore {};
  bool installed = false;
  StopSignals() {
    struct sigaction now {};
    if (::sigaction(SIGTERM, nullptr, &now) != 0 || now.sa_handler != SIG_DFL) return;
    struct sigaction handler {};
    handler.sa_handler = onStopSignal;
    sigemptyset(&handler.sa_mask);
    ::sigaction(SIGTERM, &handler, &termBefore);
    ::sigaction(SIGINT, &handler, &intBefore);
    installed = true;
  }
  ~StopSignals() {
    if (!installed) return;
    ::sigaction(SIGTERM, &termBefore, nullptr);
    ::sigaction(SIGINT, &intBefore, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
};
}  // namespace

struct Participant::Impl {
  std::string name, endpoint, token;
  std::chrono::milliseconds timeout;  // the coupler's silence that means it is gone
  pid_t coupler = 0;                  // COSIM_COUPLER_PID: the coupler that launched this process
  zmq::context_t context{1};
  zmq::socket_t socket{context, zmq::socket_type::dealer};
  struct Declared {
    std::string name;
    int components;
  };
  std::vector<pr::Field> meshFields;
  std::vector<Declared> reads, writes;
  std::map<std::string, std::vector<double>> inputs, outputs;
  std::set<std::string> unused;  // writes no exchange reads (WELCOME): left out of RESULT
  std::uint32_t features = 0;    // what the coupler agreed to use (WELCOME)
  bool checkpoints = false;      // offered in HELLO
  bool retries = false;          // offered in HELLO
  pr::FieldMemory sent, received;  // what update fields are relative to
  pr::Header current;
  // Heartbeats go on the participant's own connection (the coupler accepts no other), sent by a
  // background thread while the solver computes: the socket is shared under `socketMutex` (a ZeroMQ
  // socket may change threads across a full memory barrier).
  StopSignals stopSignals;
  std::thread heartbeat;
  std::mutex mutex, socketMutex;
  std::condition_variable wake;
  bool computing = false, stop = false;

  void send(pr::Message m) {
    auto frames = pr::encode(std::move(m), features, &sent);
    std::lock_guard lock(socketMutex);
    if (!frames.send(socket)) throw CouplingError(fmt::format("participant {}: cannot send to {}", name, endpoint));
  }
  bool couplerGone() const {
    if (coupler <= 0) return false;
    return ::getppid() != coupler && ::kill(coupler, 0) != 0 && errno == ESRCH;
  }
  // The coupler's next message. It sends heartbeats about once a second while it waits, so silence
  // for `timeout` (or the end of the process that launched this one) means it is gone: this process
  // then ends like any failed run (exit 4, files flushed) instead of waiting forever.
  pr::Message receive(const char* waitingFor) {
    auto heard = Clock::now();
    while (true) {
      if (gStopSignal)
        throw CouplingError(fmt::format("participant {}: stopped by {} while it waited for {}", name,
                                        gStopSignal == SIGINT ? "SIGINT (Ctrl-C)" : "SIGTERM", waitingFor));
      std::optional<zmq::multipart_t> frames;
      {
        std::lock_guard lock(socketMutex);
        frames = pr::receive(socket, std::chrono::milliseconds(250));
      }
      if (!frames) {
        if (couplerGone())
          throw CouplingError(fmt::format("participant {}: the coupler (pid {}) is gone while this participant waited "
                                          "for {}",
                                          name, coupler, waitingFor));
        if (Clock::now() - heard > timeout)
          throw CouplingError(fmt::format("participant {}: no {} and no heartbeat from the coupler at {} within {} s: "
                                          "the coupler is gone or stopped",
                                          name, waitingFor, endpoint, timeout.count() / 1000.0));
        continue;
      }
      heard = Clock::now();
      pr::Message m = pr::decode(*frames, "the coupler", (features & pr::kFieldUpdates) ? &received : nullptr);
      if (m.header.type == pr::Type::kHeartbeat) continue;
      if (m.header.type == pr::Type::kError) throw CouplingError(fmt::format("the coupler stopped the run: {}", m.text));
      return m;
    }
  }
  void heartbeatLoop() {
    std::unique_lock lock(mutex);
    while (!stop) {
      wake.wait_for(lock, std::chrono::seconds(1));
      if (stop) break;
      if (!computing) continue;
      pr::Message m;
      m.header.type = pr::Type::kHeartbeat;
      auto frames = pr::encode(m);
      std::lock_guard socketLock(socketMutex);
      try {
        frames.send(socket, static_cast<int>(zmq::send_flags::dontwait));
      } catch (const zmq::error_t&) {
      }
    }
  }
  void setComputing(bool c) {
    std::lock_guard lock(mutex);
    computing = c;
  }
};

namespace {
// The run's token: given, else COSIM_TOKEN, else the first line of the file COSIM_TOKEN_FILE names.
std::string findToken(std::string given) {
  if (!given.empty()) return given;
  if (const char* t = std::getenv("COSIM_TOKEN"); t && *t) return t;
  if (const char* f = std::getenv("COSIM_TOKEN_FILE"); f && *f) {
    std::ifstream in(f);
    std::string line;
    if (!std::getline(in, line)) throw CouplingError(fmt::format("COSIM_TOKEN_FILE={} cannot be read", f));
    return line;
  }
  return {};
}
}  // namespace

Participant::Participant(std::string name, std::string endpoint, std::chrono::milliseconds timeout, std::string token)
    : impl_(std::make_unique<Impl>()) {
  impl_->name = std::move(name);
  impl_->endpoint = std::move(endpoint);
  impl_->timeout = timeout;
  impl_->token = findToken(std::move(token));
  if (const char* pid = std::getenv("COSIM_COUPLER_PID")) impl_->coupler = static_cast<pid_t>(std::atol(pid));
  impl_->socket.set(zmq::sockopt::linger, 1000);
  // CURVE (a coupler reachable from other hosts): the coupler's public key, and this participant's own
  // key pair (given, or fresh for this connection).
  if (const char* server = std::getenv("COSIM_CURVE_SERVER_KEY"); server && *server) {
    std::string secret;
    if (const char* s = std::getenv("COSIM_CURVE_SECRET_KEY"); s && *s) secret = s;
    else if (const char* f = std::getenv("COSIM_CURVE_SECRET_KEY_FILE"); f && *f) std::getline(std::ifstream(f), secret);
    char pub[41] = {}, sec[41] = {};
    if (!secret.empty() && secret.size() != 40)
      throw CouplingError(fmt::format("participant {}: COSIM_CURVE_SECRET_KEY[_FILE] is not 40 Z85 characters", impl_->name));
    if (secret.empty() ? zmq_curve_keypair(pub, sec) != 0 : zmq_curve_public(pub, secret.c_str()) != 0)
      throw CouplingError(fmt::format("participant {}: no usable CURVE key pair (COSIM_CURVE_SECRET_KEY[_FILE])", impl_->name));
    if (!secret.empty()) std::copy(secret.begin(), secret.begin() + 40, sec);
    impl_->socket.set(zmq::sockopt::curve_serverkey, std::string(server));
    impl_->socket.set(zmq::sockopt::curve_publickey, std::string(pub));
    impl_->socket.set(zmq::sockopt::curve_secretkey, std::string(sec));
  } else {
    // PLAIN: the name and token prove this participant in the ZeroMQ handshake, before the coupler's
    // socket gives its connection a routing id (docs/protocol.md, "Joining").
    impl_->socket.set(zmq::sockopt::plain_username, impl_->name);
    impl_->socket.set(zmq::sockopt::plain_password, impl_->token);
  }
  impl_->socket.connect(impl_->endpoint);
}

Participant::~Participant() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stop = true;
  }
  impl_->wake.notify_all();
  if (impl_->heartbeat.joinable()) impl_->heartbeat.join();
}

void Participant::addMesh(const std::string& mesh, std::span<const double> nodes,
                          std::span<const std::uint32_t> triangles) {
  impl_->meshFields.push_back({"mesh:" + mesh + "/nodes", std::vector<double>(nodes.begin(), nodes.end())});
  impl_->meshFields.push_back({"mesh:" + mesh + "/triangles", std::vector<double>(triangles.begin(), triangles.end())});
}

void Participant::addCells(const std::string& mesh, int nodesPerCell, std::span<const std::uint32_t> cells) {
  if (nodesPerCell != 4 && nodesPerCell != 2)
    throw std::invalid_argument(fmt::format("mesh {}: cells of {} nodes; 4 (tetrahedra) or 2 (segments)", mesh, nodesPerCell));
  impl_->meshFields.push_back({"mesh:" + mesh + (nodesPerCell == 4 ? "/tetrahedra" : "/segments"),
                               std::vector<double>(cells.begin(), cells.end())});
}

void Participant::addRead(const std::string& mesh, const std::string& field, int components) {
  impl_->reads.push_back({mesh + "/" + field, components});
}

void Participant::addWrite(const std::string& mesh, const std::string& field, int components) {
  impl_->writes.push_back({mesh + "/" + field, components});
}

void Participant::offerCheckpoints() { impl_->checkpoints = true; }
void Participant::offerRetries() { impl_->retries = true; }
bool Participant::retries() const { return impl_->features & pr::kRetries; }

void Participant::initialize() {
  pr::Message hello;
  hello.header.type = pr::Type::kHello;
  hello.header.features = pr::kAllFeatures & ~(impl_->checkpoints ? 0u : static_cast<std::uint32_t>(pr::kCheckpoints)) &
                          ~(impl_->retries ? 0u : static_cast<std::uint32_t>(pr::kRetries));
  hello.fields = {{"name:" + impl_->name, {}}, {"token:" + impl_->token, {}}};
  hello.fields.insert(hello.fields.end(), impl_->meshFields.begin(), impl_->meshFields.end());
  for (const auto& r : impl_->reads) hello.fields.push_back({"read:" + r.name, {static_cast<double>(r.components)}});
  for (const auto& w : impl_->writes) hello.fields.push_back({"write:" + w.name, {static_cast<double>(w.components)}});
  impl_->send(std::move(hello));
  const pr::Message welcome = impl_->receive("WELCOME");
  if (welcome.header.type != pr::Type::kWelcome)
    throw CouplingError(fmt::format("participant {}: expected WELCOME, got {}", impl_->name, pr::toString(welcome.header.type)));
  impl_->features = welcome.header.features & pr::kAllFeatures;
  for (const auto& f : welcome.fields)
    if (f.name.rfind("unused:", 0) == 0) impl_->unused.insert(f.name.substr(7));
  windowSize_ = welcome.header.dt;
  endTime_ = welcome.header.value0;
  impl_->heartbeat = std::thread([this] { impl_->heartbeatLoop(); });
}

bool Participant::nextWindow(Window& w) {
  pr::Message m = impl_->receive("ADVANCE or FINALIZE");
  if (m.header.type == pr::Type::kFinalize) {
    pr::Message bye;
    bye.header.type = pr::Type::kBye;
    impl_->send(std::move(bye));
    return false;
  }
  if (m.header.type != pr::Type::kAdvance)
    throw CouplingError(fmt::format("participant {}: expected ADVANCE, got {}", impl_->name, pr::toString(m.header.type)));
  impl_->current = m.header;
  impl_->inputs.clear();
  w.checkpoint.clear();
  const bool writeCheckpoint = m.header.flags & pr::kWriteCheckpoint;
  for (auto& f : m.fields) {
    if (writeCheckpoint && f.name.rfind("checkpoint:", 0) == 0) w.checkpoint = f.name.substr(11);
    else impl_->inputs[f.name] = std::move(f.data);
  }
  // A checkpoint is of the window's start: never asked of a participant that cannot write one, nor of a
  // repeated iteration (its state is no longer the window's start).
  if (writeCheckpoint && (!impl_->checkpoints || (m.header.flags & pr::kRestoreCheckpoint) || w.checkpoint.empty()))
    throw CouplingError(fmt::format("participant {}: ADVANCE asks for an on-disk checkpoint {}", impl_->name,
                                    !impl_->checkpoints ? "that this participant did not offer"
                                    : w.checkpoint.empty() ? "but names no file"
                                                           : "on a repeated iteration"));
  for (const auto& r : impl_->reads)
    if (!impl_->inputs.count(r.name))
      throw CouplingError(fmt::format("participant {}: ADVANCE lacks the field {} it reads", impl_->name, r.name));
  w.index = m.header.window;
  w.iteration = m.header.iteration;
  w.time = m.header.time;
  w.dt = m.header.dt;
  w.saveCheckpoint = m.header.flags & pr::kSaveCheckpoint;
  w.restoreCheckpoint = m.header.flags & pr::kRestoreCheckpoint;
  w.writeOutput = m.header.flags & pr::kWriteOutput;
  impl_->outputs.clear();
  impl_->setComputing(true);
  return true;
}

std::span<const double> Participant::read(const std::string& mesh, const std::string& field) const {
  auto it = impl_->inputs.find(mesh + "/" + field);
  if (it == impl_->inputs.end())
    throw CouplingError(fmt::format("participant {}: {}/{} is not a field it reads", impl_->name, mesh, field));
  return it->second;
}

void Participant::write(const std::string& mesh, const std::string& field, std::span<const double> data) {
  const std::string name = mesh + "/" + field;
  if (impl_->unused.count(name)) return;
  impl_->outputs[name].assign(data.begin(), data.end());
}

void Participant::complete(double solverSeconds, double stableDt) {
  impl_->setComputing(false);
  pr::Message result;
  result.header = impl_->current;
  result.header.type = pr::Type::kResult;
  result.header.value0 = solverSeconds;
  result.header.value1 = stableDt;
  for (const auto& w : impl_->writes) {
    if (impl_->unused.count(w.name)) continue;
    auto it = impl_->outputs.find(w.name);
    if (it == impl_->outputs.end())
      throw CouplingError(fmt::format("participant {}: the write {} was not given before complete()", impl_->name, w.name));
    result.fields.push_back({w.name, std::move(it->second)});
  }
  impl_->send(std::move(result));
}

void Participant::diverged(const std::string& text) {
  impl_->setComputing(false);
  pr::Message result;
  result.header = impl_->current;
  result.header.type = pr::Type::kResult;
  result.header.flags = pr::kDiverged;
  result.fields.push_back({"diverged:" + text.substr(0, 4000), {}});
  impl_->send(std::move(result));
}

void Participant::fail(const std::string& text, bool instability) {
  pr::Message m;
  m.header.type = pr::Type::kError;
  if (instability) m.header.flags = pr::kErrorInstability;
  m.text = text;
  try {
    impl_->send(std::move(m));
  } catch (...) {
    // The coupler may be gone already; nothing more to do.
  }
}

}  // namespace cosim
