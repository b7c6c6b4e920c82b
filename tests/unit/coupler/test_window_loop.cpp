// libcosim's window loop (cosim/window_loop.hpp) against a scripted coupler: subcycling, the inputs
// each substep sees (held, or linear from the last committed window's end value), the outputs each
// window sends (the substeps' mean, or the last value), the call order around repeated iterations, the
// loop's state in an on-disk checkpoint and on a restart, and an adapter that breaks the contract.
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/state_archive.hpp"
#include "cosim/window_loop.hpp"
#include "temp_dir.hpp"

namespace {

using cosim::Interpolation;
using cosim::Reduction;

// A coupler that sends the ADVANCEs of a script and keeps what the participant sent back.
class ScriptedCoupler : public cosim::CouplingChannel {
 public:
  struct Advance {
    cosim::Window window;
    std::map<std::string, std::vector<double>> inputs;  // "mesh/field"
  };
  std::vector<Advance> script;
  std::vector<std::map<std::string, std::vector<double>>> results;  // per RESULT
  std::vector<std::string> reads, writes, failures;
  bool offered = false;

  void addMesh(const std::string&, std::span<const double>, std::span<const std::uint32_t>) override {}
  void addCells(const std::string&, int, std::span<const std::uint32_t>) override {}
  void addRead(const std::string& mesh, const std::string& field, int) override { reads.push_back(mesh + "/" + field); }
  void addWrite(const std::string& mesh, const std::string& field, int) override { writes.push_back(mesh + "/" + field); }
  void offerCheckpoints() override { offered = true; }
  void initialize() override {}
  bool nextWindow(cosim::Window& w) override {
    if (next_ == script.size() && endWithError) throw cosim::CouplingError("the coupler stopped the run: floor reached");
    if (next_ == script.size()) return false;
    w = script[next_].window;
    inputs_ = script[next_++].inputs;
    outputs_.clear();
    return true;
  }
  std::span<const double> read(const std::string& mesh, const std::string& field) const override {
    return inputs_.at(mesh + "/" + field);
  }
  void write(const std::string& mesh, const std::string& field, std::span<const double> data) override {
    outputs_[mesh + "/" + field].assign(data.begin(), data.end());
  }
  void complete(double, double) override { results.push_back(outputs_); }
  void fail(const std::string& text, bool) override { failures.push_back(text); }
  // Retries (protocol feature kRetries): agreed when offered and `agreeRetries`.
  bool agreeRetries = false, retriesOffered = false;
  bool endWithError = false;  // after the script: the coupler's ERROR (CouplingError), not FINALIZE
  std::vector<std::string> divergences;
  void offerRetries() override { retriesOffered = true; }
  bool retries() const override { return retriesOffered && agreeRetries; }
  void diverged(const std::string& text) override {
    divergences.push_back(text);
    results.push_back({});
  }

  // Window `index`, iteration `iteration` of length `dt` with the displacement `d` at its end.
  void advance(std::uint64_t index, std::uint32_t iteration, double dt, std::vector<double> d, bool save = false,
               bool restore = false, std::string checkpoint = {}) {
    Advance a;
    a.window.index = index;
    a.window.iteration = iteration;
    a.window.time = static_cast<double>(index) * dt;
    a.window.dt = dt;
    a.window.saveCheckpoint = save;
    a.window.restoreCheckpoint = restore;
    a.window.checkpoint = std::move(checkpoint);
    a.inputs["wall/displacement"] = std::move(d);
    a.inputs["wall/load"] = {10.0};
    script.push_back(std::move(a));
  }

 private:
  std::size_t next_ = 0;
  std::map<std::string, std::vector<double>> inputs_, outputs_;
};

// An adapter that records what each substep saw. It writes `force` = its substep's number (1, 2, …)
// times the displacement's first value where the substep ends, and `position` = the end value in
// endWindow.
class RecordingSolver : public cosim::CoupledSolver {
 public:
  double substep = 0.0;
  std::vector<std::string> calls;
  std::vector<double> at, displacement, rate, load;  // per step: where, d[0] there, its rate, the held load
  bool skipMeanIn = false;                           // break the contract: no force in the second step
  double divergeAbove = 1e300;                       // a window longer than this: the solver diverges
  std::vector<double> initial;                       // the displacement's declared initial value

