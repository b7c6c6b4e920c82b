#pragma once
// The coupler's one receive path: every message of a coupled run comes through Router::receive.
//
// Who may join: a participant is a connection that sent a HELLO naming a participant of the scene and
// that participant's token (a per-run secret: launched participants get it in their environment,
// external ones from the scene or from a 0600 file in the run folder). From then on that connection
// *is* the participant; its routing identity is ZeroMQ's, not a name a stranger could take first.
// A stranger, a wrong or missing token, a second connection under a taken name, a peer of another
// protocol version: refused with an ERROR in words it can read, logged, counted — and never allowed
// to stop or steer the run.
//
// Heartbeats travel both ways on the participant's own connection: the participant's prove its
// process lives while its solver computes (they never extend an answer's deadline); the coupler's,
// about once a second while it waits, let a participant notice that its coupler is gone.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <atomic>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <zmq.hpp>

#include "cosim/protocol.hpp"

namespace spdlog {
class logger;
}

namespace cosim {

/// ZeroMQ CURVE for a coupler reachable from other hosts: encryption, the coupler's identity proven by
/// its key pair, and (optionally) only the listed client public keys admitted.
struct CurveSettings {
  std::string secretKey;                 ///< the coupler's secret key (Z85, 40 characters); empty: no CURVE
  std::vector<std::string> allowedKeys;  ///< client public keys (Z85); empty: any client that has the server key
  std::string publicKey() const;         ///< derived from secretKey
};

/// Writes a secret (a token, a CURVE secret key) to `file`, created with mode 0600: never readable by
/// others, not even for a moment. Throws common::SimulationError when it cannot.
void writeSecretFile(const std::filesystem::path& file, const std::string& text);

/// A fresh CURVE key pair (public, secret), Z85.
std::pair<std::string, std::string> newCurveKeyPair();

class Router {
 public:
  Router(std::vector<std::string> names, std::shared_ptr<spdlog::logger> log);
  ~Router();  // removes the run folder (socket and token files)
  Router(const Router&) = delete;
  Router& operator=(const Router&) = delete;

  /// Binds `requested` (empty: an ipc socket in a fresh 0700 run folder under `outDir`, or under /tmp
  /// when that path is too long for a Unix socket). tcp endpoints must be loopback addresses unless
  /// CURVE is on. Every peer must pass the ZeroMQ handshake first: PLAIN with a participant's name and
  /// token (setToken before bind), or CURVE with a key of `curve.allowedKeys`. Returns the endpoint
  /// participants connect to. Throws common::ConfigError for an endpoint that cannot be used.
  std::string bind(const std::string& requested, const std::filesystem::path& outDir, const CurveSettings& curve = {});
  /// The 0700 folder of the run's socket and token files (empty when the scene named the endpoint).
  const std::filesystem::path& runDir() const { return runDir_; }

  /// A fresh random token (128 bits, hex).
  static std::string newToken();
  void setToken(std::size_t peer, std::string token) { peers_[peer].token = std::move(token); }

  struct Incoming {
    std::size_t peer;  ///< index in the names given at construction
    protocol::Message message;
  };
  /// The next message of an authenticated participant (a HELLO that authenticated one is included),
  /// within `wait`; nothing on timeout or signal. Heartbeats are recorded, not returned. Throws
  /// protocol::ProtocolError for a malformed message from a participant (its name in the text).
  std::optional<Incoming> receive(std::chrono::milliseconds wait);
  /// Sends to a participant; false if it cannot be reached.
  bool send(std::size_t peer, protocol::Message m);
  /// ERROR to every connected participant, without waiting.
  void errorToAll(const std::string& text);

  bool connected(std::size_t peer) const { return !peers_[peer].routingId.empty(); }
  /// Seconds since the participant's last message of any kind (heartbeats included); < 0: never.
  double secondsSinceHeard(std::size_t peer) const;
  std::uint32_t features(std::size_t peer) const { return peers_[peer].features; }
  void setFeatures(std::size_t peer, std::uint32_t f) { peers_[peer].features = f; }
  /// Connections refused so far, each with its reason (in the handshake or at HELLO).
  std::vector<std::string> refusals() const;

 private:
  struct Peer {
    std::string name, token, routingId;
    std::uint32_t features = 0;
    protocol::FieldMemory sent, received;  // what update fields are relative to
    std::chrono::steady_clock::time_point heard{};
  };
  std::optional<Incoming> admit(const std::string& routingId, zmq::multipart_t& frames);
  void refuse(const std::string& routingId, std::uint16_t version, const std::string& reason);
  void heartbeat();

  std::vector<Peer> peers_;
  std::shared_ptr<spdlog::logger> log_;
  zmq::context_t context_{1};
  zmq::socket_t socket_{context_, zmq::socket_type::router};
  std::filesystem::path runDir_;
  std::vector<std::string> refusals_;  // the ZAP handler's thread adds to it too
  mutable std::mutex refusalsMutex_;
  std::chrono::steady_clock::time_point lastBeat_{};
  // ZAP (ZeroMQ RFC 27) handler: admits in the handshake only a participant's name with its token
  // (PLAIN) or a listed key (CURVE); runs while the router lives.
  std::thread zap_;
  std::atomic<bool> stopZap_{false};
};

}  // namespace cosim
