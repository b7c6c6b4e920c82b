#pragma once
// The implicit schemes (coupler/README.md, "Numerics"): a window is repeated from its checkpoint until
// the fixed point x̃ converges, block by block. x̃ is a stack of blocks of read outputs: the serial
// scheme's is one, the last participant's outputs together; the parallel scheme's one per field of every
// participant (forces and displacements, each tested on its own). A scheme is this class given its blocks
// and its pass (who advances when; implicit.cpp, implicit_parallel.cpp); the class does the rest:
// the extrapolated first iterate, the per-block residuals and their test, the scaling of the stacked
// vector (the residual-sum preconditioner), the acceleration, divergence, and feeding x̃ back to the
// readers.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "scheme.hpp"

namespace spdlog {
class logger;
}

namespace cosim {

class ImplicitIteration final : public Scheme {
 public:
  /// A part of x̃ with its own convergence test and its own weight: read outputs ("mesh/field") of one
  /// participant. Its tolerance is coupling.tolerance.fields' entry that all its fields share, else the
  /// scene's.
  struct Block {
    std::size_t participant;
    std::vector<std::string> fields;
  };
  /// One pass of an iteration: every participant advanced once with `flags`, their RESULTs collected.
  /// Outputs of a participant that owns no block may be delivered within it (the serial order); the
  /// owners of blocks are delivered by the core, after the acceleration.
  using Pass = std::function<void(SchemeHost&, std::uint32_t flags)>;

  /// `name`: the scheme's, for the summary.
  ImplicitIteration(const IterationSettings& settings, std::vector<Block> blocks, std::string name, Pass pass);
  ~ImplicitIteration() override;

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override;
  bool strong() const override { return true; }
  std::string describe() const override;
  void archive(common::StateArchive& a) override;
  /// The window's outcome stands: its end starts the next one's extrapolation, its columns are kept for
  /// reuse (converged) or every column goes (not converged).
  void acceptWindow(SchemeHost& host, const WindowOutcome& w) override;
  /// The window diverged or did not converge and is repeated shorter: its columns go, the reused
  /// windows' stay.
  void abandonWindow() override;
  const IterationSettings* iteration() const override { return &settings_; }

 private:
  std::vector<double> gather(SchemeHost& host);
  void feed(SchemeHost& host, const std::vector<double>& x);
  void deliverOwners(SchemeHost& host) const;
  void updateWeights(const std::vector<double>& fieldResiduals);

  IterationSettings settings_;
  std::unique_ptr<Acceleration> acceleration_;
  std::vector<Block> blocks_;
  std::string name_;
  Pass pass_;
  std::vector<IterationSettings::Tolerance> tolerances_;  // per block
  std::vector<std::size_t> owners_;            // participants that own a block, once each
  std::vector<std::size_t> offsets_;           // block b is x̃[offsets_[b], offsets_[b + 1])
  std::vector<double> residualSum_, weights_;  // residual-sum preconditioner: per block, then per entry
  std::vector<double> previousEnd_, lastEnd_;  // x̃ at the ends of the last two windows (extrapolation)
  double lastSize_ = 0.0;                      // the last window's length [s]
  std::shared_ptr<spdlog::logger> log_;
};

}  // namespace cosim