  void declare(cosim::InterfaceDeclaration& io) override {
    io.addMesh("wall", std::vector<double>{0, 0, 0, 1, 0, 0}, {});
    io.addRead("wall", "displacement", 1, Interpolation::kLinear, initial);
    io.addRead("wall", "load", 1);
    io.addWrite("wall", "force", 1, Reduction::kMean);
    io.addWrite("wall", "position", 1);
  }
  void save() override { calls.push_back("save"); }
  void restore() override { calls.push_back("restore"); }
  double maxSubstep() const override { return substep; }
  void beginWindow(const cosim::Window& w, const cosim::Substeps& sub, cosim::WindowIo&) override {
    calls.push_back("begin " + std::to_string(w.index) + " x" + std::to_string(sub.count));
  }
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override {
    if (w.dt > divergeAbove) throw std::runtime_error("diverged: window too long");
    const auto d = io.read("wall", "displacement", s.end);
    at.push_back(s.end);
    displacement.push_back(d[0]);
    rate.push_back(io.rate("wall", "displacement")[0]);
    load.push_back(io.read("wall", "load", s.begin)[0]);
    if (skipMeanIn && s.index == 1) return;
    const double f = static_cast<double>(s.index + 1) * d[0];
    io.write("wall", "force", std::vector<double>{f, -f});
  }
  void endWindow(const cosim::Window&, cosim::WindowIo& io) override {
    io.write("wall", "position", io.read("wall", "displacement", 1.0));
    calls.push_back("end");
  }
  void commit() override { calls.push_back("commit"); }
};

cosim::WindowLoopOptions options() {
  cosim::WindowLoopOptions o;
  o.label = "recorder";
  return o;
}

// Runs `solver` through one window (displacement 0.3 at its end) that must end in a contract error, and
// returns the ERROR the coupler received.
std::string contractError(cosim::CoupledSolver& solver) {
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1.0, {0.3});
  EXPECT_THROW(cosim::runWindowLoop(coupler, solver, options()), std::logic_error);
  EXPECT_TRUE(coupler.results.empty());
  return coupler.failures.size() == 1 ? coupler.failures[0] : "failures: " + std::to_string(coupler.failures.size());
}

TEST(Substeps, FewestEqualStepsNoLongerThanTheSolversStep) {
  EXPECT_EQ(cosim::Substeps(1e-4, 1e-5).count, 10);  // 1e-4 / 1e-5 is 10.000000000000002 in doubles
  EXPECT_EQ(cosim::Substeps(1e-4, 3e-5).count, 4);
  EXPECT_EQ(cosim::Substeps(1e-4, 0.0).count, 1);  // a static solver: the window is one step
  EXPECT_EQ(cosim::Substeps(1e-4, 1e-3).count, 1);
  const cosim::Substeps sub(1e-4, 3e-5);
  EXPECT_DOUBLE_EQ(sub.dt, 2.5e-5);
  EXPECT_EQ(sub[0].begin, 0.0);
  EXPECT_EQ(sub[3].end, 1.0);
  EXPECT_EQ(sub[1].end, sub[2].begin);
}

