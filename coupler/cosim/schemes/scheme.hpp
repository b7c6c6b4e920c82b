#pragma once
// Coupling schemes (one class each, registered by name in schemes.cpp): what happens in one
// coupling window — which participants advance, in what order, with which data, and whether the window
// is repeated. The coupler's loop (coupler.cpp) owns the participants, the exchanges, the output and the
// windows; a scheme drives them through SchemeHost.
//
// The implicit schemes share ImplicitIteration (implicit_iteration.hpp): the serial one's pass advances
// the participants in order, the parallel one's send()s to every participant and then collect()s them
// all (they compute at once); the fixed point is readFields of the last participant or of every one.
// The bridging domain (bridging.cpp, volume coupling) uses the same interface: a window is one common
// time step; the scheme sends the trial step to both participants, collects their trial velocities and
// weighted masses of the overlap (outputs on the meshes it owns, kBridgeMeshes), solves the multipliers
// itself, and sends them as the inputs of a second iteration of the same window (kRestoreCheckpoint):
// participants see windows, iterations and checkpoints, as cosim/coupled_solver.hpp describes.

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "../coupler.hpp"
#include "cosim/acceleration.hpp"
#include "cosim/mapping.hpp"

namespace common {
class Config;
class StateArchive;
class Summary;
}

namespace cosim {

/// The coupled run as a scheme sees it. Participants are numbered in the scene's (Gauss–Seidel) order.
class SchemeHost {
 public:
  virtual ~SchemeHost() = default;
  virtual std::size_t participants() const = 0;
  /// ADVANCE to participant `p` with its current inputs and `flags` (protocol.hpp); returns at once.
  virtual void send(std::size_t p, std::uint32_t flags) = 0;
  /// Waits for the RESULT of every participant in `ps` (sent to before), in whatever order they come.
  virtual void collect(std::span<const std::size_t> ps) = 0;
  /// Maps participant `p`'s last outputs into the inputs of the participants that read them.
  virtual void deliver(std::size_t p) = 0;
  /// Participant `p`'s last outputs ("mesh/field" → values); a scheme may replace values (acceleration).
  virtual std::map<std::string, std::vector<double>>& outputs(std::size_t p) = 0;
  /// Participant `p`'s inputs for its next ADVANCE: a scheme that computes them itself (the bridging
  /// domain's multipliers, on the meshes it owns) writes them here.
  virtual std::map<std::string, std::vector<double>>& inputs(std::size_t p) = 0;
  /// The meshes participant `p` declared, and its name and last reported stable step [s] (0: none).
  virtual const std::map<std::string, InterfaceMesh>& meshes(std::size_t p) const = 0;
  virtual const std::string& name(std::size_t p) const = 0;
  virtual double stableStep(std::size_t p) const = 0;
  /// The outputs of `p` that some exchange reads (a field written only for output must not steer an
  /// iteration), in a fixed order.
  virtual std::vector<std::string> readFields(std::size_t p) const = 0;
  /// The iteration now under way (for messages and the protocol header), and the window.
  virtual void setIteration(std::uint32_t k) = 0;
  virtual std::uint64_t window() const = 0;
  /// The length of the window now under way [s] (adaptive: it may be a halving of coupling.time_window).
  virtual double windowSize() const = 0;
  /// Time spent in the acceleration, for the window's record [s].
  virtual void addAccelerationSeconds(double s) = 0;
  /// The iteration diverged: does not return. The coupler repeats the window shorter (from its start,
  /// after abandonWindow()) or, at coupling.min_time_window, ends the run (exit 3, with these numbers).
  [[noreturn]] virtual void iterationDiverged(double firstResidual, double residual, std::uint32_t k) = 0;
};

struct WindowOutcome {
  std::uint32_t iterations = 1;
  double residual = 0.0, relative = 0.0;  ///< the last iteration's interface residual (strong schemes)
  bool converged = true;
  /// Not converged, but every block within kNearTolerance times its tolerance.
  bool near = true;
};
/// An unconverged window this close to its tolerance stands (with a warning) instead of being repeated
/// shorter: c7 at 1e-4 s stops 43 windows at 25 passes with relative residuals of 2.6e-5 … 1.1e-2
/// (median 3.8e-4); repeating all of them cost 40 % more wall time for results that moved by less than
/// their digits. Beyond it a window is no result: c3 at 4e-4 s stopped at 0.18.
inline constexpr double kNearTolerance = 100.0;

/// What a scheme that iterates a window to a tolerance reads of `coupling:` (the implicit schemes,
/// implicit_iteration.cpp): coupling.max_iterations, tolerance, require_convergence, extrapolation,
/// acceleration.
struct IterationSettings {
  int maxIterations = 50;
  struct Tolerance {
    double absolute, relative;
  };
  double absoluteTolerance = 1e-12, relativeTolerance = 1e-8;
  /// coupling.tolerance.fields: an exchanged field's own test (field name → tolerances), else the above.
  std::map<std::string, Tolerance> fieldTolerances;
  bool requireConvergence = false;  ///< a window at max_iterations is an error (else reported)
  /// The first iteration of a window starts from the last window's result (0) or from the line through
  /// the last two (1).
  int extrapolationOrder = 0;
  AccelerationSpec acceleration = defaultAcceleration();
};

class Scheme {
 public:
  virtual ~Scheme() = default;
  /// Runs one window; `firstFlags` go with each participant's first ADVANCE of it (write-checkpoint).
  virtual WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) = 0;
  /// Weak schemes exchange once per window, with no iteration: their lag does work at the interface.
  virtual bool strong() const = 0;
  /// What it carries from window to window (acceleration history, extrapolation), written or read.
  virtual void archive(common::StateArchive&) {}
  /// After window(): the window stands (the run goes on from its end) …
  virtual void acceptWindow(SchemeHost&, const WindowOutcome&) {}
  /// … or it is void (it diverged or did not converge and is repeated shorter from its start): forget
  /// what its iterations taught, keep what earlier windows did.
  virtual void abandonWindow() {}
  /// For the summary's cost: "implicit scheme, iqn_ils acceleration".
  virtual std::string describe() const = 0;
  /// What the scheme measured, for the summary (the bridging domain's energy fractions).
  virtual void report(common::Summary&) const {}
  /// A scheme that iterates a window to a tolerance: its settings, for the coupler's diagnoses (which
  /// fix to give); nullptr for one that does not.
  virtual const IterationSettings* iteration() const { return nullptr; }
};

/// Meshes whose fields a scheme sends and reads itself, not through `exchanges` (none for most schemes).
std::vector<std::string> schemeMeshes(const CouplingSpec& spec);

/// Reads the keys of the scheme `spec.scheme` names (coupling.scheme, read before) from `coupling`: sets
/// spec.makeScheme, and returns the entries of coupling.tolerance.fields, to be checked against the
/// exchanges once those are read.
std::vector<std::pair<std::string, common::Config>> readSchemeKeys(const common::Config& coupling, CouplingSpec& spec);
std::vector<std::string> schemeNames();

}  // namespace cosim
