#pragma once
// The energy a coupling creates or destroys at an interface (a coupled run that went
// wrong says so). For a pair of exchanges — a force from participant A to B, B's displacement back to A
// on the same interface — the interface forces do work on both sides:
//   W_A = Σ_windows f_A · Δu_A   (A's output force against the wall motion A was fed),
//   W_B = Σ_windows f_B · Δu_B   (the force B was fed along B's own motion).
// With a consistent displacement map M and its transpose for the force (f_B = Mᵀ f_A), f_B·u_B =
// f_A·(M u_B) = f_A·u_A: a converged coupling gives W_A = W_B to its tolerance. A weak scheme feeds A a
// displacement one window late (or B a force that no longer matches its motion) and W_B − W_A is energy
// that no physics made: rockfall c1 under explicit_serial ended "ok" with the coupled energy balance
// off by 145 % (docs/stability.md).
//
// Call order: window() once per final window, with the data that window used. Units SI.

#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include "common/state_archive.hpp"

namespace cosim {

class InterfaceEnergy {
 public:
  /// Adds one window: A's output force and the displacement A advanced with, the force B advanced with
  /// and B's output displacement (each the interface's nodes × components, on its own mesh). The first
  /// window only sets the starting displacements. Returns what it added to W_A and W_B [J].
  std::pair<double, double> window(std::span<const double> forceA, std::span<const double> displacementA, std::span<const double> forceB,
              std::span<const double> displacementB);
  double workA() const { return workA_; }  ///< W_A [J]
  double workB() const { return workB_; }  ///< W_B [J]
  /// W_B − W_A: energy the coupling created (> 0) or destroyed [J]
  double mismatch() const { return workB_ - workA_; }
  /// The largest |W_A|, |W_B| so far: the energy that crossed the interface [J]
  double scale() const { return scale_; }


  void archive(common::StateArchive& a) {
    a.io("last_a", lastA_), a.io("last_b", lastB_), a.io("started", started_), a.io("work_a", workA_);
    a.io("work_b", workB_), a.io("scale", scale_);
  }

 private:
  std::vector<double> lastA_, lastB_;
  bool started_ = false;
  double workA_ = 0.0, workB_ = 0.0, scale_ = 0.0;
};

}  // namespace cosim
