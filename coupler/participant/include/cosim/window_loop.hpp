#pragma once
// The participant side's window loop (libcosim): the one place where a coupled solver's windows are
// committed, checkpoints saved and restored, windows subcycled, inputs interpolated per substep, outputs
// reduced per window, results timed and errors reported. A solver executable builds its adapter
// (cosim/coupled_solver.hpp) and calls runWindowLoop.

#include <cstdint>
#include <exception>
#include <functional>
#include <string>

#include "cosim/coupled_solver.hpp"
#include "cosim/participant.hpp"

namespace cosim {

struct WindowLoopReport {
  std::int64_t windows = 0;     ///< windows committed
  std::int64_t iterations = 0;  ///< window iterations advanced (repeats included)
  std::int64_t substeps = 0;    ///< substeps stepped (repeats included)
};

struct WindowLoopOptions {
  /// Names the solver in an ERROR sent to the coupler ("LABEL: what").
  std::string label;
  /// Whether an exception from the solver is a divergence (ERROR's instability flag).
  std::function<bool(const std::exception&)> diverged;
  /// Writes an on-disk checkpoint of the state at the coming window's start: the solver's and the loop's
  /// `state`, to `path`, atomically (the file appears whole or not at all). Empty: the participant offers
  /// no on-disk checkpoints.
  std::function<void(const std::string& path, const WindowLoopState& state)> writeCheckpoint;
  /// A restarted run: the loop's state read from the checkpoint (its fields must be the kLinear reads
  /// the solver declares, in order). Empty on a fresh run.
  WindowLoopState resume;
};

/// Declares the adapter's interface, says HELLO and drives `solver` until FINALIZE. A CouplingError
/// (the coupler stopped the run or is gone) propagates as it is. Any other exception from the solver is
/// first reported to the coupler as ERROR and then rethrown; so is an adapter that breaks the contract of
/// cosim/coupled_solver.hpp (std::logic_error: a field read or written that it did not declare, a kMean
/// output not written in every substep, an output not written at all) and a resume state of other
/// fields (std::invalid_argument).
WindowLoopReport runWindowLoop(CouplingChannel& channel, CoupledSolver& solver, const WindowLoopOptions& options);

}  // namespace cosim
