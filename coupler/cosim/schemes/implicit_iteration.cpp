#include "implicit_iteration.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include <fmt/ranges.h>

#include "common/config.hpp"
#include "common/log.hpp"
#include "common/state_archive.hpp"
#include "cosim/protocol.hpp"
#include "schemes.hpp"

namespace cosim {
namespace pr = protocol;
using common::Config;
using common::Interval;

namespace {
IterationSettings readIterationKeys(const Config& c, CouplingSpec& spec, FieldToleranceKeys& fieldTolerances) {
  spec.minWindow = c.get("min_time_window", spec.window / 16, Interval{0.0, spec.window, false, true});
  spec.growAfter = c.get<int>("grow_after", 20);
  if (spec.growAfter < 0) c.failAt("grow_after", "must be 0 (a halved window never grows back) or a number of windows.");
  IterationSettings s;
  s.maxIterations = c.get<int>("max_iterations", 50);
  if (s.maxIterations < 1) c.failAt("max_iterations", "must be at least 1.");
  if (Config tol = c.child("tolerance")) {
    s.absoluteTolerance = tol.get("absolute", 1e-12, Interval::nonNegative());
    s.relativeTolerance = tol.get("relative", 1e-8, Interval::nonNegative());
    if (Config fields = tol.child("fields"))
      for (const auto& [name, f] : fields.entries()) {
        s.fieldTolerances[name] = {f.get("absolute", s.absoluteTolerance, Interval::nonNegative()),
                                   f.get("relative", s.relativeTolerance, Interval::nonNegative())};
        fieldTolerances.emplace_back(name, f);
      }
  }
  s.requireConvergence = c.get<bool>("require_convergence", false);
  s.extrapolationOrder = c.choice("extrapolation", {"constant", "linear"}, "constant") == "linear" ? 1 : 0;
  if (Config acc = c.child("acceleration")) s.acceleration = readAcceleration(acc);
  return s;
}
}  // namespace

SchemeKeys readIterating(const Config& c, CouplingSpec& spec, IterationMake make) {
  SchemeKeys keys;
  IterationSettings settings = readIterationKeys(c, spec, keys.fieldTolerances);
  keys.make = [settings, make](const CouplingSpec&, const SchemeHost& host) { return make(settings, host); };
  return keys;
}

ImplicitIteration::ImplicitIteration(const IterationSettings& settings, std::vector<Block> blocks, std::string name,
                                     Pass pass)
    : settings_(settings),
      acceleration_(settings.acceleration.build()),
      blocks_(std::move(blocks)),
      name_(std::move(name)),
      pass_(std::move(pass)),
      residualSum_(blocks_.size(), 0.0),
      log_(common::logger("cosim")) {
  for (const Block& b : blocks_) {
    if (std::find(owners_.begin(), owners_.end(), b.participant) == owners_.end()) owners_.push_back(b.participant);
    std::optional<std::string> shared;
    bool same = true;
    for (const auto& f : b.fields) {
      const std::string name = f.substr(f.rfind('/') + 1);
      same = same && (!shared || *shared == name);
      shared = name;
    }
    const auto& fields = settings.fieldTolerances;
    const auto own = same && shared ? fields.find(*shared) : fields.end();
    tolerances_.push_back(own != fields.end() ? own->second
                                              : IterationSettings::Tolerance{settings.absoluteTolerance,
                                                                             settings.relativeTolerance});
  }
}

ImplicitIteration::~ImplicitIteration() = default;

std::string ImplicitIteration::describe() const { return name_ + " scheme, " + settings_.acceleration.type + " acceleration"; }

WindowOutcome ImplicitIteration::window(SchemeHost& host, std::uint32_t firstFlags) {
  WindowOutcome out;
  double firstResidual = 0.0;
  const auto maxIterations = static_cast<std::uint32_t>(settings_.maxIterations);
  std::fill(residualSum_.begin(), residualSum_.end(), 0.0);
  acceleration_->setWindowSize(host.windowSize());
  std::vector<double> fieldResidual(blocks_.size());
  std::uint32_t k = 0;
  for (k = 0; k < maxIterations; ++k) {
    host.setIteration(k);
    const std::uint32_t flags = k == 0 ? pr::kSaveCheckpoint | firstFlags : pr::kRestoreCheckpoint;
    if (k == 0 && settings_.extrapolationOrder == 1 && !previousEnd_.empty() && previousEnd_.size() == lastEnd_.size()) {
      // Start the window from x(t) + (x(t) − x(t − Δt)): the error of the first guess drops from O(Δt)
      // to O(Δt²), so a smooth window can converge at its first iteration.
      // After a halving or a doubling the line through the last two ends reaches over this window's length.
      std::vector<double> predicted(lastEnd_.size());
      const double ratio = host.windowSize() / lastSize_;
      if (ratio == 1.0)
        for (std::size_t i = 0; i < predicted.size(); ++i) predicted[i] = 2.0 * lastEnd_[i] - previousEnd_[i];
      else
        for (std::size_t i = 0; i < predicted.size(); ++i)
          predicted[i] = lastEnd_[i] + ratio * (lastEnd_[i] - previousEnd_[i]);
      feed(host, predicted);
    }
    std::vector<double> input = gather(host);  // x̃ as the readers were fed it
    pass_(host, flags);
    const std::vector<double> output = gather(host);  // H(x̃)
    if (input.size() != output.size()) input.assign(output.size(), 0.0);  // first window: nothing fed yet
    // Each block converges on its own: ‖H_b − x̃_b‖ ≤ absolute, or ≤ relative ‖H_b‖. A stacked norm
    // would let a field of large values (forces in N) hide one of small values (displacements in m).
    double rr = 0.0;
    bool converged = true, near = true;
    out.relative = 0.0;
    for (std::size_t b = 0; b < blocks_.size(); ++b) {
      double r2 = 0.0, h2 = 0.0;
      for (std::size_t i = offsets_[b]; i < offsets_[b + 1]; ++i) {
        r2 += (output[i] - input[i]) * (output[i] - input[i]);
        h2 += output[i] * output[i];
      }
      const double r = std::sqrt(r2), relative = h2 > 0 ? r / std::sqrt(h2) : r;
      fieldResidual[b] = r;
      rr += r2;
      out.relative = std::max(out.relative, relative);
      const auto& tol = tolerances_[b];
      converged = converged && (r <= tol.absolute || relative <= tol.relative);
      near = near && (r <= kNearTolerance * tol.absolute || relative <= kNearTolerance * tol.relative);
      if (blocks_.size() > 1)
        log_->debug("window {} iteration {}: {} residual {:.3e} (relative {:.3e})", host.window(), k,
                    fmt::join(blocks_[b].fields, ", "), r, relative);
    }
    out.residual = std::sqrt(rr);
    out.converged = converged;
    out.near = near;
    if (k == 0) firstResidual = out.residual;
    // An iteration that diverges is stopped here, before its values reach a participant or a file.
    // (Growth alone is not enough: before a wave reaches the interface the residuals are round-off.)
    if (!std::isfinite(out.residual) ||
        (k >= 3 && out.residual > 1e3 * firstResidual && out.relative > 0.5 && out.residual > settings_.absoluteTolerance))
      host.iterationDiverged(firstResidual, out.residual, k);
    log_->debug("window {} iteration {}: residual {:.3e} (largest relative {:.3e})", host.window(), k, out.residual,
                out.relative);
    if (out.converged || k + 1 == maxIterations) {
      deliverOwners(host);
      break;
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (blocks_.size() > 1) {
      updateWeights(fieldResidual);
      acceleration_->setWeights(weights_);
    }
    std::vector<double> next(output.size());
    acceleration_->next(input, output, next);
    host.addAccelerationSeconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    feed(host, next);
  }
  out.iterations = k + 1;
  return out;
}

void ImplicitIteration::acceptWindow(SchemeHost& host, const WindowOutcome& w) {
  previousEnd_.swap(lastEnd_);
  lastEnd_ = gather(host);
  lastSize_ = host.windowSize();
  if (w.converged) acceleration_->converged();
  else acceleration_->unconverged();
}

// The residual-sum preconditioner (Mehl et al. 2016, the "residual-sum" preconditioner of preCICE): field f is weighted
// by 1 / Σ_k ‖r_f^k‖ / ‖r^k‖ over this window's iterations k, so every field's weighted residual is of
// order one whatever its unit, and a field that has converged further weighs more. Reset at each
// window's start. A field that has not yet had a residual (the forces before contact) gets the largest
// weight of the others, the least that keeps its columns from being ignored once it does.
void ImplicitIteration::updateWeights(const std::vector<double>& fieldResidual) {
  double total = 0.0;
  for (double r : fieldResidual) total += r * r;
  total = std::sqrt(total);
  if (total > 0)
    for (std::size_t b = 0; b < blocks_.size(); ++b) residualSum_[b] += fieldResidual[b] / total;
  double largest = 0.0;
  for (double s : residualSum_)
    if (s > 0) largest = std::max(largest, 1.0 / s);
  if (largest == 0.0) largest = 1.0;
  weights_.resize(offsets_.back());
  for (std::size_t b = 0; b < blocks_.size(); ++b)
    std::fill(weights_.begin() + static_cast<std::ptrdiff_t>(offsets_[b]),
              weights_.begin() + static_cast<std::ptrdiff_t>(offsets_[b + 1]),
              residualSum_[b] > 0 ? 1.0 / residualSum_[b] : largest);
}

std::vector<double> ImplicitIteration::gather(SchemeHost& host) {
  std::vector<double> v;
  offsets_.assign(1, 0);
  for (const Block& b : blocks_) {
    auto& outputs = host.outputs(b.participant);
    for (const auto& f : b.fields)
      if (const auto it = outputs.find(f); it != outputs.end()) v.insert(v.end(), it->second.begin(), it->second.end());
    offsets_.push_back(v.size());
  }
  return v;
}

void ImplicitIteration::feed(SchemeHost& host, const std::vector<double>& x) {
  std::size_t offset = 0;
  for (const Block& b : blocks_)
    for (const auto& f : b.fields) {
      auto& values = host.outputs(b.participant)[f];
      std::copy(x.begin() + static_cast<std::ptrdiff_t>(offset),
                x.begin() + static_cast<std::ptrdiff_t>(offset + values.size()), values.begin());
      offset += values.size();
    }
  deliverOwners(host);
}

void ImplicitIteration::deliverOwners(SchemeHost& host) const {
  for (std::size_t p : owners_) host.deliver(p);
}

void ImplicitIteration::abandonWindow() { acceleration_->abandon(); }

void ImplicitIteration::archive(common::StateArchive& a) {
  a.io("previous_end", previousEnd_), a.io("last_end", lastEnd_), a.io("last_window_s", lastSize_);
  auto scope = a.scope("acceleration");
  acceleration_->archive(a);
}

}  // namespace cosim
