#pragma once
// The participant side's window loop (libcosim): the one place where a coupled solver's windows are
// committed, checkpoints saved and restored, results timed and errors reported. A solver executable
// builds its adapter (cosim/coupled_solver.hpp) and calls runWindowLoop; DESIGN.md §4.

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
};

/// Declares the adapter's interface, says HELLO and drives `solver` until FINALIZE. A CouplingError
/// (the coupler stopped the run or is gone) propagates as it is. Any other exception from the solver is
/// first reported to the coupler as ERROR ("LABEL: what", with the diverged flag if `diverged(e)`)
/// and then rethrown.
WindowLoopReport runWindowLoop(Participant& p, CoupledSolver& solver, const std::string& label,
                               const std::function<bool(const std::exception&)>& diverged = {});

}  // namespace cosim