// Four substeps: the linear input goes from 0 to the coupler's value in quarters, its rate is the
// window's, the held input is the coupler's throughout; the mean output is the substeps' mean and the
// last-value output is what endWindow wrote.
TEST(WindowLoop, InterpolatesInputsPerSubstepAndReducesOutputsPerWindow) {
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1e-4, {8.0, 0.0});
  RecordingSolver solver;
  solver.substep = 2.5e-5;
  const auto report = cosim::runWindowLoop(coupler, solver, options());
  EXPECT_EQ(report.windows, 1);
  EXPECT_EQ(report.substeps, 4);
  EXPECT_EQ(solver.displacement, (std::vector<double>{2.0, 4.0, 6.0, 8.0}));
  for (double r : solver.rate) EXPECT_DOUBLE_EQ(r, 8.0 / 1e-4);
  EXPECT_EQ(solver.load, (std::vector<double>(4, 10.0)));
  ASSERT_EQ(coupler.results.size(), 1u);
  // (1·2 + 2·4 + 3·6 + 4·8) / 4 = 15
  EXPECT_DOUBLE_EQ(coupler.results[0].at("wall/force")[0], 15.0);
  EXPECT_DOUBLE_EQ(coupler.results[0].at("wall/force")[1], -15.0);
  EXPECT_EQ(coupler.results[0].at("wall/position"), (std::vector<double>{8.0, 0.0}));
  EXPECT_EQ(solver.calls, (std::vector<std::string>{"begin 0 x4", "end", "commit"}));
}

// An implicit scheme repeats window 0 with another end value: both iterations start from zero. Window 1
// starts where window 0's last iteration ended, not its first; and at the window's end the solver gets
// the coupler's value itself, not a re-interpolation of it (0.3 + 1·(0.9 − 0.3) is not 0.9 in doubles):
// a Dirichlet side's own state stays equal to what the loop starts the next window from.
TEST(WindowLoop, RepeatedIterationsStartFromTheLastCommittedWindowsEnd) {
  ASSERT_NE(0.3 + 1.0 * (0.9 - 0.3), 0.9) << "values that would show a re-interpolated end";
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1.0, {0.1}, true);
  coupler.advance(0, 1, 1.0, {0.3}, false, true);
  coupler.advance(1, 0, 1.0, {0.9}, true);
  RecordingSolver solver;
  solver.substep = 0.5;
  cosim::runWindowLoop(coupler, solver, options());
  EXPECT_EQ(solver.displacement, (std::vector<double>{0.05, 0.1, 0.15, 0.3, 0.3 + 0.5 * (0.9 - 0.3), 0.9}));
  EXPECT_DOUBLE_EQ(solver.rate[4], 0.6);
  EXPECT_EQ(solver.calls, (std::vector<std::string>{"save", "begin 0 x2", "end", "restore", "begin 0 x2", "end",
                                                    "commit", "save", "begin 1 x2", "end", "commit"}));
  ASSERT_EQ(coupler.results.size(), 3u);
  EXPECT_EQ(coupler.results[2].at("wall/position")[0], 0.9);
}

// A declared initial value is where the first window starts from (an interface already displaced when
// the run begins); without one, zero.
TEST(WindowLoop, FirstWindowStartsFromTheDeclaredInitialValue) {
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1.0, {1.0});
  RecordingSolver solver;
  solver.substep = 0.5;
  solver.initial = {0.2};
  cosim::runWindowLoop(coupler, solver, options());
  EXPECT_EQ(solver.displacement, (std::vector<double>{0.2 + 0.5 * (1.0 - 0.2), 1.0}));
  EXPECT_DOUBLE_EQ(solver.rate[0], 0.8);
}

// The state an on-disk checkpoint holds is the window start's; a run resumed with it continues as the
// uninterrupted run did.
TEST(WindowLoop, CheckpointHoldsTheWindowStartAndARestartContinuesFromIt) {
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1.0, {0.3});
  coupler.advance(1, 0, 1.0, {0.9}, false, false, "ckpt");
  RecordingSolver solver;
  solver.substep = 0.25;
  cosim::WindowLoopState written;
  auto o = options();
  o.writeCheckpoint = [&](const std::string& path, const cosim::WindowLoopState& s) {
    EXPECT_EQ(path, "ckpt");
    written = s;
  };
  cosim::runWindowLoop(coupler, solver, o);
  EXPECT_TRUE(coupler.offered);
  EXPECT_EQ(written.fields, (std::vector<std::string>{"wall/displacement"}));
  EXPECT_EQ(written.start, (std::vector<std::vector<double>>{{0.3}}));

  ScriptedCoupler restarted;
  restarted.advance(1, 0, 1.0, {0.9});
  RecordingSolver again;
  again.substep = 0.25;
  auto r = options();
  r.resume = written;
  cosim::runWindowLoop(restarted, again, r);
  const std::vector<double> tail(solver.displacement.end() - 4, solver.displacement.end());
  EXPECT_EQ(again.displacement, tail);
  EXPECT_EQ(restarted.results[0], coupler.results[1]);
}

