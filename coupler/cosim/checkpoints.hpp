#pragma once
// The coupled run's on-disk checkpoints (coupling.checkpoint_interval) and the restart from them
// (`cosim run SCENE --out DIR --restart`). checkpoint/cosim.h5 names the window and each participant's
// own file beside it; the coupler's state at that window's start is archived by the loop into it.
// A checkpoint is written at a window's start and committed once the window stands; the participants
// write theirs before their first RESULT of that window, and the previous checkpoint's files go.

#include <cstdint>
#include <filesystem>
#include <optional>

#include "common/state_archive.hpp"
#include "connections.hpp"

namespace common {
class H5Writer;
}

namespace cosim {

class Checkpoints {
 public:
  Checkpoints(std::filesystem::path outDir, const CouplingSpec& coupling)
      : dir_(std::move(outDir) / "checkpoint"), coupling_(coupling) {}

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path participantFile(const Participant& p, std::uint64_t window) const;

  /// Restart: reads checkpoint/cosim.h5 (a located common::ConfigError when it is missing, damaged or
  /// of another scene), points each participant at its file and returns the archive, positioned for
  /// the loop's state; `startWindow` is the window it holds.
  common::StateArchive open(std::vector<Participant>& participants, std::uint64_t& startWindow);
  /// A fresh run: an earlier run's checkpoints are not this run's to restart from.
  void clear() const;

  /// Window `window` (not the run's first) starts with a checkpoint?
  bool due(std::uint64_t window, std::uint64_t startWindow) const;
  /// The coupler's checkpoint of this window's start, with the participants' file names and coupling.h5's
  /// extent; the loop archives its state into it before the window runs.
  common::StateArchive begin(std::uint64_t window, const std::vector<Participant>& participants, common::H5Writer& h5);
  /// The window stands: the checkpoint is committed and the previous one's participant files removed.
  void commit(common::StateArchive& checkpoint, std::uint64_t window, const std::vector<Participant>& participants);
  std::int64_t written() const { return written_; }

 private:
  std::filesystem::path dir_;
  const CouplingSpec& coupling_;
  std::uint64_t last_ = 0;  // the window of the last committed (or restarted-from) checkpoint
  std::int64_t written_ = 0;
};

}  // namespace cosim
