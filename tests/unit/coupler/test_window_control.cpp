// Adaptive coupling windows (cosim/window_control.hpp): halvings down to the floor, doubling back after
// quiet windows on the grid of the halvings, and the end reached exactly.
#include <gtest/gtest.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "temp_dir.hpp"

#include "window_control.hpp"

using cosim::WindowControl;

// 1e-4 s windows to 1e-3 s: a window halved twice runs 2.5e-5 s windows, grows back after 3 quiet
// windows only where the doubled window starts on its own grid, and the run ends at 10 × 1e-4 exactly.
TEST(WindowControl, HalvesToTheFloorAndGrowsBackOnTheGrid) {
  WindowControl c(1e-4, 2.5e-5, 3, 10);
  EXPECT_EQ(c.maxLevel(), 2);
  EXPECT_EQ(c.size(), 1e-4);
  c.accept();
  EXPECT_EQ(c.time(), 1e-4);
  EXPECT_TRUE(c.halve());
  EXPECT_TRUE(c.halve());
  EXPECT_FALSE(c.halve());  // the floor
  EXPECT_EQ(c.size(), 2.5e-5);
  EXPECT_EQ(c.halvings(), 2);
  // Quiet windows of 2.5e-5 s from t = 1e-4: after three the time is 1.75e-4, off the 5e-5 grid; the
  // fourth lands on it and the window doubles.
  for (int i = 0; i < 3; ++i) c.accept();
  EXPECT_EQ(c.size(), 2.5e-5);
  c.accept();
  EXPECT_DOUBLE_EQ(c.time(), 2e-4);
  EXPECT_EQ(c.size(), 5e-5);
  // Three quiet windows of 5e-5 s end at 3.5e-4, off the 1e-4 grid; the fourth at 4e-4 doubles.
  for (int i = 0; i < 4; ++i) c.accept();
  EXPECT_EQ(c.size(), 1e-4);
  EXPECT_DOUBLE_EQ(c.time(), 4e-4);
  int windows = 0;
  while (!c.finished()) {
    c.accept();
    ++windows;
  }
  EXPECT_EQ(windows, 6);
  EXPECT_DOUBLE_EQ(c.time(), 1e-3);
  EXPECT_EQ(c.smallest(), 2.5e-5);
}

// Never past the end: a halved window near the end does not double over it, and the time is counted in
// whole ticks (3,000 windows of 1e-4 s end at 0.3 s to the last bit, as i × window does).
TEST(WindowControl, EndsExactlyAtTheEnd) {
  WindowControl c(1e-4, 1e-4 / 16, 1, 3000);
  for (int i = 0; i < 2999; ++i) c.accept();
  EXPECT_TRUE(c.halve());
  c.accept();  // 2999.5 windows: quiet, but doubling would overrun the end
  EXPECT_EQ(c.size(), 5e-5);
  c.accept();
  EXPECT_TRUE(c.finished());
  EXPECT_EQ(c.time(), 3000 * 1e-4);
  WindowControl fixed(1e-4, 1e-4, 20, 3000);
  EXPECT_EQ(fixed.maxLevel(), 0);
  EXPECT_FALSE(fixed.halve());
  for (int i = 0; i < 1234; ++i) fixed.accept();
  EXPECT_EQ(fixed.time(), static_cast<double>(1234) * 1e-4);
}

// A restart may lower coupling.min_time_window (the fix an exit 3 prints): the saved time is rescaled to
// the new floor's ticks; a raised floor that the saved time is not on is a located input error.
TEST(WindowControl, ARestartRescalesToItsOwnFloor) {
  const TempDir dir;
  const auto file = dir.path() / "control.h5";
  WindowControl saved(1e-4, 2.5e-5, 20, 100);
  saved.accept();
  ASSERT_TRUE(saved.halve());
  ASSERT_TRUE(saved.halve());
  saved.accept();  // t = 1.25e-4, in a 2.5e-5 s window
  {
    auto a = common::StateArchive::create(file, "test");
    saved.archive(a);
    a.commit();
  }
  WindowControl lower(1e-4, 1e-4 / 64, 20, 100);
  {
    auto a = common::StateArchive::open(file, "test");
    lower.archive(a);
  }
  EXPECT_DOUBLE_EQ(lower.time(), 1.25e-4);
  EXPECT_EQ(lower.size(), 2.5e-5);
  EXPECT_EQ(lower.halvings(), 2);
  WindowControl higher(1e-4, 1e-4, 20, 100);
  auto a = common::StateArchive::open(file, "test");
  EXPECT_THROW(higher.archive(a), common::ConfigError);
}