TEST(WindowLoop, ResumeStateOfOtherFieldsIsRefused) {
  ScriptedCoupler coupler;
  coupler.advance(0, 0, 1.0, {0.3});
  RecordingSolver solver;
  auto o = options();
  o.resume.fields = {"net/displacement"};
  o.resume.start = {{0.0}};
  try {
    cosim::runWindowLoop(coupler, solver, o);
    FAIL() << "resumed from another interface's state";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("interpolates [net/displacement], the solver declares [wall/displacement]"),
              std::string::npos)
        << e.what();
  }
  ASSERT_EQ(coupler.failures.size(), 1u);
  EXPECT_EQ(coupler.failures[0].rfind("recorder: ", 0), 0u);
}

// A window-mean output missing from one substep would send a mean over fewer substeps than the window
// has: the loop stops the run and tells the coupler.
TEST(WindowLoop, MeanOutputMissingFromASubstepIsAContractError) {
  RecordingSolver solver;
  solver.substep = 0.25;
  solver.skipMeanIn = true;
  const std::string error = contractError(solver);
  EXPECT_NE(error.find("did not write its window-mean output wall/force in substep 2 of 4"), std::string::npos) << error;
}

TEST(WindowLoop, UndeclaredFieldIsAContractError) {
  class Stray : public RecordingSolver {
    void step(const cosim::Window&, const cosim::Substep&, cosim::WindowIo& io) override { io.read("wall", "velocity"); }
  };
  Stray solver;
  const std::string error = contractError(solver);
  EXPECT_NE(error.find("reads wall/velocity, which it did not declare"), std::string::npos) << error;
}

// A last-value output written in every step sends the last step's value; one never written, or a mean
// output written twice in a step, stops the run naming the field.
TEST(WindowLoop, LastValueOutputIsTheLastWriteAndMissingOrDoubleWritesAreContractErrors) {
  class Writer : public RecordingSolver {
   public:
    bool writePosition = true, meanTwice = false;
    void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override {
      RecordingSolver::step(w, s, io);
      if (meanTwice) io.write("wall", "force", std::vector<double>{0.0, 0.0});
      if (writePosition) io.write("wall", "position", std::vector<double>{static_cast<double>(s.index)});
    }
    void endWindow(const cosim::Window&, cosim::WindowIo&) override {}
  };
  {
    ScriptedCoupler coupler;
    coupler.advance(0, 0, 1.0, {0.3});
    Writer solver;
    solver.substep = 0.25;
    cosim::runWindowLoop(coupler, solver, options());
    EXPECT_EQ(coupler.results[0].at("wall/position"), (std::vector<double>{3.0})) << "the fourth step's";
  }
  Writer silent;
  silent.writePosition = false;
  std::string error = contractError(silent);
  EXPECT_NE(error.find("did not write its output wall/position in the window"), std::string::npos) << error;
  Writer twice;
  twice.meanTwice = true;
  error = contractError(twice);
  EXPECT_NE(error.find("wall/force is written once per step, in step(): written twice in one"), std::string::npos) << error;
}

