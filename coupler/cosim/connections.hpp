#pragma once
// The participants of a coupled run as processes and peers: launching them, the handshake (HELLO and
// WELCOME), the one receive path with its deadlines, and the end (FINALIZE, BYE, exit codes), or the
// abort of all of them. Everything that goes wrong here ends the run through fail(): an ERROR to every
// participant, SIGTERM then SIGKILL to the launched ones, and common::SimulationError (exit 4).

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "coupler.hpp"
#include "router.hpp"
#include "cosim/mapping.hpp"
#include "cosim/protocol.hpp"

namespace cosim {

using Fields = std::map<std::string, std::vector<double>>;  // "mesh/field" → values

/// One participant: its scene entry, its process, what its HELLO declared and its interface data.
struct Participant {
  ParticipantSpec spec;
  pid_t pid = -1;
  std::filesystem::path log;
  std::map<std::string, InterfaceMesh> meshes;
  std::map<std::string, int> reads, writes;  // "mesh/field" → components
  std::set<std::string> unused;               // writes no exchange reads: the participant may leave them out
  bool hello = false;
  Fields inputs;   // to send with the next ADVANCE
  Fields outputs;  // of the last RESULT
  /// Of the inputs of the last ADVANCE, the fields the interface-energy ledger reads (nothing else is copied).
  Fields advanced;
  std::set<std::string> keepAdvanced;
  double solverSeconds = 0.0, waitSeconds = 0.0, stableDt = 0.0;
  std::chrono::steady_clock::time_point sentAt;  // its last ADVANCE
  std::string diverged;                          // its last RESULT said its solver diverged: why
  bool finished = false;
  std::filesystem::path restart;  // its checkpoint, when the run restarts
};

/// Where the run is, for every message that reports a failure, and which deadline an answer has.
struct Position {
  double time = 0.0;
  std::uint64_t window = 0;
  std::uint32_t iteration = 0;
  bool firstWindow = true;  // answers of the first window this process runs may include a long setup
  enum class Phase { kStart, kWindows, kFinalize } phase = Phase::kStart;
};

class Connections {
 public:
  /// `onDiverged`: a participant's ERROR flagged as an instability (who, text); it must not return.
  Connections(const CoupledScene& scene, std::filesystem::path outDir, std::filesystem::path binDir,
              const Position& at, std::function<void(const std::string&, const std::string&)> onDiverged);
  ~Connections();  // stops what is still running
  Connections(const Connections&) = delete;
  Connections& operator=(const Connections&) = delete;

  std::size_t size() const { return all_.size(); }
  Participant& operator[](std::size_t i) { return all_[i]; }
  const Participant& operator[](std::size_t i) const { return all_[i]; }
  std::vector<Participant>& all() { return all_; }
  const std::vector<Participant>& all() const { return all_; }
  std::size_t indexOf(const Participant& p) const { return static_cast<std::size_t>(&p - all_.data()); }
  const Router& router() const { return router_; }

  /// Binds the coupler's endpoint and hands out the tokens (written to a file for an external
  /// participant without one); returns the bound endpoint.
  std::string listen();
  /// Starts every participant that is not external.
  void launchAll(const std::string& endpoint);
  /// Waits for every HELLO and reads the meshes, reads and writes it declares.
  void handshake();
  /// WELCOME to each: the window, the end, the features agreed and the writes it may leave out.
  void welcome();

  void send(Participant& p, protocol::Message m);
  /// The RESULT of every participant in `ps` (sent to before), each given to `take` as it comes.
  void collect(std::span<const std::size_t> ps, const std::function<void(Participant&, protocol::Message)>& take);

  /// FINALIZE to all, their BYEs, then their exits within coupling.timeout (one that hangs is stopped).
  void finish();
  /// After finish(): a participant that failed or hung after its BYE fails the run (exit 4; exit 3 for
  /// a final check of its own that found an instability).
  void checkEnds() const;

  /// Ends the run: ERROR to all, every launched process stopped, SimulationError(kCoupling).
  [[noreturn]] void fail(const std::string& what);
  /// The same without the throw (a caller that throws its own error); once.
  void abortAll(const std::string& why);

 private:
  void launch(Participant& p, const std::string& endpoint, const std::string& token);
  void checkAlive(Participant& p, bool finishing = false);
  void checkInterrupted();
  std::optional<Router::Incoming> next();
  double answerTimeout() const;
  const char* phaseName() const;
  [[noreturn]] void failSilent(const Participant& p, const char* waitingFor, double limit);
  void collectByes();
  static std::vector<std::string> names(const CoupledScene& scene);

  const CoupledScene& scene_;
  std::filesystem::path outDir_, binDir_;
  const Position& at_;
  std::function<void(const std::string&, const std::string&)> onDiverged_;
  std::shared_ptr<spdlog::logger> log_;
  Router router_;
  std::vector<Participant> all_;
  std::vector<std::string> tokens_;
  std::string launchedClientSecret_;  // CURVE: the launched participants' secret key (Z85)
  bool finalized_ = false;
  std::vector<std::pair<std::string, int>> failedAtEnd_;  // name, exit code
  std::vector<std::string> hungAtEnd_;
};

/// Installs the SIGINT/SIGTERM handlers whose signal the receive path turns into the run's end.
void watchSignals();

}  // namespace cosim
