#pragma once
// Accelerations of the implicit coupling's fixed-point iteration. In each coupling
// window the coupler iterates x̃ → H(x̃) (for DEM–FEM: interface displacements through both solvers);
// the residual is r = H(x̃) − x̃. An Acceleration turns (x̃_k, H(x̃_k)) into the next input x̃_{k+1}.
//
// Call order per window: next() for every iteration, then converged() once the window is accepted
// (IQN-ILS keeps that window's columns for reuse) or unconverged() when it ran out of iterations,
// then the next window.
// One source file per method, chosen by name: constant, aitken, iqn_ils.

#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "cosim/qr_filter.hpp"

namespace common {
class Config;
class StateArchive;
}

namespace cosim {

class Acceleration {
 public:
  virtual ~Acceleration() = default;
  virtual std::string name() const = 0;
  /// The next input from the current input and its output. `next` may alias nothing.
  virtual void next(std::span<const double> input, std::span<const double> output, std::span<double> next) = 0;
  /// Per-entry weights of the residual in the norms the method minimises or compares (a stacked vector
  /// of fields of different units: forces and displacements); empty, or never called: all ones. Set
  /// before next(); the method keeps its history unweighted, so the weights may change every call.
  void setWeights(std::span<const double> w) { weights_.assign(w.begin(), w.end()); }
  /// The length of the window under way [s] (adaptive windows): what a method keeps from a window
  /// belongs to its length (IQN-ILS reuses only windows of the same length). Set before next().
  void setWindowSize(double dt) { windowSize_ = dt; }
  /// The window converged: reset per-window state (keep what the method reuses).
  virtual void converged() = 0;
  /// The window ended at the iteration limit: reset per-window state and keep nothing for reuse (its
  /// iterates, and the older windows' model that led there, would steer the next window astray).
  virtual void unconverged() { converged(); }
  /// The window diverged and is repeated shorter from its start: its iterates are void; what the method
  /// kept from earlier windows may stay (IQN-ILS keeps its reused columns).
  virtual void abandon() { unconverged(); }
  /// What it carries from window to window (IQN-ILS: the reused windows' columns), written into `a` or
  /// read from it: a restarted run accelerates as the uninterrupted one. Called between windows.
  virtual void archive(common::StateArchive& a) = 0;

 protected:
  std::vector<double> weights_;
  double windowSize_ = 0.0;
};

struct AccelerationParams {
  double relaxation = 0.5;    ///< constant ω, and the first step of Aitken and IQN-ILS
  int reusedWindows = 8;      ///< IQN-ILS: windows whose columns are reused
  int maxColumns = 100;       ///< IQN-ILS: columns kept at most
  double filter = 1e-4;       ///< IQN-ILS: the QR filter's limit (cosim/qr_filter.hpp)
  QrFilter filterType = QrFilter::kQr2;  ///< IQN-ILS: which filter
  /// IQN-ILS across a changing active set (the entries where H(x̃) is not exactly zero: the nodes in
  /// contact of a force field): keep every column as it is, mask the columns to the entries active now,
  /// or drop every column when the set changes.
  enum class ActiveSet { kKeep, kMask, kDrop } activeSet = ActiveSet::kKeep;
};

std::unique_ptr<Acceleration> makeAcceleration(const std::string& name, const AccelerationParams& params);
std::vector<std::string> accelerationNames();
/// Reads `coupling.acceleration` (type and the keys of that type only: another type's key is unknown
/// there, exit 2) into `params`; returns the type.
std::string readAcceleration(const common::Config& acceleration, AccelerationParams& params);

}  // namespace cosim
