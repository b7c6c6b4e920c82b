#include "checkpoints.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/results_file.hpp"

namespace cosim {

namespace fs = std::filesystem;

fs::path Checkpoints::participantFile(const Participant& p, std::uint64_t window) const {
  return dir_ / fmt::format("{}_{:08d}.h5", p.spec.name, window);
}

common::StateArchive Checkpoints::open(std::vector<Participant>& participants, std::uint64_t& startWindow) {
  const fs::path file = dir_ / "cosim.h5";
  if (!fs::exists(file))
    throw common::ConfigError(fmt::format("--restart: {} holds no checkpoint ({} is missing); a run writes them with "
                                          "coupling.checkpoint_interval",
                                          dir_.parent_path().string(), file.string()));
  common::StateArchive::verify(file);
  common::StateArchive resume = common::StateArchive::open(file, "cosim");
  double windowSize = 0.0;
  resume.io("window", startWindow);
  resume.io("time_window", windowSize);
  if (windowSize != coupling_.window)
    throw common::ConfigError(fmt::format("--restart: the checkpoint {} is of a run with coupling.time_window = {} s; "
                                          "this scene has {} s",
                                          file.string(), windowSize, coupling_.window));
  for (auto& p : participants) {
    if (p.spec.external)
      throw common::ConfigError(fmt::format("--restart: participant \"{}\" is external: the coupler cannot start it from "
                                            "its checkpoint",
                                            p.spec.name));
    if (!resume.has("participants/" + p.spec.name))
      throw common::ConfigError(fmt::format("--restart: the checkpoint {} has no participant \"{}\"", file.string(),
                                            p.spec.name));
    std::string name;
    resume.io("participants/" + p.spec.name, name);
    p.restart = dir_ / name;
    try {
      common::StateArchive::verify(p.restart);
    } catch (const common::ConfigError& e) {
      throw common::ConfigError(fmt::format("--restart: participant \"{}\"'s checkpoint: {}", p.spec.name, e.what()));
    }
  }
  last_ = startWindow;
  return resume;
}

void Checkpoints::clear() const {
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

bool Checkpoints::due(std::uint64_t window, std::uint64_t startWindow) const {
  const int interval = coupling_.checkpointInterval;
  return interval > 0 && window > 0 && window % static_cast<std::uint64_t>(interval) == 0 && window != startWindow;
}

common::StateArchive Checkpoints::begin(std::uint64_t window, const std::vector<Participant>& participants,
                                        common::H5Writer& h5) {
  common::StateArchive checkpoint = common::StateArchive::create(dir_ / "cosim.h5", "cosim");
  double windowSize = coupling_.window;
  checkpoint.io("window", window);
  checkpoint.io("time_window", windowSize);
  for (const auto& p : participants) {
    std::string f = participantFile(p, window).filename().string();
    checkpoint.io("participants/" + p.spec.name, f);
  }
  common::archiveExtent(checkpoint, h5);
  return checkpoint;
}

void Checkpoints::commit(common::StateArchive& checkpoint, std::uint64_t window,
                         const std::vector<Participant>& participants) {
  checkpoint.commit();
  ++written_;
  common::logger("cosim")->info("checkpoint at window {}: {}", window, dir_.string());
  // The previous checkpoint's participant files: no coupler checkpoint names them any more.
  if (last_ > 0 && last_ != window)
    for (const auto& p : participants) {
      std::error_code ec;
      fs::remove(participantFile(p, last_), ec);
    }
  last_ = window;
}

}  // namespace cosim
