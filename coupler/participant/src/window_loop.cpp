#include "cosim/window_loop.hpp"

#include <chrono>
#include <exception>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace cosim {

namespace {

// The interface as the loop keeps it: the declarations (forwarded to the channel), each kLinear input's
// window-start and window-end values, and each output's reduction over the substeps of an iteration.
class LoopInterface final : public InterfaceDeclaration, public WindowIo {
 public:
  explicit LoopInterface(CouplingChannel& channel) : channel_(channel) {}

  void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::uint32_t> triangles) override {
    channel_.addMesh(mesh, nodes, triangles);
  }
  void addCells(const std::string& mesh, int nodesPerCell, std::span<const std::uint32_t> cells) override {
    channel_.addCells(mesh, nodesPerCell, cells);
  }
  void addRead(const std::string& mesh, const std::string& field, int components, Interpolation interpolation,
               std::span<const double> initial) override {
    channel_.addRead(mesh, field, components);
    reads_.push_back({mesh, field, interpolation, {initial.begin(), initial.end()}, {}, {}, {}});
  }
  void addWrite(const std::string& mesh, const std::string& field, int components, Reduction reduction) override {
    channel_.addWrite(mesh, field, components);
    writes_.push_back({mesh, field, reduction, {}, 0, -2});
  }

  void resume(const WindowLoopState& state) {
    const WindowLoopState declared = this->state();
    if (state.fields.empty() && state.start.empty()) return;
    if (state.fields != declared.fields || state.start.size() != state.fields.size())
      throw std::invalid_argument(fmt::format("the restart's window loop state interpolates [{}], the solver declares [{}]",
                                              fmt::join(state.fields, ", "), fmt::join(declared.fields, ", ")));
    std::size_t i = 0;
    for (auto& r : reads_)
      if (r.interpolation == Interpolation::kLinear) r.start = state.start[i++];
  }
  WindowLoopState state() const {
    WindowLoopState s;
    for (const auto& r : reads_)
      if (r.interpolation == Interpolation::kLinear) {
        s.fields.push_back(r.mesh + "/" + r.field);
        s.start.push_back(r.start);
      }
    return s;
  }

  // A new iteration of window `w` in `count` substeps: the coupler's values are the window-end values.
  void begin(const Window& w, std::int64_t count) {
    dt_ = w.dt;
    count_ = count;
    step_ = -1;
    for (auto& r : reads_) {
      if (r.interpolation != Interpolation::kLinear) continue;
      const auto end = channel_.read(r.mesh, r.field);
      r.end.assign(end.begin(), end.end());
      if (r.start.empty()) r.start.assign(r.end.size(), 0.0);  // no initial value declared: zero
      if (r.start.size() != r.end.size())
        throw std::invalid_argument(fmt::format("{}/{}: {} values at the window start (declared or restarted), {} from "
                                                "the coupler", r.mesh, r.field, r.start.size(), r.end.size()));
    }
    for (auto& o : writes_) {
      o.value.clear();
      o.writes = 0;
      o.lastStep = -2;
    }
  }
  void beginStep(std::int64_t s) { step_ = s; }
  void endStep() {
    for (const auto& o : writes_)
      if (o.reduction == Reduction::kMean && o.lastStep != step_)
        throw std::logic_error(fmt::format("the solver did not write its window-mean output {}/{} in substep {} of {}",
                                           o.mesh, o.field, step_ + 1, count_));
    step_ = -1;
  }
  // The iteration's outputs to the channel.
  void finish() {
    for (const auto& o : writes_) {
      if (o.writes == 0)
        throw std::logic_error(fmt::format("the solver did not write its output {}/{} in the window", o.mesh, o.field));
      channel_.write(o.mesh, o.field, o.value);
    }
  }
  // The window last advanced is final: its end values start the next one.
  void commit() {
    for (auto& r : reads_)
      if (r.interpolation == Interpolation::kLinear && !r.end.empty()) r.start = r.end;
  }

