#pragma once
// Adaptive coupling windows (coupler/README.md, `coupling.min_time_window`): a window whose coupling iteration diverges is
// repeated from its start as two half windows, down to coupling.min_time_window; after
// coupling.grow_after quiet windows the window doubles again, up to coupling.time_window. Windows stay on
// the grid of halvings of time_window, so a run ends at end_time exactly: a window only doubles where
// the doubled one starts on its own grid.
//
// Pure bookkeeping (no messages, no participants), so the coupler's loop and a unit test drive it alike.
// Times are counted in ticks of the smallest window the floor allows, integers: 3,000 windows of 1e-4 s
// summed as doubles would not land on 0.3 s.

#include <cstdint>

namespace common {
class StateArchive;
}

namespace cosim {

class WindowControl {
 public:
  /// `window` the scene's (largest) window, `minWindow` the floor (≤ window; rounded down to a power-of-two
  /// fraction of it), `growAfter` quiet windows before a doubling (0: never grows back), `windows` the
  /// scene's number of windows (end_time / window).
  WindowControl(double window, double minWindow, int growAfter, std::uint64_t windows);

  double size() const { return window_ / static_cast<double>(std::uint64_t{1} << level_); }
  double time() const { return static_cast<double>(tick_) * tickSeconds(); }
  bool finished() const { return tick_ >= endTick_; }
  /// Halves the window now under way (its start stays); false at the floor.
  bool halve();
  /// The window now under way was accepted: time moves on; the window may double.
  void accept();

  /// Floor of the halvings: min_time_window = window / 2^maxLevel.
  int maxLevel() const { return maxLevel_; }
  bool atFloor() const { return level_ >= maxLevel_; }
  double smallest() const { return window_ / static_cast<double>(std::uint64_t{1} << smallestLevel_); }
  std::int64_t halvings() const { return halvings_; }

  void archive(common::StateArchive& a);

 private:
  double tickSeconds() const { return window_ / static_cast<double>(std::uint64_t{1} << maxLevel_); }
  std::uint64_t ticks(int level) const { return std::uint64_t{1} << (maxLevel_ - level); }

  double window_;
  int maxLevel_, growAfter_;
  std::uint64_t endTick_;
  std::uint64_t tick_ = 0;
  int level_ = 0, smallestLevel_ = 0;
  int quiet_ = 0;
  std::int64_t halvings_ = 0;
};

}  // namespace cosim
