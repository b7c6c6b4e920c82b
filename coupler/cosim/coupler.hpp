#pragma once
// The coupler process: launches the participants of a coupled scene, performs the handshake, builds the
// mappings, and runs the coupling loop (explicit serial / explicit parallel / implicit serial
// Gauss–Seidel with acceleration), writing coupling.h5 and the summary. docs/protocol.md describes the
// messages; coupler/README.md the scene keys.

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace common {
class Config;
class Summary;
}  // namespace common

namespace cosim {

class Scheme;
class SchemeHost;

struct ParticipantSpec {
  std::string name;
  std::vector<std::string> command;  ///< program and arguments; empty when external
  bool external = false;             ///< started by hand: the coupler waits for its HELLO
  int threads = 0;                   ///< > 0: passed as --threads N (OpenMP threads of the participant)
  /// Where it starts: the folder of the scene file that wrote its `command` (an included file's own
  /// folder, so its relative scene paths hold), else the coupled scene's.
  std::filesystem::path workDir;
  /// Its credential (`token` or `token_file` in the scene); empty: a fresh one for each run.
  std::string token;
};

/// One data flow: `from` writes `field` on `fromMesh`; `to` reads it on `toMesh`.
struct ExchangeSpec {
  std::string from, to, fromMesh, toMesh, field;
  std::string mapping = "nearest_projection";
  bool conservative = false;  ///< forces: map with the transpose, preserving totals
};

struct CouplingSpec {
  std::string scheme = "implicit";  ///< a name of schemeNames() (schemes/scheme.hpp)
  double window = 0.0, endTime = 0.0;
  /// Adaptive windows (WindowControl): the floor of the halvings of a diverging window, and the quiet
  /// windows after which it doubles again (0: never). The scheme's keys set them: an implicit scheme's
  /// min_time_window and grow_after; a weak scheme never repeats a window, so never halves one.
  double minWindow = 0.0;
  int growAfter = 20;
  /// Largest |W_B − W_A| / (energy that crossed the interface) before the run stops with exit 3
  /// (InterfaceEnergy: the energy the coupling itself created or destroyed).
  double energyTolerance = 0.05;
  double timeoutSeconds = 60.0;       ///< per answer of a participant (heartbeats do not extend it)
  double firstAnswerTimeoutSeconds = 600.0;  ///< HELLO and the answers of window 0 (a long setup)
  std::string endpoint;  ///< empty: ipc:// in the results folder
  std::string curveSecretKey;               ///< coupling.curve.secret_key_file's key (Z85); empty: no CURVE
  std::vector<std::string> curveAllowedKeys;  ///< coupling.curve.allowed_keys
  bool pollingIdle = true;  ///< hold a zero wake-up latency request (/dev/cpu_dma_latency) while the run lasts
  /// Windows between on-disk checkpoints of the coupler and every participant (0: none); a run with them
  /// continues from its last one with `cosim run SCENE --out DIR --restart`.
  int checkpointInterval = 0;
  /// Builds the scheme coupling.scheme names, with what its own keys said bound in (schemes/schemes.hpp),
  /// once the participants declared their meshes.
  std::function<std::unique_ptr<Scheme>(const CouplingSpec&, const SchemeHost&)> makeScheme;
};

struct CoupledScene {
  CouplingSpec coupling;
  std::vector<ParticipantSpec> participants;  ///< in Gauss–Seidel order
  std::vector<ExchangeSpec> exchanges;
  std::filesystem::path sceneDir;  ///< participants' commands run from here
};

/// Reads a coupled scene; every error a common::ConfigError with its location.
CoupledScene loadCoupledScene(const common::Config& cfg);

/// `--set NAME:KEY=VALUE` on the cosim command line: KEY=VALUE for participant NAME's own scene, passed
/// on as `--set KEY=VALUE` at the end of its command. Splits `overrides` into the coupled scene's own
/// and these (participant name → overrides), in order. An override is a participant's when a ':' comes
/// before its first '='.
std::map<std::string, std::vector<std::string>> takeParticipantOverrides(std::vector<std::string>& overrides);
/// Appends them to the participants' commands; an unknown participant name is a ConfigError naming the
/// override and the participants there are.
void applyParticipantOverrides(CoupledScene& scene, const std::map<std::string, std::vector<std::string>>& byName);

/// Runs the coupled scene. Throws common::SimulationError with ExitCode::kCoupling on protocol errors,
/// timeouts and participants that die; other participants are stopped and files stay readable.
/// `restart`: continue from the last checkpoint in `outDir` (coupling.checkpoint_interval), appending to its
/// files; a missing, damaged or foreign checkpoint is a common::ConfigError.
void runCoupled(const CoupledScene& scene, const std::filesystem::path& outDir, const std::filesystem::path& binDir,
                common::Summary& summary, bool progress, bool restart = false);

}  // namespace cosim