  std::span<const double> read(const std::string& mesh, const std::string& field, double at) override {
    Read& r = find(reads_, mesh, field, "read");
    if (r.interpolation == Interpolation::kHold) return channel_.read(mesh, field);
    if (at <= 0.0) return r.start;
    if (at >= 1.0) return r.end;
    r.buffer.resize(r.end.size());
    for (std::size_t i = 0; i < r.end.size(); ++i) r.buffer[i] = r.start[i] + at * (r.end[i] - r.start[i]);
    return r.buffer;
  }
  std::span<const double> rate(const std::string& mesh, const std::string& field) override {
    Read& r = find(reads_, mesh, field, "read");
    if (r.interpolation != Interpolation::kLinear)
      throw std::logic_error(fmt::format("the rate of {}/{}, an input declared without linear interpolation", mesh, field));
    r.rate.resize(r.end.size());
    for (std::size_t i = 0; i < r.end.size(); ++i) r.rate[i] = (r.end[i] - r.start[i]) / dt_;
    return r.rate;
  }
  void write(const std::string& mesh, const std::string& field, std::span<const double> data) override {
    Write& o = find(writes_, mesh, field, "write");
    if (o.writes > 0 && o.value.size() != data.size())
      throw std::logic_error(fmt::format("the solver wrote {} values of {}/{}, then {}", o.value.size(), mesh, field, data.size()));
    ++o.writes;
    if (o.reduction == Reduction::kEnd) {
      o.value.assign(data.begin(), data.end());
      return;
    }
    if (step_ < 0 || o.lastStep == step_)
      throw std::logic_error(fmt::format("the window-mean output {}/{} is written once per step, in step(): {}", mesh, field,
                                         step_ < 0 ? "written outside one" : "written twice in one"));
    o.lastStep = step_;
    if (o.value.empty()) o.value.assign(data.size(), 0.0);
    for (std::size_t i = 0; i < data.size(); ++i) o.value[i] += data[i] / static_cast<double>(count_);
  }

 private:
  struct Read {
    std::string mesh, field;
    Interpolation interpolation;
    std::vector<double> start, end, buffer, rate;
  };
  struct Write {
    std::string mesh, field;
    Reduction reduction;
    std::vector<double> value;
    std::int64_t writes, lastStep;
  };
  template <class T>
  static T& find(std::vector<T>& all, const std::string& mesh, const std::string& field, const char* what) {
    for (auto& x : all)
      if (x.field == field && x.mesh == mesh) return x;
    throw std::logic_error(fmt::format("the solver {}s {}/{}, which it did not declare", what, mesh, field));
  }

  CouplingChannel& channel_;
  std::vector<Read> reads_;
  std::vector<Write> writes_;
  double dt_ = 0.0;
  std::int64_t count_ = 1, step_ = -1;
};

}  // namespace

WindowLoopReport runWindowLoop(CouplingChannel& channel, CoupledSolver& solver, const WindowLoopOptions& options) {
  WindowLoopReport report;
  LoopInterface io(channel);
  try {
    solver.declare(io);
    io.resume(options.resume);
    if (options.writeCheckpoint) channel.offerCheckpoints();
    if (options.diverged) channel.offerRetries();
    channel.initialize();
    Window w;
    bool advanced = false;
    std::uint64_t current = 0;
    // The solver diverged in the last iteration and the coupler was told (retries): it may repeat the
    // window from its start, shorter; if it ends the run instead, the divergence is this process's end.
    std::exception_ptr divergence;
    while (true) {
      bool more = false;
      try {
        more = channel.nextWindow(w);
      } catch (const CouplingError&) {
        if (divergence) std::rethrow_exception(divergence);
        throw;
      }
      if (!more) {
        if (divergence) std::rethrow_exception(divergence);
        break;
      }
      if (divergence) {
        if (!w.restoreCheckpoint || w.index != current)
          throw std::logic_error("after the solver diverged the coupler must repeat the window from its start "
                                 "(restore-checkpoint)");
        divergence = nullptr;
      }
      const auto start = std::chrono::steady_clock::now();
      if (advanced && w.index != current) {  // a new window: the previous one is final
        solver.commit();
        io.commit();
        ++report.windows;
      }
      current = w.index;
      if (!w.checkpoint.empty()) {
        if (!options.writeCheckpoint)
          throw std::logic_error("the coupler asks for an on-disk checkpoint (" + w.checkpoint +
                                 ") and the loop was given no writeCheckpoint");
        options.writeCheckpoint(w.checkpoint, io.state());
      }
      const Substeps sub(w.dt, solver.maxSubstep());
      try {
        if (w.restoreCheckpoint) solver.restore();
        if (w.saveCheckpoint) solver.save();
        io.begin(w, sub.count);
        solver.beginWindow(w, sub, io);
        for (std::int64_t s = 0; s < sub.count; ++s) {
          io.beginStep(s);
          solver.step(w, sub[s], io);
          io.endStep();
        }
        solver.endWindow(w, io);
        io.finish();
      } catch (const std::exception& e) {
        if (!channel.retries() || !options.diverged || !options.diverged(e)) throw;
        channel.diverged(options.label + ": " + e.what());
        divergence = std::current_exception();
        ++report.iterations;
        continue;
      }
      advanced = true;
      ++report.iterations;
      report.substeps += sub.count;
      channel.complete(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), solver.stableStep());
    }
    if (advanced) {
      solver.commit();
      ++report.windows;
    }
  } catch (const CouplingError&) {
    throw;
  } catch (const std::exception& e) {
    channel.fail(options.label + ": " + e.what(), options.diverged && options.diverged(e));
    throw;
  }
  return report;
}

}  // namespace cosim
