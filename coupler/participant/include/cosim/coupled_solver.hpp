#pragma once
// What a solver library provides to take part in a coupled run: a coupled adapter (CoupledSolver) that
// the window loop of libcosim (cosim/window_loop.hpp) drives. Header only and free of ZeroMQ, so a
// solver library can implement it without linking libcosim (DESIGN.md §2: no ZeroMQ in solver
// libraries); its executable links libcosim and runs the loop.
//
// The loop, for every ADVANCE: a new window index commits the previous window (it is final); an on-disk
// checkpoint if asked (restart: writeCheckpoint, the state at this window's start); restore (a repeated
// iteration) or save (a window's first iteration of an implicit scheme); advance; RESULT.
// After FINALIZE the last window is committed. A scheme that runs several participants at once
// (implicit parallel) or exchanges per common time step (bridging domain) changes what the coupler
// sends and when, not this sequence: the adapter sees windows, iterations and checkpoints either way.

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

/// The interface data of a coupled run as the adapter sees it: declared before the run, read and written
/// in each window iteration. Meshes are node coordinates (x, y, z per node) and triangles (0-based node
/// indices, may be empty); fields are `components` values per node, node-major.
class InterfaceIo {
 public:
  virtual ~InterfaceIo() = default;
  virtual void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::uint32_t> triangles) = 0;
  virtual void addRead(const std::string& mesh, const std::string& field, int components) = 0;
  virtual void addWrite(const std::string& mesh, const std::string& field, int components) = 0;
  virtual std::span<const double> read(const std::string& mesh, const std::string& field) const = 0;
  virtual void write(const std::string& mesh, const std::string& field, std::span<const double> data) = 0;
};

class CoupledSolver {
 public:
  virtual ~CoupledSolver() = default;
  /// Interface meshes, reads and writes (before the handshake).
  virtual void declare(InterfaceIo& io) = 0;
  /// Keeps the state at the start of a window in memory (an implicit scheme may repeat the window).
  virtual void save() = 0;
  /// Returns to the state save() kept.
  virtual void restore() = 0;
  /// One iteration of window `w`: read the inputs, advance from w.time by w.dt, write every output.
  virtual void advance(const Window& w, InterfaceIo& io) = 0;
  /// The window advanced last is final (the coupler moved on, or the run ends): record it.
  virtual void commit() = 0;
  /// The largest stable step of the solver, reported with each result [s] (0: none).
  virtual double stableStep() const { return 0.0; }
  /// Whether writeCheckpoint() works: the coupler asks for on-disk checkpoints (a restartable run,
  /// coupling.checkpoint_interval) only of participants that can write them.
  virtual bool checkpoints() const { return false; }
  /// Writes everything a restarted run needs to continue from the coming window (the windows before
  /// are committed) to `path`, atomically (the file appears whole or not at all). The solver's
  /// executable reads it back when started with --restart PATH.
  virtual void writeCheckpoint(const std::string& path) { (void)path; }
};

/// Subcycling a window of length `window` with steps of at most `step`: count equal substeps.
struct Substeps {
  Substeps(double window, double step)
      : count(std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(window / step - 1e-9)))),
        dt(window / static_cast<double>(count)) {}
  std::int64_t count;
  double dt;
  /// Where substep s starts and ends as a fraction of the window (linear interpolation of an input).
  double begin(std::int64_t s) const { return static_cast<double>(s) / static_cast<double>(count); }
  double end(std::int64_t s) const { return static_cast<double>(s + 1) / static_cast<double>(count); }
};

}  // namespace cosim
