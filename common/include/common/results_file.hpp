#pragma once
// A run's HDF5 results file and, on a restart, the checkpoint it continues from: one
// place for every solver, standalone or coupled, and the coupler; and when a coupled run's snapshots fall.
//
// A checkpoint keeps the extent of the results file under kResultsExtent (archiveExtent); a restart
// reopens the file cut back to it (openResults), only once the checkpoint proved whole (every
// checksum), of the right program and of this scene's dimensions: a refused restart changes nothing.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "common/h5_writer.hpp"
#include "common/state_archive.hpp"

namespace common {

inline constexpr const char* kResultsExtent = "output";

struct ResultsFile {
  std::optional<StateArchive> restart;  ///< the checkpoint to read the state from; empty: a fresh run
  std::unique_ptr<H5Writer> h5;
};

/// `restart` empty: `h5Path` created afresh, and `stale` (where an earlier run in the same folder kept
/// its checkpoint) removed, so a later --restart cannot continue someone else's run. Otherwise the
/// checkpoint is verified, opened as `kind` and checked against `shape` (StateArchive::shape) before
/// `h5Path` is reopened at its extent.
ResultsFile openResults(const std::filesystem::path& h5Path, const std::filesystem::path& restart,
                        const std::string& kind, const std::string& shape, const std::filesystem::path& stale = {});

/// Writes the extent of `h5` (flushed) into a checkpoint being written.
void archiveExtent(StateArchive& a, H5Writer& h5);

/// Snapshots every `interval` [s] (0: none) of a coupled run's committed windows: whether the window ending
/// at `t` takes one (round-off of 1e-9 interval allowed), and if so `next` moves past it. Not the standalone
/// loop's rule (common::Cadence: the step nearest to each time): a coupled window's length is not known
/// ahead (an adaptive window is halved where it diverges), so the snapshot is the first committed end at
/// or past its time, and one window longer than the interval takes one snapshot, not several.
inline bool snapshotDue(double t, double interval, double& next) {
  if (!(interval > 0) || t + 1e-9 * interval < next) return false;
  while (next <= t + 1e-9 * interval) next += interval;
  return true;
}

}  // namespace common
