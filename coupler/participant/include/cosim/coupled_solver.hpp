#pragma once
// What a solver library provides to take part in a coupled run: a coupled adapter (CoupledSolver) that
// the window loop of libcosim (cosim/window_loop.hpp) drives. Header only and free of ZeroMQ, so a
// solver library can implement it without linking libcosim (no ZeroMQ in solver
// libraries); its executable links libcosim and runs the loop.
//
// The loop, for every ADVANCE: a new window index commits the previous window (it is final); an on-disk
// checkpoint if asked (restart: the solver's state and the loop's, at this window's start); restore (a
// repeated iteration) or save (a window's first iteration of an implicit scheme); then the window's
// substeps: beginWindow, step once per substep, endWindow; RESULT with the outputs reduced as declared.
// After FINALIZE the last window is committed.
//
// Subcycling belongs to the loop: it splits a window into the fewest equal substeps no longer than the
// solver's maxSubstep(), gives each substep its inputs where the solver asks for them (interpolated in
// time as each read declared) and makes each output of a window from its substeps' (the mean, or the
// last, as each write declared). A scheme that runs several participants at once (implicit parallel) or
// exchanges per common time step (bridging domain: a window is one common step, so one substep) changes
// what the coupler sends and when, not this sequence.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace cosim {

struct Window {
  std::uint64_t index = 0;
  std::uint32_t iteration = 0;
  double time = 0.0;  ///< window start [s]
  double dt = 0.0;    ///< window length [s]
  bool saveCheckpoint = false, restoreCheckpoint = false, writeOutput = false;
  /// Not empty: write the state at this window's start to this file (restart) before advancing.
  std::string checkpoint;
};

/// How an input reaches a window's substeps.
enum class Interpolation {
  kHold,    ///< the coupler's value, at any point of the window
  kLinear,  ///< linear in time, from its value at the window start (the last committed window's end value;
            ///< before the first window, the initial value declared) to the coupler's value at the window end
};

/// How a window's output is made from its substeps' values.
enum class Reduction {
  kEnd,   ///< the last value written in the window (in a step or in endWindow)
  kMean,  ///< the mean of the values written in each of its substeps (a force: impulse / window length)
};

/// Declaring the interface (before the handshake). Meshes are node coordinates (x, y, z per node) and
/// triangles (0-based node indices, may be empty); fields are `components` values per node, node-major.
class InterfaceDeclaration {
 public:
  virtual ~InterfaceDeclaration() = default;
  virtual void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::uint32_t> triangles) = 0;
  /// Cells of a volume or a line on a declared mesh (a bridging domain's overlap, which the coupler
  /// interpolates in): `nodesPerCell` 4 (tetrahedra) or 2 (segments), 0-based node indices.
  virtual void addCells(const std::string& mesh, int nodesPerCell, std::span<const std::uint32_t> cells) = 0;
  /// `initial`: a kLinear input's value at the start of the run (empty: zero), where the solver's
  /// interface is before the coupler sends anything.
  virtual void addRead(const std::string& mesh, const std::string& field, int components,
                       Interpolation interpolation = Interpolation::kHold, std::span<const double> initial = {}) = 0;
  virtual void addWrite(const std::string& mesh, const std::string& field, int components,
                        Reduction reduction = Reduction::kEnd) = 0;
};

/// A participant's side of a bridging domain (the coupler's `bridging` scheme, docs/validation/bridging.md):
/// the overlap as mesh `bridge` — the continuum's nodes with its elements there as cells (`nodesPerCell`
/// 2, 3 or 4), or the particles' centres with no cells (0) — on which it writes, at each window's end, the
/// velocity (3), the weighted mass (1) and its energy weight (1; the continuum's may run beyond [0, 1] at
/// nodes outside the zone, the linear function the coupler interpolates and clamps), and reads the multiplier force held over
/// the window (3); and the one-node mesh `bridge_energy`, on which it writes its mechanical energy (its
/// weighted share in the overlap) and what it dissipated less the work of its loads other than the
/// multipliers (their sum over both sides stays the initial energy), and reads the coupled system's energy `scale` [J]. Its step is leapfrog's
/// kick-drift: a force held over a step changes the velocity by force × step / mass, by half that in the
/// run's first step (the half kick from the velocities at t = 0).
/// Particles that rotate (`spin`) also write their angular velocity `spin` (3) and weighted moment of
/// inertia `inertia` (1, β I) and read the multiplier torque `torque` (3), held over the step like the
/// force: the coupler then makes them spin with a continuum of tetrahedra, ω = ½ ∇ × v. The continuum also
/// writes on `bridge_energy` its zone's `shape` (1: 0 linear, 1 cubic; common/bridging_zone.hpp), which
/// the coupler applies to the interpolated linear function before it checks α + β = 1.
inline void declareBridge(InterfaceDeclaration& io, std::span<const double> nodes, int nodesPerCell,
                          std::span<const std::uint32_t> cells, bool spin = false) {
  io.addMesh("bridge", nodes, nodesPerCell == 3 ? cells : std::span<const std::uint32_t>());
  if (nodesPerCell == 2 || nodesPerCell == 4) io.addCells("bridge", nodesPerCell, cells);
  io.addRead("bridge", "force", 3);
  io.addWrite("bridge", "velocity", 3);
  io.addWrite("bridge", "mass", 1);
  io.addWrite("bridge", "weight", 1);
  if (spin) {
    io.addRead("bridge", "torque", 3);
    io.addWrite("bridge", "spin", 3);
    io.addWrite("bridge", "inertia", 1);
  }
  const double origin[3] = {0, 0, 0};
  io.addMesh("bridge_energy", origin, {});
  io.addWrite("bridge_energy", "energy", 2);
  io.addRead("bridge_energy", "scale", 1);
  if (nodesPerCell != 0) io.addWrite("bridge_energy", "shape", 1);
}

