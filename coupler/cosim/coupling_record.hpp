#pragma once
// What a coupled run records of its windows: coupling.h5's `windows` series (iterations, residuals,
// timings per participant, the window's length), the counters the summary reports and a failure's
// diagnosis cites (unconverged windows, the largest final residual, the last windows' convergence).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "connections.hpp"
#include "schemes/scheme.hpp"

namespace common {
class H5Writer;
class StateArchive;
class Summary;
}  // namespace common

namespace cosim {

class WindowControl;

class CouplingRecord {
 public:
  /// Of the last kRecentWindows windows, how many did not converge: the evidence when a participant
  /// then diverges.
  static constexpr int kRecentWindows = 20;

  explicit CouplingRecord(const Connections& peers);
  ~CouplingRecord();
  /// coupling.h5 in `outDir`, new, or (restart) cut back to the extent `resume` holds.
  void open(const std::filesystem::path& outDir, common::StateArchive* resume);
  common::H5Writer& file() { return *h5_; }

  void addAccelerationSeconds(double s) { accelerationSeconds_ += s; }
  double accelerationSeconds() const { return accelerationSeconds_; }
  /// Around a window that stands: its start (timings so far), then its outcome, which ended at `end` [s]
  /// and was `size` long.
  void begin(double mappingSeconds);
  void end(const WindowOutcome& w, double end, double size, double mappingSeconds);
  void flush();

  /// Passes (coupling iterations) of every window so far.
  std::int64_t passes() const { return totalIterations_; }
  int recentUnconverged() const { return recentUnconverged_; }
  double lastResidual() const { return lastResidual_; }
  double lastRelative() const { return lastRelative_; }

  /// The summary of the first `windows` windows (also of a run that failed: how far it got).
  void report(common::Summary& summary, std::uint64_t windows, const WindowControl& control) const;
  void archive(common::StateArchive& a);

 private:
  const Connections& peers_;
  std::unique_ptr<common::H5Writer> h5_;
  std::int64_t totalIterations_ = 0, unconverged_ = 0;
  double maxResidual_ = 0.0;
  std::uint64_t recentMask_ = 0;
  int recentUnconverged_ = 0;
  double lastResidual_ = 0.0, lastRelative_ = 0.0;
  double accelerationSeconds_ = 0.0;
  // At the window's start.
  double mapping0_ = 0.0, acceleration0_ = 0.0;
  std::vector<double> solver0_, wait0_;
  std::uint64_t rows_ = 0;
};

}  // namespace cosim
