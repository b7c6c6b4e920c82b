#pragma once
// What a DEM scene run on its own gives common::runLoop, on one rank or several: the clock (the time, in
// steps of dt, to end_time in whole steps) and the schedule of the scene's `output` section.

#include <cmath>
#include <filesystem>
#include <string>

#include "common/run_loop.hpp"
#include "dem/scene.hpp"

namespace dem {

/// The kind of a DEM run's checkpoint, on one rank or several.
inline const std::string kStandaloneKind = common::standaloneKind("dem_solver");

class SteppedDem : public common::SteppedRun {
 public:
  SteppedDem(const Simulation& sim, double endTime)
      : clockSim_(sim), totalSteps_(std::llround(endTime / sim.settings().dt)) {}
  double clock() const override { return clockSim_.time(); }
  double clockStep() const override { return clockSim_.settings().dt; }
  std::int64_t steps() const override { return static_cast<std::int64_t>(clockSim_.steps()); }
  bool finished() const override { return steps() >= totalSteps_; }

 private:
  const Simulation& clockSim_;
  std::int64_t totalSteps_;
};

/// The loop's settings for `scene` writing into `outDir`: series and snapshots from the start, checkpoints
/// one interval in.
inline common::RunLoopSettings loopSettings(const Scene& scene, const std::filesystem::path& outDir, const std::string& kind,
                                            bool progress) {
  common::RunLoopSettings s;
  s.label = "dem";
  s.kind = kind;
  s.end = scene.endTime;
  s.series = common::Cadence::every(scene.output.seriesInterval);
  s.snapshots = common::Cadence::every(scene.output.interval);
  s.checkpoints = common::Cadence::after(scene.output.checkpointInterval);
  s.checkpointFile = outDir / "checkpoint" / "dem.h5";
  s.progress = progress;
  return s;
}

}  // namespace dem
