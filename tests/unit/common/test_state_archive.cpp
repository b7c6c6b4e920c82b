#include "common/state_archive.hpp"

#include <fstream>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "common/errors.hpp"

namespace fs = std::filesystem;

namespace {

struct Record {
  Eigen::Vector3d x;
  std::uint32_t id;
  double w;
};

struct Component {
  double time = 0.0;
  std::int64_t steps = 0;
  std::vector<Eigen::Vector3d> positions;
  std::vector<Record> records;
  std::vector<std::vector<std::uint32_t>> lists;
  std::vector<std::string> names;
  std::string label;
  std::array<double, 3> energy{};
  std::pair<std::size_t, std::size_t> range{};
  bool flag = false;
  void archive(common::StateArchive& a) {
    a.io("time", time);
    a.io("steps", steps);
    a.io("positions", positions);
    a.io("records", records);
    a.io("lists", lists);
    a.io("names", names);
    a.io("label", label);
    a.io("energy", energy);
    a.io("range", range);
    a.io("flag", flag);
  }
};

Component sample() {
  Component c;
  c.time = 0.125 + 1e-17;
  c.steps = -(std::int64_t{1} << 40);
  c.positions = {{1.0, 2.0, 3.0}, {std::nextafter(1.0, 2.0), -0.0, 1e-300}};
  c.records = {{{4, 5, 6}, 7u, 8.5}};
  c.lists = {{1, 2, 3}, {}, {4}};
  c.names = {"a", "", "wall/2"};
  c.label = "block";
  c.energy = {1.0, 2.0, 3.0};
  c.range = {3, 9};
  c.flag = true;
  return c;
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "cosim_state_archive_test";
  fs::create_directories(dir);
  fs::remove(dir / name);  // an earlier run's
  return dir / name;
}

void expectSame(const Component& a, const Component& b) {
  EXPECT_EQ(std::memcmp(&a.time, &b.time, sizeof(double)), 0);
  EXPECT_EQ(a.steps, b.steps);
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t i = 0; i < a.positions.size(); ++i) EXPECT_EQ(std::memcmp(a.positions[i].data(), b.positions[i].data(), 24), 0);
  ASSERT_EQ(a.records.size(), b.records.size());
  EXPECT_EQ(a.records[0].x, b.records[0].x);
  EXPECT_EQ(a.records[0].id, b.records[0].id);
  EXPECT_EQ(a.lists, b.lists);
  EXPECT_EQ(a.names, b.names);
  EXPECT_EQ(a.label, b.label);
  EXPECT_EQ(a.energy, b.energy);
  EXPECT_EQ(a.range, b.range);
  EXPECT_EQ(a.flag, b.flag);
}

TEST(StateArchive, WritesAndReadsEveryKindOfValueBitForBit) {
  const fs::path p = scratch("roundtrip.h5");
  Component written = sample();
  {
    auto a = common::StateArchive::create(p, "test");
    a.io("component", written);
    EXPECT_FALSE(fs::exists(p)) << "only the .tmp exists before commit()";
    a.commit();
  }
  ASSERT_TRUE(fs::exists(p));
  EXPECT_FALSE(fs::exists(fs::path(p).concat(".tmp")));
  Component read;
  auto a = common::StateArchive::open(p, "test");
  a.io("component", read);
  expectSame(written, read);
}

TEST(StateArchive, AnUncommittedArchiveLeavesThePreviousFileIntact) {
  const fs::path p = scratch("kept.h5");
  Component first = sample();
  {
    auto a = common::StateArchive::create(p, "test");
    a.io("component", first);
    a.commit();
  }
  {
    Component other;
    auto a = common::StateArchive::create(p, "test");
    a.io("component", other);  // a crash here: no commit
  }
  EXPECT_FALSE(fs::exists(fs::path(p).concat(".tmp")));
  Component read;
  auto a = common::StateArchive::open(p, "test");
  a.io("component", read);
  expectSame(first, read);
}

TEST(StateArchive, RefusesTruncatedDamagedForeignAndIncompleteFiles) {
  const fs::path p = scratch("damaged.h5");
  Component c = sample();
  c.positions.assign(4096, Eigen::Vector3d(1, 2, 3));
  {
    auto a = common::StateArchive::create(p, "test");
    a.io("component", c);
    a.commit();
  }
  EXPECT_THROW(common::StateArchive::open(p, "other"), common::ConfigError);
  EXPECT_THROW(common::StateArchive::open(scratch("missing.h5"), "test"), common::ConfigError);
  {  // a missing dataset is named
    auto a = common::StateArchive::open(p, "test");
    double x = 0;
    try {
      a.io("component/nothing", x);
      ADD_FAILURE() << "no error";
    } catch (const common::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("component/nothing"), std::string::npos) << e.what();
    }
  }
  // Flip bytes inside the positions' data: the checksum refuses them.
  const auto size = fs::file_size(p);
  std::vector<char> bytes(size);
  std::ifstream(p, std::ios::binary).read(bytes.data(), static_cast<std::streamsize>(size));
  const double one = 1.0;
  auto it = std::search(bytes.begin(), bytes.end(), reinterpret_cast<const char*>(&one), reinterpret_cast<const char*>(&one) + 8);
  ASSERT_NE(it, bytes.end());
  std::vector<char> damaged = bytes;
  damaged[static_cast<std::size_t>(it - bytes.begin()) + 3] ^= 0x10;
  const fs::path q = scratch("flipped.h5");
  std::ofstream(q, std::ios::binary).write(damaged.data(), static_cast<std::streamsize>(size));
  {
    Component read;
    auto a = common::StateArchive::open(q, "test");
    EXPECT_THROW(a.io("component", read), common::ConfigError);
  }
  EXPECT_EQ(common::StateArchive::verify(p), "test");
  EXPECT_THROW(common::StateArchive::verify(q), common::ConfigError) << "verify() reads every checksum";
  // Truncated to half its length.
  const fs::path t = scratch("truncated.h5");
  std::ofstream(t, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(size / 2));
  EXPECT_THROW(common::StateArchive::verify(t), common::ConfigError);
  EXPECT_THROW(
      {
        Component read;
        auto a = common::StateArchive::open(t, "test");
        a.io("component", read);
      },
      common::ConfigError);
}

}  // namespace