/// The interface inside a window, as the loop presents it to the adapter.
class WindowIo {
 public:
  virtual ~WindowIo() = default;
  /// An input at the point `at` of the window (0 its start, 1 its end; a substep's begin or end). The
  /// span stays valid until the next read of the same field (rate(): until its next rate()).
  virtual std::span<const double> read(const std::string& mesh, const std::string& field, double at = 1.0) = 0;
  /// A kLinear input's rate over the window, (end − start) / window length [field unit / s].
  virtual std::span<const double> rate(const std::string& mesh, const std::string& field) = 0;
  /// An output's value now. kMean: once in every step; kEnd: in any step or in endWindow, the last counts.
  virtual void write(const std::string& mesh, const std::string& field, std::span<const double> data) = 0;
};

/// One substep of a window iteration.
struct Substep {
  std::int64_t index = 0, count = 1;
  double dt = 0.0;                ///< its length [s]
  double begin = 0.0, end = 1.0;  ///< where it starts and ends, as fractions of the window
};

/// Subcycling a window of length `window` with steps of at most `step` (0: one step): equal substeps (a
/// kMean output weighs each by 1/count).
struct Substeps {
  Substeps(double window, double step)
      : count(step > 0 ? std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(window / step - 1e-9))) : 1),
        dt(window / static_cast<double>(count)) {}
  std::int64_t count;
  double dt;
  Substep operator[](std::int64_t s) const {
    const double n = static_cast<double>(count);
    return {s, count, dt, static_cast<double>(s) / n, static_cast<double>(s + 1) / n};
  }
};

/// What the window loop carries from one window to the next: the window-start value of every kLinear
/// input. Part of an on-disk checkpoint (its archive() fits common::StateArchive).
struct WindowLoopState {
  std::vector<std::string> fields;           ///< "mesh/field", in declaration order
  std::vector<std::vector<double>> start;    ///< each one's value at the window start
  template <class Archive>
  void archive(Archive& a) {
    a.io("fields", fields);
    a.io("start", start);
  }
};

class CoupledSolver {
 public:
  virtual ~CoupledSolver() = default;
  /// Interface meshes, reads and writes (before the handshake).
  virtual void declare(InterfaceDeclaration& io) = 0;
  /// Keeps the state at the start of a window in memory (an implicit scheme may repeat the window).
  virtual void save() = 0;
  /// Returns to the state save() kept.
  virtual void restore() = 0;
  /// The longest step the solver takes inside a window [s]; 0: a window is one step (a static solve).
  virtual double maxSubstep() const { return 0.0; }
  /// Before the first substep of a window iteration starting at w.time (what holds for the whole
  /// iteration: the step length, a kLinear input's rate).
  virtual void beginWindow(const Window& w, const Substeps& sub, WindowIo& io) { (void)w, (void)sub, (void)io; }
  /// One substep: read the inputs where the solver needs them, advance by s.dt, write the outputs.
  virtual void step(const Window& w, const Substep& s, WindowIo& io) = 0;
  /// After the last substep: kEnd outputs not written in the steps, the iteration's record.
  virtual void endWindow(const Window& w, WindowIo& io) { (void)w, (void)io; }
  /// The window advanced last is final (the coupler moved on, or the run ends): record it.
  virtual void commit() = 0;
  /// The largest stable step of the solver, reported with each result [s] (0: none).
  virtual double stableStep() const { return 0.0; }
};

}  // namespace cosim
