// Implicit serial (strong, Gauss–Seidel): the window is repeated until the interface converges. The
// fixed point x̃ is what the last participant writes for the others (its read outputs, concatenated);
// each iteration runs every participant in order from the window's checkpoint, compares H(x̃) with x̃
// (absolute and relative residual) and lets the acceleration propose the next x̃ (DESIGN.md §6).
#include <chrono>
#include <cmath>

#include "common/log.hpp"
#include "common/state_archive.hpp"
#include "cosim/protocol.hpp"
#include "schemes.hpp"

namespace cosim {
namespace {
namespace pr = protocol;

class ImplicitSerial final : public Scheme {
 public:
  ImplicitSerial(const CouplingSpec& spec, const SchemeHost& host)
      : spec_(spec),
        acceleration_(makeAcceleration(spec.acceleration, spec.accelerationParams)),
        last_(host.participants() - 1),
        fixed_(host.readFields(last_)) {}

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    WindowOutcome out;
    double firstResidual = 0.0;
    const auto maxIterations = static_cast<std::uint32_t>(spec_.maxIterations);
    std::uint32_t k = 0;
    for (k = 0; k < maxIterations; ++k) {
      host.setIteration(k);
      const std::uint32_t flags = k == 0 ? pr::kSaveCheckpoint | firstFlags : pr::kRestoreCheckpoint;
      if (k == 0 && spec_.extrapolationOrder == 1 && !previousEnd_.empty() && previousEnd_.size() == lastEnd_.size()) {
        // Start the window from x(t) + (x(t) − x(t − Δt)): the error of the first guess drops from
        // O(Δt) to O(Δt²), so a smooth window can converge at its first iteration.
        std::vector<double> predicted(lastEnd_.size());
        for (std::size_t i = 0; i < predicted.size(); ++i) predicted[i] = 2.0 * lastEnd_[i] - previousEnd_[i];
        feed(host, predicted);
      }
      // x̃: what the first participant is fed from the last one this iteration (last's output space).
      std::vector<double> input = gather(host);
      for (std::size_t p = 0; p < host.participants(); ++p) {
        host.send(p, flags);
        const std::size_t one[] = {p};
        host.collect(one);
        // The last participant's outputs reach the others at the next iteration: mapped once, after the
        // acceleration (feed) or at the window's end, not also as they came.
        if (p != last_) host.deliver(p);
      }
      const std::vector<double> output = gather(host);
      if (input.size() != output.size()) input.assign(output.size(), 0.0);  // first window: nothing fed yet
      double rr = 0.0, hh = 0.0;
      for (std::size_t i = 0; i < output.size(); ++i) {
        rr += (output[i] - input[i]) * (output[i] - input[i]);
        hh += output[i] * output[i];
      }
      out.residual = std::sqrt(rr);
      out.relative = hh > 0 ? out.residual / std::sqrt(hh) : out.residual;
      if (k == 0) firstResidual = out.residual;
      // An iteration that diverges is stopped here, before its values reach a participant or a file.
      // (Growth alone is not enough: before a wave reaches the interface the residuals are round-off.)
      if (!std::isfinite(out.residual) ||
          (k >= 3 && out.residual > 1e3 * firstResidual && out.relative > 0.5 && out.residual > spec_.absoluteTolerance))
        host.iterationDiverged(firstResidual, out.residual, k);
      log_->debug("window {} iteration {}: residual {:.3e} (relative {:.3e})", host.window(), k, out.residual,
                  out.relative);
      out.converged = out.residual <= spec_.absoluteTolerance || out.relative <= spec_.relativeTolerance;
      if (out.converged || k + 1 == maxIterations) {
        host.deliver(last_);
        break;
      }
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<double> next(output.size());
      acceleration_->next(input, output, next);
      host.addAccelerationSeconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      feed(host, next);
    }
    out.iterations = k + 1;
    previousEnd_.swap(lastEnd_);
    lastEnd_ = gather(host);
    if (out.converged) acceleration_->converged();
    else acceleration_->unconverged();
    return out;
  }

  bool strong() const override { return true; }
  std::string describe() const override { return "implicit scheme, " + spec_.acceleration + " acceleration"; }

  void archive(common::StateArchive& a) override {
    a.io("previous_end", previousEnd_), a.io("last_end", lastEnd_);
    auto scope = a.scope("acceleration");
    acceleration_->archive(a);
  }

 private:
  // x̃: the fixed fields of the last participant's outputs, concatenated.
  std::vector<double> gather(SchemeHost& host) const {
    std::vector<double> v;
    auto& outputs = host.outputs(last_);
    for (const auto& f : fixed_)
      if (const auto it = outputs.find(f); it != outputs.end()) v.insert(v.end(), it->second.begin(), it->second.end());
    return v;
  }
  // Puts x̃ back into those outputs and maps it to their readers.
  void feed(SchemeHost& host, const std::vector<double>& v) const {
    std::size_t offset = 0;
    auto& outputs = host.outputs(last_);
    for (const auto& f : fixed_) {
      auto& values = outputs[f];
      std::copy(v.begin() + static_cast<std::ptrdiff_t>(offset),
                v.begin() + static_cast<std::ptrdiff_t>(offset + values.size()), values.begin());
      offset += values.size();
    }
    host.deliver(last_);
  }

  const CouplingSpec& spec_;
  std::unique_ptr<Acceleration> acceleration_;
  std::size_t last_;
  std::vector<std::string> fixed_;
  std::vector<double> previousEnd_, lastEnd_;  // x̃ at the ends of the last two windows (extrapolation)
  std::shared_ptr<spdlog::logger> log_ = common::logger("cosim");
};
}  // namespace

std::unique_ptr<Scheme> makeImplicitSerial(const CouplingSpec& spec, const SchemeHost& host) {
  return std::make_unique<ImplicitSerial>(spec, host);
}
}  // namespace cosim
