#pragma once
// dem_solver as one participant of a coupled run on several MPI ranks (dem/ranked_run.hpp). Rank 0 alone
// talks to the coupler: libcosim's window loop drives this adapter there, and every call it makes is first
// sent to the other ranks (an order and its data, MPI_Bcast), which do the same on their shares. The
// interface wall's displacement goes out from rank 0 that way, and its node forces, each rank's contacts'
// share, are summed back on rank 0. The coupler sees one participant.
//
// How a run ends: rank 0 sends kFinish after its loop, or kStop with its exit code and message when it
// failed outside a window operation (the coupler stopped the run, or is gone); the other ranks then end
// with that error too. A divergence inside a step is every rank's at once (RankedSimulation, the summed
// ledger): each waits for rank 0's next order, as the coupler may repeat the window shorter. Any other
// failure inside an operation is one rank's alone, and the run is aborted (stopRanks).
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "cosim/coupled_solver.hpp"
#include "dem/scene.hpp"
#include "dem/stability_monitor.hpp"
#include "ranked_output.hpp"
#include "ranked_simulation.hpp"

namespace dem {

class RankedParticipant : public cosim::CoupledSolver {
 public:
  RankedParticipant(Scene& scene, RankedSimulation& ranked, RankedOutput& output, StabilityMonitor& monitor,
                    double criticalDt, int rank);

  // The window loop's calls, on rank 0.
  void declare(cosim::InterfaceDeclaration& io) override;
  void save() override { order(kSave); }
  void restore() override { order(kRestore); }
  double maxSubstep() const override { return dt_; }
  void beginWindow(const cosim::Window& w, const cosim::Substeps& sub, cosim::WindowIo& io) override;
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override;
  void endWindow(const cosim::Window& w, cosim::WindowIo& io) override;
  void commit() override { order(kCommit); }
  double stableStep() const override { return critical_; }

  /// Rank 0, after its window loop: the others leave follow().
  void finish() { order(kFinish); }
  /// Rank 0 failed with `code` and `what`; the others throw the same from follow(). False if it failed
  /// inside an operation while the others may wait in it: then nothing can be sent, and the run aborts.
  bool stop(int code, const std::string& what);
  /// The ranks other than 0: do what rank 0 sends until it finishes (or throw what it stopped with).
  void follow();

  std::int64_t committed() const { return committed_; }

 private:
  enum Order : int { kBeginWindow, kStep, kEndWindow, kSave, kRestore, kCommit, kFinish, kStop };
  // Sends the order and its data from rank 0, then does it here.
  void order(Order what, double value = 0.0, std::span<const double> data = {});
  // What an order does on every rank.
  void apply(Order what, double value, std::span<const double> data);
  // The interface wall's nodes displaced by `d` from their reference, at the window's velocity.
  void placeWall(std::span<const double> d);

  Scene& scene_;
  Simulation& sim_;
  RankedSimulation& ranked_;
  RankedOutput& output_;
  StabilityMonitor& monitor_;
  int rank_;
  std::uint32_t wall_;
  MeshWall reference_;
  double dt_, critical_;
  std::vector<Vec3> positions_, velocity_;
  std::vector<double> forces_;  // rank 0: the interface's node forces of the step, summed
  std::shared_ptr<const RankedSimulation::Saved> saved_;
  SeriesRecorder::Row pending_;  // the last iteration's row, kept if its window turns out final
  double nextSnapshot_;
  std::int64_t committed_ = 0;
  bool applying_ = false;
};

}  // namespace dem
