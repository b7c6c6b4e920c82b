#pragma once
// The results of a run on several MPI ranks in one rank's layout: rank 0 writes the series and snapshots
// that every rank's share goes into, and the summary of the whole run. Standalone (ranked_run.cpp) and
// coupled (ranked_participant.cpp) runs share it. Every call but write() and flush() is collective.
#include <cstdint>
#include <optional>
#include <vector>

#include "dem/ranked_run.hpp"
#include "dem/scene.hpp"
#include "ranked_simulation.hpp"

namespace common {
class H5Writer;
class Summary;
}  // namespace common

namespace dem {

class RankedOutput {
 public:
  /// `h5`: rank 0's results file (nullptr on the others), with the series of the bodies `track`.
  RankedOutput(Simulation& sim, const RankedSimulation& ranked, const Ranks& ranks, common::H5Writer* h5,
               std::vector<std::uint32_t> track);
  /// A series row of the whole run now, complete on rank 0.
  SeriesRecorder::Row sample() const;
  /// Rank 0 writes `row`; the others have nothing to write.
  void write(const SeriesRecorder::Row& row);
  /// Rank 0's results file to disk.
  void flush();
  /// A particle snapshot and the mesh walls' node forces now, stamped `time`.
  void writeParticles(double time);
  /// The summary of the whole run: its counts, contacts, ledger, bonds, speed (`loopSeconds` of stepping)
  /// and the ranks' cost (rank 0's share for the per-phase cost); the whole scene's `criticalDt` and the
  /// monitor's `energyError`.
  void report(const Scene& scene, double loopSeconds, double criticalDt, double energyError,
              common::Summary& summary) const;

 private:
  Simulation& sim_;
  const RankedSimulation& ranked_;
  Ranks ranks_;
  common::H5Writer* h5_;
  std::vector<std::uint32_t> track_;
  std::optional<SeriesRecorder> series_;  // rank 0
};

}  // namespace dem
