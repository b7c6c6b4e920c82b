#include "window_control.hpp"

#include <cmath>

#include <algorithm>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace cosim {

WindowControl::WindowControl(double window, double minWindow, int growAfter, std::uint64_t windows)
    : window_(window), maxLevel_(0), growAfter_(growAfter) {
  // The deepest level whose window is still ≥ the floor (to a relative 1e-12: 1e-4 / 4 is 2.5e-5), and
  // whose ticks over the whole run still fit the counter.
  while (maxLevel_ < 40 && window / static_cast<double>(std::uint64_t{1} << (maxLevel_ + 1)) >= minWindow * (1 - 1e-12) &&
         windows < (std::uint64_t{1} << (62 - maxLevel_ - 1)))
    ++maxLevel_;
  endTick_ = windows * ticks(0);
}

bool WindowControl::halve() {
  if (level_ >= maxLevel_) return false;
  ++level_;
  ++halvings_;
  quiet_ = 0;
  if (level_ > smallestLevel_) smallestLevel_ = level_;
  return true;
}

void WindowControl::accept() {
  tick_ += ticks(level_);
  if (level_ > 0) ++quiet_;
  // Double where the doubled window starts on its own grid, and never past the end.
  if (level_ > 0 && growAfter_ > 0 && quiet_ >= growAfter_ && tick_ % ticks(level_ - 1) == 0 &&
      tick_ + ticks(level_ - 1) <= endTick_) {
    --level_;
    quiet_ = 0;
  }
}

void WindowControl::archive(common::StateArchive& a) {
  // Ticks are fractions of the window set by the floor, which a restart may change (the fix of an exit
  // 3 is a lower coupling.min_time_window): they are rescaled to this run's floor.
  int maxLevel = maxLevel_;
  a.io("max_level", maxLevel);
  a.io("tick", tick_);
  a.io("level", level_), a.io("smallest_level", smallestLevel_), a.io("quiet", quiet_);
  a.io("halvings", halvings_);
  if (!a.reading() || maxLevel == maxLevel_) return;
  if (maxLevel < maxLevel_) {
    tick_ <<= (maxLevel_ - maxLevel);
  } else {
    const std::uint64_t factor = std::uint64_t{1} << (maxLevel - maxLevel_);
    if (tick_ % factor != 0)
      throw common::ConfigError(fmt::format("{}: the checkpoint was written inside a window shorter than this run's "
                                            "coupling.min_time_window allows ({:.6g} s); restart with the "
                                            "min_time_window of the run that wrote it, or lower",
                                            a.path().string(), window_ / static_cast<double>(std::uint64_t{1} << maxLevel)));
    tick_ /= factor;
  }
  level_ = std::min(level_, maxLevel_);
  smallestLevel_ = std::min(smallestLevel_, maxLevel_);
}

}  // namespace cosim
