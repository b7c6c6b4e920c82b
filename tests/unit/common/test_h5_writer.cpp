#include "common/h5_writer.hpp"

#include <fstream>
#include <regex>
#include <sstream>

#include <gtest/gtest.h>
#include <hdf5.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "sample_run.hpp"
#include "temp_dir.hpp"

using common::CellType;
using common::Field;
using common::H5Writer;

namespace {

std::vector<hsize_t> shapeOf(hid_t file, const std::string& path) {
  if (H5Lexists(file, path.c_str(), H5P_DEFAULT) <= 0) return {};
  hid_t ds = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (ds < 0) return {};
  hid_t space = H5Dget_space(ds);
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  H5Sclose(space);
  H5Dclose(ds);
  return dims;
}

std::vector<double> readDoubles(hid_t file, const std::string& path) {
  std::size_t n = 1;
  for (auto d : shapeOf(file, path)) n *= d;
  std::vector<double> v(n);
  hid_t ds = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  EXPECT_GE(ds, 0) << path;
  if (ds >= 0) {
    H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(ds);
  }
  return v;
}

double readTime(hid_t file, const std::string& group) {
  double t = -1;
  hid_t attr = H5Aopen_by_name(file, group.c_str(), "time", H5P_DEFAULT, H5P_DEFAULT);
  EXPECT_GE(attr, 0) << group;
  H5Aread(attr, H5T_NATIVE_DOUBLE, &t);
  H5Aclose(attr);
  return t;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST(H5Writer, TimeSeriesReadBack) {
  TempDir dir;
  const auto file = dir.path() / "run.h5";
  writeSampleRun(file);
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const auto t = readDoubles(f, "/timeseries/energy/time");
  const auto k = readDoubles(f, "/timeseries/energy/kinetic");
  const auto p = readDoubles(f, "/timeseries/energy/potential");
  ASSERT_EQ(t.size(), 101u);
  ASSERT_EQ(k.size(), 101u);
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_DOUBLE_EQ(t[i], 0.01 * static_cast<double>(i));
    EXPECT_DOUBLE_EQ(k[i] + p[i], 0.5);  // stored exactly what was appended
  }
  EXPECT_DOUBLE_EQ(readDoubles(f, "/timeseries/block/vz")[100], -9.81);
  H5Fclose(f);
}

TEST(H5Writer, SnapshotsReadBack) {
  TempDir dir;
  const auto file = dir.path() / "run.h5";
  writeSampleRun(file);
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_EQ(shapeOf(f, "/meshes/membrane/nodes"), (std::vector<hsize_t>{4, 3}));
  EXPECT_EQ(shapeOf(f, "/meshes/membrane/cells"), (std::vector<hsize_t>{2, 3}));
  EXPECT_DOUBLE_EQ(readTime(f, "/meshes/membrane/steps/000002"), 0.2);
  EXPECT_DOUBLE_EQ(readDoubles(f, "/meshes/membrane/steps/000002/point/displacement")[11], -0.06);
  EXPECT_DOUBLE_EQ(readDoubles(f, "/meshes/membrane/steps/000002/nodes")[11], -0.06);
  EXPECT_EQ(shapeOf(f, "/meshes/membrane/steps/000001/nodes"), std::vector<hsize_t>{});  // not moved: not stored
  EXPECT_EQ(readDoubles(f, "/meshes/membrane/steps/000002/cell/stress"), (std::vector<double>{2.0, 4.0}));
  EXPECT_EQ(shapeOf(f, "/particles/spheres/steps/000001/position"), (std::vector<hsize_t>{3, 3}));
  EXPECT_DOUBLE_EQ(readTime(f, "/particles/spheres/steps/000001"), 0.5);
  H5Fclose(f);
}

// Every DataItem the XDMF names must exist in the .h5 with exactly the declared dimensions, and every
// temporal grid must list its snapshots' times.
TEST(H5Writer, XdmfNamesExistingDatasetsWithDeclaredShapes) {
  TempDir dir;
  const auto file = dir.path() / "run.h5";
  writeSampleRun(file);
  const std::string xdmf = slurp(dir.path() / "run.xdmf");
  ASSERT_FALSE(xdmf.empty());
  EXPECT_EQ(xdmf.find("<?xml"), 0u);
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const std::regex item(R"re(<DataItem Dimensions="([0-9 ]+)"[^>]*Format="HDF">([^:<]+):([^<]+)</DataItem>)re");
  int items = 0;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), item); it != std::sregex_iterator(); ++it) {
    ++items;
    const std::string dims = (*it)[1], h5 = (*it)[2], path = (*it)[3];
    EXPECT_EQ(h5, "run.h5");  // relative: the results folder can be moved
    std::vector<hsize_t> declared;
    std::istringstream ds(dims);
    for (hsize_t d; ds >> d;) declared.push_back(d);
    EXPECT_EQ(shapeOf(f, path), declared) << path;
  }
  H5Fclose(f);
  EXPECT_EQ(items, 3 * 4 + 2 * 2);  // mesh: cells, nodes, 2 fields per snapshot; particles: position, radius
  const std::regex time(R"re(<Time Value="([^"]+)"/>)re");
  std::vector<double> times;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), time); it != std::sregex_iterator(); ++it)
    times.push_back(std::stod((*it)[1]));
  EXPECT_EQ(times, (std::vector<double>{0.0, 0.1, 0.2, 0.0, 0.5}));
  EXPECT_NE(xdmf.find("TopologyType=\"Polyvertex\" NumberOfElements=\"3\""), std::string::npos);
  EXPECT_NE(xdmf.find("AttributeType=\"Vector\" Center=\"Node\""), std::string::npos);
  EXPECT_NE(xdmf.find("AttributeType=\"Scalar\" Center=\"Cell\""), std::string::npos);
}