// The loop's state through a checkpoint file (common::StateArchive), as cosim::runAdapter writes and
// reads it: every start value to the bit, an empty one (a checkpoint before any window) included.
TEST(WindowLoopState, RoundTripsThroughAStateArchive) {
  const TempDir dir;
  const auto path = dir.path() / "loop.h5";
  cosim::WindowLoopState state;
  state.fields = {"wall/displacement", "net/velocity"};
  state.start = {{0.1, -0.0, 1e-300, 0.3 + 0.6}, {}};
  common::StateArchive::write(path, "test", [&](common::StateArchive& a) { a.io("window_loop", state); });
  cosim::WindowLoopState read;
  auto a = common::StateArchive::open(path, "test");
  a.io("window_loop", read);
  EXPECT_EQ(read.fields, state.fields);
  ASSERT_EQ(read.start.size(), 2u);
  ASSERT_EQ(read.start[0].size(), 4u);
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_EQ(std::memcmp(&read.start[0][i], &state.start[0][i], sizeof(double)), 0) << i;
  EXPECT_TRUE(read.start[1].empty());
}

}  // namespace

// A solver that diverges in an iteration, under a coupler that agreed to retries: the loop answers with
// a diverged RESULT instead of ending, and the coupler's repeat (restore, a shorter window) goes on as a
// fresh iteration; the window is committed once, after it. A coupler that then ends the run gets the
// divergence rethrown; one that moves on without restoring is a contract error.
TEST(WindowLoop, ADivergedIterationIsRepeatedWhenTheCouplerAgrees) {
  auto diverges = [](const std::exception& e) { return std::string(e.what()).find("diverged") != std::string::npos; };
  ScriptedCoupler c;
  c.agreeRetries = true;
  c.advance(0, 0, 1.0, {0.5}, true);         // diverges
  c.advance(0, 0, 0.5, {0.25}, true, true);  // repeated halved, restored
  c.advance(1, 0, 0.5, {0.5}, true);
  RecordingSolver s;
  s.divergeAbove = 0.75;
  auto o = options();
  o.diverged = diverges;
  const auto report = cosim::runWindowLoop(c, s, o);
  EXPECT_TRUE(c.retriesOffered);
  ASSERT_EQ(c.divergences.size(), 1u);
  EXPECT_EQ(c.divergences[0], "recorder: diverged: window too long");
  EXPECT_TRUE(c.failures.empty());
  EXPECT_EQ(report.windows, 2);
  EXPECT_EQ(report.iterations, 3);
  const std::vector<std::string> calls{"save",       "begin 0 x1", "restore", "save", "begin 0 x1", "end",
                                       "commit",     "save",       "begin 1 x1", "end",  "commit"};
  EXPECT_EQ(s.calls, calls);
  ASSERT_EQ(c.results.size(), 3u);
  EXPECT_EQ(c.results[1].at("wall/position")[0], 0.25);

  ScriptedCoupler ends;  // the coupler ends the run after the divergence (at its floor): the loop ends
  ends.agreeRetries = true;  // with the divergence itself (exit 3 there), not the coupler's ERROR
  ends.endWithError = true;
  ends.advance(0, 0, 1.0, {0.5}, true);
  RecordingSolver s2;
  s2.divergeAbove = 0.75;
  try {
    cosim::runWindowLoop(ends, s2, o);
    ADD_FAILURE() << "no error";
  } catch (const cosim::CouplingError& e) {
    ADD_FAILURE() << "the coupler's ERROR instead of the divergence: " << e.what();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "diverged: window too long");
  }
  EXPECT_EQ(ends.divergences.size(), 1u);

  ScriptedCoupler careless;  // moves on without restoring the diverged state
  careless.agreeRetries = true;
  careless.advance(0, 0, 1.0, {0.5}, true);
  careless.advance(1, 0, 1.0, {0.5}, true);
  RecordingSolver s3;
  s3.divergeAbove = 0.75;
  try {
    cosim::runWindowLoop(careless, s3, o);
    ADD_FAILURE() << "no error";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("must repeat the window from its start"), std::string::npos) << e.what();
  }

  ScriptedCoupler old;  // a coupler without retries: the divergence is an ERROR and the loop ends
  old.advance(0, 0, 1.0, {0.5}, true);
  RecordingSolver s4;
  s4.divergeAbove = 0.75;
  EXPECT_THROW(cosim::runWindowLoop(old, s4, o), std::runtime_error);
  EXPECT_TRUE(old.divergences.empty());
  ASSERT_EQ(old.failures.size(), 1u);
}
