#include "cosim/window_loop.hpp"

#include <chrono>

namespace cosim {

WindowLoopReport runWindowLoop(Participant& p, CoupledSolver& solver, const std::string& label,
                               const std::function<bool(const std::exception&)>& diverged) {
  WindowLoopReport report;
  try {
    solver.declare(p);
    if (solver.checkpoints()) p.offerCheckpoints();
    p.initialize();
    Window w;
    bool advanced = false;
    std::uint64_t current = 0;
    while (p.nextWindow(w)) {
      const auto start = std::chrono::steady_clock::now();
      if (advanced && w.index != current) {  // a new window: the previous one is final
        solver.commit();
        ++report.windows;
      }
      current = w.index;
      if (!w.checkpoint.empty()) solver.writeCheckpoint(w.checkpoint);
      if (w.restoreCheckpoint) solver.restore();
      if (w.saveCheckpoint) solver.save();
      solver.advance(w, p);
      advanced = true;
      ++report.iterations;
      p.complete(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), solver.stableStep());
    }
    if (advanced) {
      solver.commit();
      ++report.windows;
    }
  } catch (const CouplingError&) {
    throw;
  } catch (const std::exception& e) {
    p.fail(label + ": " + e.what(), diverged && diverged(e));
    throw;
  }
  return report;
}

}  // namespace cosim
