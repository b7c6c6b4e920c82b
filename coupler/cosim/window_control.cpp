#include "window_control.hpp"

#include <cmath>

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
  ++quiet_;
  // Double where the doubled window starts on its own grid, and never past the end.
  if (level_ > 0 && growAfter_ > 0 && quiet_ >= growAfter_ && tick_ % ticks(level_ - 1) == 0 &&
      tick_ + ticks(level_ - 1) <= endTick_) {
    --level_;
    quiet_ = 0;
  }
}

void WindowControl::archive(common::StateArchive& a) {
  a.io("tick", tick_);
  a.io("level", level_), a.io("smallest_level", smallestLevel_), a.io("quiet", quiet_);
  a.io("halvings", halvings_);
}

}  // namespace cosim
