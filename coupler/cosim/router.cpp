#include "router.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include <fmt/format.h>

#include "common/summary.hpp"
#include <spdlog/spdlog.h>

#include "common/errors.hpp"

namespace cosim {

namespace fs = std::filesystem;
namespace pr = protocol;
using Clock = std::chrono::steady_clock;

namespace {

// Readable form of a ZeroMQ-assigned routing identity (binary) for the log.
std::string hex(const std::string& bytes) {
  std::string s;
  for (unsigned char c : bytes) s += fmt::format("{:02x}", c);
  return s;
}

// Compares in time independent of where the strings differ: a token is not guessed byte by byte.
bool sameSecret(const std::string& a, const std::string& b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::min(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0 && !a.empty();
}

bool isLoopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

// The private folder of a run's ipc socket: a fresh 0700 folder (mkdtemp), so no other user can connect to
// it whatever the umask, and it goes with the run; in TMPDIR when `outDir` is too long a path for a socket.
fs::path privateRunDir(const fs::path& outDir) {
  std::string pattern = (outDir / ".cosim-XXXXXX").string();
  if (pattern.size() + 12 > 100) {  // sun_path holds 108 bytes
    const char* tmp = std::getenv("TMPDIR");
    pattern = (fs::path(tmp && *tmp ? tmp : "/tmp") / "cosim-XXXXXX").string();
  }
  std::vector<char> buf(pattern.begin(), pattern.end());
  buf.push_back('\0');
  if (!::mkdtemp(buf.data()))
    throw common::SimulationError(fmt::format("cannot create the run folder {}: {}", pattern, std::strerror(errno)),
                                  common::ExitCode::kCoupling);
  return buf.data();
}

// The handshake check's verdict on one ZAP request (RFC 27: version, request id, domain, address,
// identity, mechanism, credentials — CURVE: the client's key; PLAIN: user name and password): empty to
// let the peer in, else why not. A malformed request is refused too (its REP socket answers every one).
std::string zapRefusal(const zmq::multipart_t& request, bool useCurve, const std::vector<std::string>& allowed,
                       const std::vector<std::pair<std::string, std::string>>& credentials) {
  const std::string mechanism = request.size() >= 7 ? request.at(5).to_string() : "";
  if (useCurve && mechanism == "CURVE" && request.at(6).size() == 32) {
    char z85[41] = {};
    zmq_z85_encode(z85, static_cast<const std::uint8_t*>(request.at(6).data()), 32);
    return std::find(allowed.begin(), allowed.end(), std::string(z85)) != allowed.end()
               ? ""
               : fmt::format("a CURVE client whose public key {} is not in coupling.curve.allowed_keys", z85);
  }
  if (!useCurve && mechanism == "PLAIN" && request.size() >= 8) {
    const std::string user = request.at(6).to_string(), password = request.at(7).to_string();
    const auto who = std::find_if(credentials.begin(), credentials.end(), [&](const auto& c) { return c.first == user; });
    if (who == credentials.end()) return "a name that is no participant of this run";
    return sameSecret(who->second, password) ? "" : fmt::format("participant \"{}\" with a wrong token", user);
  }
  return "a malformed handshake";
}

}  // namespace

Router::Router(std::vector<std::string> names, std::shared_ptr<spdlog::logger> log) : log_(std::move(log)) {
  for (auto& n : names) peers_.push_back({std::move(n), {}, {}, 0, {}, {}, {}});
  socket_.set(zmq::sockopt::linger, 0);
  socket_.set(zmq::sockopt::router_mandatory, 1);
}

std::string CurveSettings::publicKey() const {
  char pub[41] = {};
  if (zmq_curve_public(pub, secretKey.c_str()) != 0) throw std::runtime_error("not a CURVE secret key");
  return pub;
}

void writeSecretFile(const fs::path& file, const std::string& text) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  const bool ok = fd >= 0 && ::fchmod(fd, 0600) == 0 &&
                  ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  const int error = errno;
  if (fd >= 0) ::close(fd);
  if (!ok)
    throw common::SimulationError(fmt::format("cannot write {}: {}", file.string(), std::strerror(error)),
                                  common::ExitCode::kCoupling);
}

std::pair<std::string, std::string> newCurveKeyPair() {
  char pub[41] = {}, sec[41] = {};
  if (zmq_curve_keypair(pub, sec) != 0) throw std::runtime_error("this libzmq has no CURVE (built without libsodium)");
  return {pub, sec};
}

Router::~Router() {
  // The socket first: with the handshake check gone, libzmq 4.3 would admit a connection unchecked (a
  // missing ZAP handler means "allow"), and a stranger still connecting at the end could reach the table of
  // routing ids.
  socket_.close();
  stopZap_ = true;
  if (zap_.joinable()) zap_.join();
  if (!runDir_.empty()) {
    std::error_code ec;
    fs::remove_all(runDir_, ec);
  }
}

std::string Router::newToken() {
  std::ifstream urandom("/dev/urandom", std::ios::binary);
  unsigned char bytes[16] = {};
  if (!urandom.read(reinterpret_cast<char*>(bytes), sizeof bytes))
    throw std::runtime_error("cannot read /dev/urandom for the run's participant tokens");
  std::string s;
  for (unsigned char c : bytes) s += fmt::format("{:02x}", c);
  return s;
}

std::string Router::bind(const std::string& requested, const fs::path& outDir, const CurveSettings& curve) {
  std::string ep = requested;
  if (ep.empty()) {
    runDir_ = privateRunDir(outDir);
    ep = "ipc://" + (runDir_ / "cosim.sock").string();
  } else if (ep.rfind("tcp://", 0) == 0) {
    const std::string rest = ep.substr(6);
    const auto colon = rest.rfind(':');
    const std::string host = rest.substr(0, colon);
    if (!isLoopback(host) && curve.secretKey.empty())
      throw common::ConfigError(fmt::format(
          "coupling.endpoint = {}: \"{}\" lets other machines reach the coupler, which then needs ZeroMQ CURVE: make a "
          "key pair with `cosim keys PREFIX` and give coupling.curve.secret_key_file: PREFIX.secret (participants get "
          "the public key as COSIM_CURVE_SERVER_KEY). Participants on one host: leave coupling.endpoint out (a private "
          "ipc socket) or use tcp://127.0.0.1:PORT.",
          ep, host));
  }
  // Every peer proves itself in the ZeroMQ handshake (ZAP, RFC 27), before the router gives its connection
  // a routing id. A stranger therefore never reaches the router's table of routing ids, where libzmq 4.3
  // aborts the process when a peer's self-chosen id equals one it later assigns to a peer without one
  // (its counter starts at the same value in every run). PLAIN: a participant's name and token; CURVE: a
  // listed public key (the launched participants' run key is always listed).
  const bool useCurve = !curve.secretKey.empty();
  if (useCurve) {
    socket_.set(zmq::sockopt::curve_server, 1);
    socket_.set(zmq::sockopt::curve_secretkey, curve.secretKey);
  } else {
    socket_.set(zmq::sockopt::plain_server, 1);
  }
  std::vector<std::pair<std::string, std::string>> credentials;  // name, token: fixed before the bind
  for (const auto& p : peers_) credentials.emplace_back(p.name, p.token);
  // The handler must be bound before the first connection arrives.
  auto ready = std::make_shared<std::atomic<int>>(0);
  zap_ = std::thread([this, useCurve, allowed = curve.allowedKeys, credentials, ready] {
    zmq::socket_t handler(context_, zmq::socket_type::rep);
    handler.set(zmq::sockopt::linger, 0);
    try {
      handler.bind("inproc://zeromq.zap.01");
    } catch (const zmq::error_t&) {
      *ready = 2;
      return;
    }
    *ready = 1;
    while (!stopZap_) try {
      auto request = pr::receive(handler, std::chrono::milliseconds(200));
      if (!request) continue;
      const std::string refused = zapRefusal(*request, useCurve, allowed, credentials);
      const std::string version = request->size() >= 7 ? request->at(0).to_string() : "1.0";
      const std::string id = request->size() >= 2 ? request->at(1).to_string() : "";
      if (!refused.empty()) {
        std::lock_guard lock(refusalsMutex_);
        if (refusals_.size() < 1000) refusals_.push_back("in the handshake: " + refused);
        if (refusals_.size() <= 20) log_->warn("refused a connection in the handshake: {}", refused);
      }
      zmq::multipart_t reply;
      reply.addstr(version);
      reply.addstr(id);
      reply.addstr(refused.empty() ? "200" : "400");
      reply.addstr(refused.empty() ? "OK" : "not a participant of this run");
      reply.addstr("");
      reply.addstr("");
      reply.send(handler);
    } catch (const std::exception& e) {
      log_->error("the handshake check (ZAP handler): {}", e.what());
    }
  });
  while (!*ready) std::this_thread::yield();
  if (*ready != 1) throw std::runtime_error("cannot start the handshake check (ZAP handler)");
  try {
    socket_.bind(ep);
  } catch (const zmq::error_t& e) {
    throw common::ConfigError(fmt::format("coupling.endpoint = {}: ZeroMQ cannot bind it ({}). Use ipc://PATH on one "
                                          "host, or tcp://127.0.0.1:PORT.",
                                          ep, e.what()));
  }
  // A socket the scene placed: its file readable and writable by this user only.
  if (ep.rfind("ipc://", 0) == 0 && runDir_.empty()) ::chmod(ep.substr(6).c_str(), 0600);
  return socket_.get(zmq::sockopt::last_endpoint);
}

double Router::secondsSinceHeard(std::size_t peer) const {
  if (peers_[peer].heard == Clock::time_point{}) return -1.0;
  return std::chrono::duration<double>(Clock::now() - peers_[peer].heard).count();
}

std::vector<std::string> Router::refusals() const {
  std::lock_guard lock(refusalsMutex_);
  return refusals_;
}

void Router::refuse(const std::string& routingId, std::uint16_t version, const std::string& reason) {
  {
    std::lock_guard lock(refusalsMutex_);
    if (refusals_.size() < 1000) refusals_.push_back(reason);
    if (refusals_.size() <= 20) log_->warn("refused a connection ({}): {}", hex(routingId), common::cleanUtf8(reason));
  }
  zmq::multipart_t frames = pr::encodeError(common::cleanUtf8("refused: " + reason), version ? version : pr::kVersion);
  frames.pushstr(routingId);
  try {
    frames.send(socket_, static_cast<int>(zmq::send_flags::dontwait));
  } catch (const zmq::error_t&) {
  }
}

std::optional<Router::Incoming> Router::admit(const std::string& routingId, zmq::multipart_t& frames) {
  const std::uint16_t version = pr::peekVersion(frames);
  if (version == 0) {
    refuse(routingId, 0, "its first message is not a cosim HELLO");
    return std::nullopt;
  }
  if (version != pr::kVersion) {
    refuse(routingId, version,
           fmt::format("it speaks protocol version {}; this coupler speaks version {} (docs/protocol.md: a HELLO "
                       "carries the participant's name and the run's token)",
                       version, pr::kVersion));
    return std::nullopt;
  }
  pr::Message m;
  try {
    m = pr::decode(frames, "a connecting peer");
  } catch (const pr::ProtocolError& e) {
    refuse(routingId, version, e.what());
    return std::nullopt;
  }
  if (m.header.type != pr::Type::kHello) {
    refuse(routingId, version, fmt::format("it sent {} before HELLO", pr::toString(m.header.type)));
    return std::nullopt;
  }
  std::string name, token;
  std::vector<pr::Field> rest;
  for (auto& f : m.fields) {
    if (f.name.rfind("name:", 0) == 0) name = f.name.substr(5);
    else if (f.name.rfind("token:", 0) == 0) token = f.name.substr(6);
    else rest.push_back(std::move(f));
  }
  m.fields = std::move(rest);
  const auto it = std::find_if(peers_.begin(), peers_.end(), [&](const Peer& p) { return p.name == name; });
  if (it == peers_.end()) {
    refuse(routingId, version, fmt::format("HELLO names \"{}\", which is not a participant of this run", name));
    return std::nullopt;
  }
  if (!sameSecret(token, it->token)) {
    refuse(routingId, version,
           fmt::format("HELLO as \"{}\" {}", name, token.empty() ? "without a token" : "with a wrong token"));
    return std::nullopt;
  }
  if (!it->routingId.empty()) {
    refuse(routingId, version, fmt::format("HELLO as \"{}\", a name already connected", name));
    return std::nullopt;
  }
  it->routingId = routingId;
  it->heard = Clock::now();
  return Incoming{static_cast<std::size_t>(it - peers_.begin()), std::move(m)};
}

void Router::heartbeat() {
  const auto now = Clock::now();
  if (now - lastBeat_ < std::chrono::seconds(1)) return;
  lastBeat_ = now;
  for (std::size_t i = 0; i < peers_.size(); ++i) {
    if (peers_[i].routingId.empty()) continue;
    zmq::multipart_t frames = pr::encode(pr::Message{{pr::Type::kHeartbeat}, {}, {}});
    frames.pushstr(peers_[i].routingId);
    try {
      frames.send(socket_, static_cast<int>(zmq::send_flags::dontwait));
    } catch (const zmq::error_t&) {
      // Gone or its queue full: the deadline of the wait decides, not the heartbeat.
    }
  }
}

std::optional<Router::Incoming> Router::receive(std::chrono::milliseconds wait) {
  // The caller's own loop checks its signal flag between calls: keep `wait` short (≤ 200 ms).
  const auto until = Clock::now() + wait;
  while (true) {
    heartbeat();
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    if (left.count() <= 0) return std::nullopt;
    auto frames = pr::receive(socket_, std::min(left, std::chrono::milliseconds(200)));
    if (!frames) continue;
    const std::string id = frames->popstr();
    const auto it = std::find_if(peers_.begin(), peers_.end(), [&](const Peer& p) { return p.routingId == id; });
    if (it == peers_.end()) {
      if (auto hello = admit(id, *frames)) return hello;
      continue;
    }
    Peer& p = *it;
    p.heard = Clock::now();
    pr::Message m = pr::decode(*frames, fmt::format("participant \"{}\"", p.name),
                               (p.features & pr::kFieldUpdates) ? &p.received : nullptr);
    if (m.header.type == pr::Type::kHeartbeat) continue;
    return Incoming{static_cast<std::size_t>(it - peers_.begin()), std::move(m)};
  }
}

bool Router::send(std::size_t peer, pr::Message m) {
  Peer& p = peers_[peer];
  if (p.routingId.empty()) return false;
  zmq::multipart_t frames = pr::encode(std::move(m), p.features, &p.sent);
  frames.pushstr(p.routingId);
  try {
    return frames.send(socket_);
  } catch (const zmq::error_t&) {
    return false;  // EHOSTUNREACH: its connection is gone
  }
}

void Router::errorToAll(const std::string& text) {
  for (auto& p : peers_) {
    if (p.routingId.empty()) continue;
    zmq::multipart_t frames = pr::encodeError(common::cleanUtf8(text));
    frames.pushstr(p.routingId);
    try {
      frames.send(socket_, static_cast<int>(zmq::send_flags::dontwait));
    } catch (const zmq::error_t&) {
    }
  }
}

}  // namespace cosim