TEST(H5Writer, ShapeErrorsNameTheDataset) {
  TempDir dir;
  H5Writer w(dir.path() / "bad.h5");
  w.addSeries("s", {"a", "b"});
  try {
    w.append("s", 0.0, std::vector<double>{1.0});
    FAIL() << "expected SimulationError";
  } catch (const common::SimulationError& e) {
    EXPECT_STREQ(e.what(),
                 "HDF5 output bad.h5: row has 1 values, the series has 2 columns besides time (dataset /timeseries/s).");
  }
  const std::vector<double> nodes{0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<std::int64_t> cells{0, 1, 2};
  w.addMesh("m", nodes, cells, CellType::kTriangle);
  const std::vector<double> shortField{1.0, 2.0};
  EXPECT_THROW(w.writeMeshSnapshot("m", 0.0, {}, {Field{"u", 1, shortField}}), common::SimulationError);
}

namespace {

std::vector<double> xdmfTimes(const std::string& xdmf) {
  const std::regex time(R"re(<Time Value="([^"]+)"/>)re");
  std::vector<double> out;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), time); it != std::sregex_iterator(); ++it)
    out.push_back(std::stod((*it)[1]));
  return out;
}

const std::vector<double> kNodes{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
const std::vector<std::int64_t> kCells{0, 1, 2, 0, 2, 3};

// The mesh part of a run; `value` fills every field, so a snapshot tells which run wrote it.
void meshSnapshot(H5Writer& w, double time, double value) {
  const std::vector<double> u(12, value), stress{value, value};
  w.writeMeshSnapshot("membrane", time, {}, {Field{"displacement", 3, u}}, {Field{"stress", 1, stress}});
}

void particleSnapshot(H5Writer& w, double time, std::size_t n) {
  const std::vector<double> pos(3 * n, time), radius(n, 0.05);
  w.writeParticles("spheres", time, pos, {Field{"radius", 1, radius}});
}

void networkSnapshot(H5Writer& w, double time) {
  const std::vector<double> points{0, 0, 0, 1, 0, 0, 1, 1, 0}, force{time, 2 * time};
  const std::vector<std::int64_t> lines{0, 1, 1, 2};
  w.writeLines("contacts", time, points, lines, {Field{"force", 1, force}});
}

}  // namespace

// A restart from a checkpoint taken after 6 rows, 2 mesh, 1 particle and 1 network snapshots: the file
// keeps exactly those, what the first run wrote later is gone, and the restarted run continues after them.
TEST(H5Writer, ResumeCutsBackToTheCheckpointAndAppends) {
  TempDir dir;
  const auto file = dir.path() / "run.h5";
  const auto archive = dir.path() / "checkpoint.h5";
  std::string atCheckpoint;
  {
    H5Writer w(file);
    w.addSeries("energy", {"kinetic"});
    w.addMesh("membrane", kNodes, kCells, CellType::kTriangle);
    for (int i = 0; i < 6; ++i) w.append("energy", 0.1 * i, std::vector<double>{1.0 * i});
    meshSnapshot(w, 0.0, 1.0);
    meshSnapshot(w, 0.1, 2.0);
    particleSnapshot(w, 0.0, 2);
    networkSnapshot(w, 0.0);
    w.writeArray("/state/table", std::vector<double>{1, 2});
    common::H5Extent extent = w.checkpoint();
    atCheckpoint = slurp(dir.path() / "run.xdmf");
    auto a = common::StateArchive::create(archive, "test");  // as a solver stores it with its state
    a.io("results", extent);
    a.commit();
    for (int i = 6; i < 10; ++i) w.append("energy", 0.1 * i, std::vector<double>{1.0 * i});
    meshSnapshot(w, 0.2, 3.0);
    particleSnapshot(w, 0.5, 3);
    networkSnapshot(w, 0.5);
    w.addSeries("late", {"x"});  // declared after the checkpoint: the restart removes it
    w.append("late", 0.7, std::vector<double>{7.0});
  }
  common::H5Extent extent;
  auto a = common::StateArchive::open(archive, "test");
  a.io("results", extent);
  {
    H5Writer w(file, extent);
    // The snapshots rebuilt from the file are described as the first run described them.
    EXPECT_EQ(slurp(dir.path() / "run.xdmf"), atCheckpoint);
    w.addSeries("energy", {"kinetic"});
    w.addMesh("membrane", kNodes, kCells, CellType::kTriangle);
    for (int i = 0; i < 4; ++i) w.append("energy", 1.0 + 0.1 * i, std::vector<double>{100.0 + i});
    meshSnapshot(w, 0.15, 9.0);
    w.writeArray("/state/table", std::vector<double>{3, 4, 5});
  }
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_EQ(readDoubles(f, "/timeseries/energy/kinetic"), (std::vector<double>{0, 1, 2, 3, 4, 5, 100, 101, 102, 103}));
  EXPECT_DOUBLE_EQ(readDoubles(f, "/timeseries/energy/time")[6], 1.0);
  EXPECT_EQ(H5Lexists(f, "/timeseries/late", H5P_DEFAULT), 0);
  EXPECT_DOUBLE_EQ(readDoubles(f, "/meshes/membrane/steps/000001/point/displacement")[0], 2.0);  // kept
  EXPECT_DOUBLE_EQ(readTime(f, "/meshes/membrane/steps/000002"), 0.15);                          // the new one
  EXPECT_EQ(readDoubles(f, "/meshes/membrane/steps/000002/cell/stress"), (std::vector<double>{9.0, 9.0}));
  EXPECT_EQ(H5Lexists(f, "/meshes/membrane/steps/000003", H5P_DEFAULT), 0);
  EXPECT_EQ(H5Lexists(f, "/particles/spheres/steps/000000", H5P_DEFAULT), 1);
  EXPECT_EQ(H5Lexists(f, "/particles/spheres/steps/000001", H5P_DEFAULT), 0);
  EXPECT_EQ(H5Lexists(f, "/networks/contacts/steps/000001", H5P_DEFAULT), 0);
  EXPECT_EQ(readDoubles(f, "/state/table"), (std::vector<double>{3, 4, 5}));
  H5Fclose(f);
  const std::string xdmf = slurp(dir.path() / "run.xdmf");
  EXPECT_EQ(xdmfTimes(xdmf), (std::vector<double>{0.0, 0.1, 0.15, 0.0, 0.0}));  // membrane, spheres, contacts
  for (const char* grid : {"membrane_2", "spheres_0", "contacts_0", "Polyvertex\" NumberOfElements=\"2\""})
    EXPECT_NE(xdmf.find(grid), std::string::npos) << grid;
  EXPECT_EQ(xdmf.find("membrane_3"), std::string::npos);
  EXPECT_EQ(xdmf.find("spheres_1"), std::string::npos);
}

TEST(H5Writer, ResumeWithOtherColumnsThrowsNamingFileAndSeries) {
  TempDir dir;
  const auto file = dir.path() / "run.h5";
  common::H5Extent extent;
  {
    H5Writer w(file);
    w.addSeries("s", {"a", "b"});
    w.append("s", 0.0, std::vector<double>{1.0, 2.0});
    extent = w.checkpoint();
  }
  H5Writer w(file, extent);
  try {
    w.addSeries("s", {"a", "c"});
    FAIL() << "expected SimulationError";
  } catch (const common::SimulationError& e) {
    EXPECT_STREQ(e.what(),
                 "HDF5 output run.h5: the file's series has columns a, b, time, the restarted program declares time, "
                 "a, c; a restart must declare the series of the run that wrote the file (dataset /timeseries/s).");
  }
}

TEST(H5Writer, ResumeOfAMissingFileThrows) {
  TempDir dir;
  const auto file = dir.path() / "gone.h5";
  try {
    H5Writer w(file, common::H5Extent{});
    FAIL() << "expected SimulationError";
  } catch (const common::SimulationError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}
