#include "coupling_record.hpp"

#include <algorithm>

#include "common/h5_writer.hpp"
#include "common/results_file.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "window_control.hpp"

namespace cosim {

CouplingRecord::CouplingRecord(const Connections& peers) : peers_(peers) {}
CouplingRecord::~CouplingRecord() = default;

void CouplingRecord::open(const std::filesystem::path& outDir, common::StateArchive* resume) {
  if (resume) {
    common::H5Extent extent;
    resume->io(common::kResultsExtent, extent);
    h5_ = std::make_unique<common::H5Writer>(outDir / "coupling.h5", extent);
  } else {
    h5_ = std::make_unique<common::H5Writer>(outDir / "coupling.h5");
  }
  std::vector<std::string> cols{"iterations", "residual",       "residual_relative", "converged",
                                "mapping_s",  "acceleration_s", "window_s"};
  for (const auto& p : peers_.all()) cols.insert(cols.end(), {p.spec.name + "_solver_s", p.spec.name + "_wait_s"});
  h5_->addSeries("windows", cols);
}

void CouplingRecord::begin(double mappingSeconds) {
  mapping0_ = mappingSeconds, acceleration0_ = accelerationSeconds_;
  solver0_.clear(), wait0_.clear();
  for (const auto& p : peers_.all()) solver0_.push_back(p.solverSeconds), wait0_.push_back(p.waitSeconds);
}

void CouplingRecord::end(const WindowOutcome& w, double end, double size, double mappingSeconds) {
  if (!w.converged) ++unconverged_;
  totalIterations_ += w.iterations;
  maxResidual_ = std::max(maxResidual_, w.residual);
  recentMask_ = ((recentMask_ << 1) | (w.converged ? 0u : 1u)) & ((1ull << kRecentWindows) - 1);
  recentUnconverged_ = __builtin_popcountll(recentMask_);
  lastResidual_ = w.residual, lastRelative_ = w.relative;
  std::vector<double> row{static_cast<double>(w.iterations), w.residual,  w.relative, w.converged ? 1.0 : 0.0,
                          mappingSeconds - mapping0_, accelerationSeconds_ - acceleration0_, size};
  const auto& all = peers_.all();
  for (std::size_t i = 0; i < all.size(); ++i)
    row.insert(row.end(), {all[i].solverSeconds - solver0_[i], all[i].waitSeconds - wait0_[i]});
  h5_->append("windows", end, row);
  if (rows_++ % 16 == 0) h5_->flush();
}

void CouplingRecord::flush() {
  if (h5_) h5_->flush();
}

void CouplingRecord::report(common::Summary& summary, std::uint64_t windows, const WindowControl& control) const {
  summary.setSteps(static_cast<std::int64_t>(windows));
  summary.set("windows", static_cast<std::int64_t>(windows));
  summary.set("mean_coupling_iterations",
              static_cast<double>(totalIterations_) / static_cast<double>(std::max<std::uint64_t>(windows, 1)));
  summary.set("unconverged_windows", unconverged_);
  summary.set("max_final_residual", maxResidual_);
  summary.set("refused_connections", static_cast<std::int64_t>(peers_.router().refusals().size()));
  summary.set("windows_halved", control.halvings());
  summary.set("smallest_window", control.smallest());
}

void CouplingRecord::archive(common::StateArchive& a) {
  a.io("total_iterations", totalIterations_);
  a.io("unconverged", unconverged_), a.io("max_residual", maxResidual_), a.io("recent_mask", recentMask_);
  a.io("recent_unconverged", recentUnconverged_), a.io("last_residual", lastResidual_);
  a.io("last_relative", lastRelative_), a.io("acceleration_s", accelerationSeconds_);
}

}  // namespace cosim
