#include "common/h5_writer.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <hdf5.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace common {

namespace fs = std::filesystem;

namespace {

// Owns one HDF5 identifier; closes it with the matching H5?close.
class Handle {
 public:
  Handle() = default;
  Handle(hid_t id, herr_t (*closer)(hid_t)) : id_(id), closer_(closer) {}
  Handle(Handle&& o) noexcept : id_(o.id_), closer_(o.closer_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept {
    std::swap(id_, o.id_);
    std::swap(closer_, o.closer_);
    return *this;
  }
  ~Handle() {
    if (id_ >= 0 && closer_) closer_(id_);
  }
  hid_t get() const { return id_; }

 private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*closer_)(hid_t) = nullptr;
};

struct DataItem {
  std::string path;
  std::vector<std::size_t> dims;
  bool integer = false;
};

struct AttributeRef {
  std::string name;
  int components;
  bool cellCentred;
  DataItem item;
};

struct SnapshotRef {
  double time;
  DataItem geometry;
  std::size_t cellCount;  // mesh cells, or particle count for polyvertex
  std::vector<AttributeRef> attributes;
  DataItem cells;  // a network's own topology (lines change between snapshots); empty: the grid's
};

struct GridRef {
  bool particles = false;
  CellType type = CellType::kTriangle;
  DataItem nodes, cells;
  std::vector<SnapshotRef> snapshots;
};

struct SeriesRef {
  std::vector<std::string> columns;  // including "time"
  std::vector<Handle> datasets;
  hsize_t rows = 0;                    // rows in the file
  std::vector<double> pending;         // appended rows not yet written, row-major
};

// Rows are written in blocks: extending a dataset row by row costs an HDF5 call per column and row.
constexpr std::size_t kBlockRows = 256;

const char* topologyName(CellType t) {
  switch (t) {
    case CellType::kLine: return "Polyline\" NodesPerElement=\"2";
    case CellType::kTriangle: return "Triangle";
    case CellType::kTetrahedron: return "Tetrahedron";
  }
  return "?";
}

const char* attributeType(int components) {
  switch (components) {
    case 1: return "Scalar";
    case 3: return "Vector";
    case 6: return "Tensor6";
    case 9: return "Tensor";
    default: return "Matrix";
  }
}

std::string dimsText(const std::vector<std::size_t>& dims) {
  return fmt::format("{}", fmt::join(dims, " "));
}

std::string stepGroup(const std::string& grid, std::size_t i) { return fmt::format("{}/steps/{:06d}", grid, i); }

std::map<std::string, std::uint64_t> byName(const std::vector<std::string>& names,
                                            const std::vector<std::uint64_t>& counts) {
  COSIM_ASSERT(names.size() == counts.size(), "an H5Extent with {} names and {} counts", names.size(), counts.size());
  std::map<std::string, std::uint64_t> out;
  for (std::size_t i = 0; i < std::min(names.size(), counts.size()); ++i) out.emplace(names[i], counts[i]);
  return out;
}

}  // namespace

void H5Extent::archive(StateArchive& a) {
  a.io("series", series);
  a.io("rows", rows);
  a.io("grids", grids);
  a.io("snapshots", snapshots);
}

struct H5Writer::Impl {
  Handle file;
  std::string fileName;  // basename used inside the XDMF, so the results folder can be moved
  std::map<std::string, SeriesRef> series;
  std::map<std::string, GridRef> grids;  // meshes and particle sets, by XDMF grid name
  std::vector<std::string> gridOrder;
  bool resumed = false;
  std::set<std::string> meshesToRedeclare;  // resumed from the file, not yet declared again by addMesh

  explicit Impl(const fs::path& h5Path) : fileName(h5Path.filename().string()) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // our own messages name the file and dataset
  }

  [[noreturn]] void fail(const std::string& what, const std::string& dataset) const {
    throw SimulationError(fmt::format("HDF5 output {}: {} (dataset {}).", fileName, what, dataset));
  }

  // The backstop of "never a NaN in an output file": a solver's own checks should have
  // stopped the run first, so reaching this is an instability the solver did not name.
  void requireFinite(std::span<const double> values, double time, const std::string& dataset) const {
    for (std::size_t i = 0; i < values.size(); ++i)
      if (!std::isfinite(values[i]))
        throw InstabilityError({"non-finite value in the output", fmt::format("{} entry {}", dataset, i), time,
                                fmt::format("{} = {} was about to be written to {}", dataset, values[i], fileName),
                                "lower the time step; the solver's own checks missed this, please report it"});
  }

  // A failing check (a missing parent group) counts as absent.
  bool exists(const std::string& path) const { return H5Lexists(file.get(), path.c_str(), H5P_DEFAULT) > 0; }

  void remove(const std::string& path) {
    if (H5Ldelete(file.get(), path.c_str(), H5P_DEFAULT) < 0) fail("cannot remove", path);
  }

  std::vector<std::string> children(const std::string& group) const {
    std::vector<std::string> names;
    if (!exists(group)) return names;
    auto collect = [](hid_t, const char* name, const H5L_info_t*, void* out) -> herr_t {
      static_cast<std::vector<std::string>*>(out)->push_back(name);
      return 0;
    };
    if (H5Literate_by_name(file.get(), group.c_str(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names,
                           H5P_DEFAULT) < 0)
      fail("cannot list group", group);
    return names;
  }

  DataItem readItem(const std::string& path) const {
    Handle ds(H5Dopen2(file.get(), path.c_str(), H5P_DEFAULT), H5Dclose);
    if (ds.get() < 0) fail("missing from the file the checkpoint describes", path);
    Handle space(H5Dget_space(ds.get()), H5Sclose), type(H5Dget_type(ds.get()), H5Tclose);
    std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(H5Sget_simple_extent_ndims(space.get()), 0)));
    H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
    return {path, {dims.begin(), dims.end()}, H5Tget_class(type.get()) == H5T_INTEGER};
  }

  std::vector<AttributeRef> readFields(const std::string& group, bool cellCentred,
                                       const std::set<std::string>& skip = {}) const {
    std::vector<AttributeRef> out;
    for (const auto& name : children(group))
      if (!skip.count(name)) {
        DataItem d = readItem(group + "/" + name);
        const int components = d.dims.size() > 1 ? static_cast<int>(d.dims[1]) : 1;
        out.push_back({name, components, cellCentred, std::move(d)});
      }
    return out;
  }

  // The inverse of writeMeshSnapshot, writeParticles and writeLines, for a snapshot a restart keeps.
  SnapshotRef readSnapshot(const GridRef& g, const std::string& step) const {
    SnapshotRef s{0.0, g.nodes, 0, {}, {}};
    Handle attr(H5Aopen_by_name(file.get(), step.c_str(), "time", H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (attr.get() < 0 || H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &s.time) < 0)
      fail("snapshot missing from the file the checkpoint describes", step);
    if (g.particles) {
      s.geometry = readItem(step + "/position");
      s.cellCount = s.geometry.dims[0];
      s.attributes = readFields(step, false, {"position"});
    } else if (g.cells.path.empty()) {  // a network: points and lines of its own in each snapshot
      s.geometry = readItem(step + "/points");
      s.cells = readItem(step + "/lines");
      s.cellCount = s.cells.dims[0];
      s.attributes = readFields(step, true, {"points", "lines"});
    } else {
      if (exists(step + "/nodes")) s.geometry = readItem(step + "/nodes");
      s.cellCount = g.cells.dims[0];
      s.attributes = readFields(step + "/point", false);
      auto cellAttrs = readFields(step + "/cell", true);
      s.attributes.insert(s.attributes.end(), cellAttrs.begin(), cellAttrs.end());
    }
    return s;
  }

  // Cuts the earlier run's file back to `extent`. What the checkpoint does not know was written after it
  // and goes; what it keeps must be there, else this is not the file the checkpoint was taken with.
  // A restart's results: a new file holding what `extent` keeps of the old one (`file`, read-only), read
  // object by object, so whatever a killed process left half-written beyond the checkpoint (a link to
  // an object that never reached the disk cannot even be deleted) is never opened; it then replaces the
  // old file.
  void rebuild(const fs::path& path, const H5Extent& extent) {
    const auto rows = byName(extent.series, extent.rows);
    const auto snapshots = byName(extent.grids, extent.snapshots);
    const fs::path tmp = fs::path(path).concat(".resume");
    {
      Handle dst(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
      if (dst.get() < 0) fail("cannot create the file to resume into", tmp.string());
      const Handle lcpl = linkProps();
      auto copy = [&](const std::string& p) {
        if (H5Ocopy(file.get(), p.c_str(), dst.get(), p.c_str(), H5P_DEFAULT, lcpl.get()) < 0)
          fail("cannot copy what the checkpoint keeps (the file was damaged before it, or is another run's)", p);
      };
      for (const auto& top : children("/")) {
        const std::string root = "/" + top;
        if (root == "/timeseries") {
          for (const auto& name : children(root)) {
            const auto kept = rows.find(name);
            if (kept == rows.end()) continue;
            for (const auto& column : children(root + "/" + name)) {
              const std::string p = root + "/" + name + "/" + column;
              hsize_t n = kept->second;
              if (const auto held = readItem(p).dims.at(0); held < n)
                fail(fmt::format("the file holds {} rows, the checkpoint {}", held, n), p);
              std::vector<double> values(n);
              if (n > 0) {
                Handle ds(H5Dopen2(file.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
                Handle space(H5Dget_space(ds.get()), H5Sclose), mem(H5Screate_simple(1, &n, nullptr), H5Sclose);
                const hsize_t first = 0;
                H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, &first, nullptr, &n, nullptr);
                if (H5Dread(ds.get(), H5T_NATIVE_DOUBLE, mem.get(), space.get(), H5P_DEFAULT, values.data()) < 0)
                  fail("cannot read the rows the checkpoint keeps", p);
              }
              hsize_t maxDims = H5S_UNLIMITED, chunk = 1024;
              Handle space(H5Screate_simple(1, &n, &maxDims), H5Sclose), dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
              H5Pset_chunk(dcpl.get(), 1, &chunk);
              Handle ds(H5Dcreate2(dst.get(), p.c_str(), H5T_IEEE_F64LE, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT),
                        H5Dclose);
              if (ds.get() < 0 || (n > 0 && H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT,
                                                     values.data()) < 0))
                fail("cannot write the rows the checkpoint keeps", tmp.string() + ":" + p);
            }
          }
        } else if (root == "/meshes" || root == "/particles" || root == "/networks") {
          for (const auto& name : children(root)) {
            const auto kept = snapshots.find(name);
            if (kept == snapshots.end()) continue;
            const std::string base = root + "/" + name;
            for (const auto& child : children(base))
              if (child != "steps") copy(base + "/" + child);
            for (std::size_t i = 0; i < kept->second; ++i) copy(stepGroup(base, i));
          }
        } else {
          copy(root);
        }
      }
      if (H5Fflush(dst.get(), H5F_SCOPE_GLOBAL) < 0) fail("cannot flush", tmp.string());
    }
    file = Handle();
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) fail(fmt::format("cannot replace the file by its resumed copy: {}", ec.message()), tmp.string());
  }

  void resume(const H5Extent& extent) {
    const auto rows = byName(extent.series, extent.rows);
    for (const auto& name : children("/timeseries")) {
      const std::string group = "/timeseries/" + name;
      auto kept = rows.find(name);
      if (kept == rows.end()) {
        remove(group);
        continue;
      }
      for (const auto& column : children(group)) {
        const std::string path = group + "/" + column;
        hsize_t n = kept->second;
        if (const auto held = readItem(path).dims.at(0); held < n)
          fail(fmt::format("the file holds {} rows, the checkpoint {}", held, n), path);
        Handle ds(H5Dopen2(file.get(), path.c_str(), H5P_DEFAULT), H5Dclose);
        if (H5Dset_extent(ds.get(), &n) < 0) fail("cannot cut back to the checkpoint", path);
      }
    }
    const auto snapshots = byName(extent.grids, extent.snapshots);
    for (const std::string root : {"/meshes", "/particles", "/networks"})
      for (const auto& name : children(root)) {
        const std::string base = root + "/" + name;
        auto kept = snapshots.find(name);
        if (kept == snapshots.end()) {
          remove(base);
          continue;
        }
        GridRef g;
        g.particles = root == "/particles";
        if (root == "/meshes") {
          g.nodes = readItem(base + "/nodes");
          g.cells = readItem(base + "/cells");
          g.type = static_cast<CellType>(g.cells.dims.at(1));
          meshesToRedeclare.insert(name);
        } else {
          g.type = CellType::kLine;  // a network's; unused for particles
        }
        for (std::size_t i = 0; i < kept->second; ++i) g.snapshots.push_back(readSnapshot(g, stepGroup(base, i)));
        for (const auto& step : children(base + "/steps"))
          if (std::stoull(step) >= kept->second) remove(base + "/steps/" + step);
        grids.emplace(name, std::move(g));
      }
    for (const auto& [name, n] : rows)
      if (n > 0 && !exists("/timeseries/" + name))
        fail(fmt::format("the checkpoint keeps {} rows of it, the file has none", n), "/timeseries/" + name);
    for (const auto& name : extent.grids)
      if (grids.count(name)) gridOrder.push_back(name);
      else if (snapshots.at(name) > 0)
        fail(fmt::format("the checkpoint keeps {} snapshots of grid \"{}\", the file has no grid of that name",
                         snapshots.at(name), name),
             "/");
  }

  Handle linkProps() const {
    Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
    H5Pset_create_intermediate_group(lcpl.get(), 1);
    return lcpl;
  }

  DataItem writeArray(const std::string& path, const void* data, hid_t memType, std::size_t rows, std::size_t cols) {
    std::vector<hsize_t> dims{rows};
    if (cols > 1) dims.push_back(cols);
    Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
    const hid_t fileType = memType == H5T_NATIVE_DOUBLE ? H5T_IEEE_F64LE : H5T_STD_I64LE;
    Handle lcpl = linkProps();
    Handle ds(H5Dcreate2(file.get(), path.c_str(), fileType, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT),
              H5Dclose);
    if (ds.get() < 0) fail("cannot create dataset", path);
    if (rows * cols > 0 && H5Dwrite(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
      fail("cannot write dataset", path);
    DataItem item{path, {rows}, memType != H5T_NATIVE_DOUBLE};
    if (cols > 1) item.dims.push_back(cols);
    return item;
  }

  void setTime(const std::string& group, double time) {
    Handle g(H5Gopen2(file.get(), group.c_str(), H5P_DEFAULT), H5Gclose);
    Handle space(H5Screate(H5S_SCALAR), H5Sclose);
    Handle attr(H5Acreate2(g.get(), "time", H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (attr.get() < 0 || H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &time) < 0) fail("cannot write time attribute", group);
  }

  std::vector<AttributeRef> writeFields(const std::string& base, const std::vector<Field>& fields, std::size_t rows,
                                        bool cellCentred) {
    std::vector<AttributeRef> out;
    for (const auto& f : fields) {
      const std::string path = base + f.name;
      if (f.components < 1 || f.data.size() != rows * static_cast<std::size_t>(f.components))
        fail(fmt::format("field \"{}\" has {} values, expected {} rows × {} components", f.name, f.data.size(), rows,
                         f.components),
             path);
      out.push_back({f.name, f.components, cellCentred,
                     writeArray(path, f.data.data(), H5T_NATIVE_DOUBLE, rows, static_cast<std::size_t>(f.components))});
    }
    return out;
  }

  void writePending(const std::string& name, SeriesRef& s) {
    const std::size_t cols = s.columns.size();
    const hsize_t n = s.pending.size() / cols;
    if (n == 0) return;
    const hsize_t newSize = s.rows + n;
    Handle mem(H5Screate_simple(1, &n, nullptr), H5Sclose);
    std::vector<double> column(n);
    for (std::size_t c = 0; c < cols; ++c) {
      for (hsize_t r = 0; r < n; ++r) column[r] = s.pending[r * cols + c];
      hid_t ds = s.datasets[c].get();
      H5Dset_extent(ds, &newSize);
      Handle space(H5Dget_space(ds), H5Sclose);
      H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, &s.rows, nullptr, &n, nullptr);
      if (H5Dwrite(ds, H5T_NATIVE_DOUBLE, mem.get(), space.get(), H5P_DEFAULT, column.data()) < 0)
        fail("cannot append", fmt::format("/timeseries/{}/{}", name, s.columns[c]));
    }
    s.rows = newSize;
    s.pending.clear();
  }

  std::string item(const DataItem& d) const {
    return fmt::format(
        "<DataItem Dimensions=\"{}\" NumberType=\"{}\" Precision=\"8\" Format=\"HDF\">{}:{}</DataItem>",
        dimsText(d.dims), d.integer ? "Int" : "Float", fileName, d.path);
  }

  void writeXdmf(const fs::path& xdmf) const {
    // A Domain without a grid is no file for ParaView (5.11's reader crashes on it): no snapshot, no
    // sidecar — the time series are read from the .h5 (tools/plot_timeseries.py).
    const bool anyGrid = std::any_of(grids.begin(), grids.end(), [](const auto& g) { return !g.second.snapshots.empty(); });
    if (!anyGrid) {
      std::error_code ec;
      fs::remove(xdmf, ec);
      return;
    }
    const fs::path tmp = fs::path(xdmf).concat(".tmp");
    {
      std::ofstream out(tmp);
      if (!out) throw SimulationError(fmt::format("cannot write XDMF file {}.", tmp.string()));
      out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n";
      for (const auto& name : gridOrder) {
        const GridRef& g = grids.at(name);
        if (g.snapshots.empty()) continue;
        out << fmt::format("  <Grid Name=\"{}\" GridType=\"Collection\" CollectionType=\"Temporal\">\n", name);
        for (std::size_t i = 0; i < g.snapshots.size(); ++i) {
          const SnapshotRef& s = g.snapshots[i];
          out << fmt::format("   <Grid Name=\"{}_{}\" GridType=\"Uniform\">\n    <Time Value=\"{:.17g}\"/>\n", name, i,
                             s.time);
          if (g.particles)
            out << fmt::format(
                "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"{}\" NodesPerElement=\"1\"/>\n",
                s.cellCount);
          else
            out << fmt::format("    <Topology TopologyType=\"{}\" NumberOfElements=\"{}\">\n     {}\n    </Topology>\n",
                               topologyName(g.type), s.cellCount, item(s.cells.path.empty() ? g.cells : s.cells));
          out << fmt::format("    <Geometry GeometryType=\"XYZ\">\n     {}\n    </Geometry>\n", item(s.geometry));
          for (const auto& a : s.attributes)
            out << fmt::format(
                "    <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"{}\">\n     {}\n    </Attribute>\n", a.name,
                attributeType(a.components), a.cellCentred ? "Cell" : "Node", item(a.item));
          out << "   </Grid>\n";
        }
        out << "  </Grid>\n";
      }
      out << " </Domain>\n</Xdmf>\n";
      if (!out) throw SimulationError(fmt::format("cannot write XDMF file {}.", tmp.string()));
    }
    fs::rename(tmp, xdmf);
  }
};

H5Writer::H5Writer(const fs::path& h5Path) : path_(h5Path), impl_(std::make_unique<Impl>(h5Path)) {
  if (h5Path.has_parent_path()) fs::create_directories(h5Path.parent_path());
  impl_->file = Handle(H5Fcreate(h5Path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (impl_->file.get() < 0) throw SimulationError(fmt::format("cannot create HDF5 file {}.", h5Path.string()));
  // Readable from the first moment: a process killed before its first row leaves a valid, empty file
  // (not 96 bytes of superblock nobody can open, issue 30).
  flush();
}

bool H5Writer::resumed() const { return impl_->resumed; }

H5Writer::H5Writer(const fs::path& h5Path, const H5Extent& extent)
    : path_(h5Path), impl_(std::make_unique<Impl>(h5Path)) {
  auto reopen = [&](unsigned mode) {
    impl_->file = Handle(H5Fopen(h5Path.c_str(), mode, H5P_DEFAULT), H5Fclose);
    if (impl_->file.get() < 0)
      throw SimulationError(fmt::format(
          "cannot reopen HDF5 file {} to resume from a checkpoint: it is missing or unreadable, and a restart "
          "appends to the file of the run that wrote the checkpoint. Restore that file, or start the run afresh.",
          h5Path.string()));
  };
  reopen(H5F_ACC_RDONLY);
  impl_->rebuild(h5Path, extent);
  reopen(H5F_ACC_RDWR);
  impl_->resumed = true;
  impl_->resume(extent);
  flush();
}

H5Writer::~H5Writer() {
  try {
    flush();
  } catch (...) {
    // A destructor must not throw; the last explicit flush() already reported any problem.
  }
}

fs::path H5Writer::xdmfPath() const { return fs::path(path_).replace_extension(".xdmf"); }

void H5Writer::addSeries(const std::string& name, const std::vector<std::string>& columns) {
  const std::string group = "/timeseries/" + name;
  if (impl_->series.count(name)) impl_->fail("time series declared twice", group);
  SeriesRef s;
  s.columns.push_back("time");
  s.columns.insert(s.columns.end(), columns.begin(), columns.end());
  // Only a resumed file holds the group already (cut back to the checkpoint): the series continues.
  if (impl_->exists(group)) {
    auto inFile = impl_->children(group), declared = s.columns;
    std::sort(declared.begin(), declared.end());  // children() lists by name
    if (inFile != declared)
      impl_->fail(fmt::format("the file's series has columns {}, the restarted program declares {}; a restart "
                              "must declare the series of the run that wrote the file",
                              fmt::join(inFile, ", "), fmt::join(s.columns, ", ")),
                  group);
    for (const auto& col : s.columns)
      s.datasets.emplace_back(H5Dopen2(impl_->file.get(), (group + "/" + col).c_str(), H5P_DEFAULT), H5Dclose);
    s.rows = impl_->readItem(group + "/time").dims.at(0);
    impl_->series.emplace(name, std::move(s));
    return;
  }
  for (const auto& col : s.columns) {
    const std::string path = group + "/" + col;
    hsize_t dims = 0, maxDims = H5S_UNLIMITED, chunk = 1024;
    Handle space(H5Screate_simple(1, &dims, &maxDims), H5Sclose);
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl.get(), 1, &chunk);
    Handle lcpl = impl_->linkProps();
    Handle ds(H5Dcreate2(impl_->file.get(), path.c_str(), H5T_IEEE_F64LE, space.get(), lcpl.get(), dcpl.get(),
                         H5P_DEFAULT),
              H5Dclose);
    if (ds.get() < 0) impl_->fail("cannot create time series column", path);
    s.datasets.push_back(std::move(ds));
  }
  impl_->series.emplace(name, std::move(s));
  // The structure is on disk before any row: a reader (or a crash) finds every declared column.
  H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL);
}

void H5Writer::append(const std::string& name, double time, std::span<const double> values) {
  auto it = impl_->series.find(name);
  if (it == impl_->series.end()) impl_->fail("time series not declared", "/timeseries/" + name);
  SeriesRef& s = it->second;
  if (values.size() + 1 != s.columns.size())
    impl_->fail(fmt::format("row has {} values, the series has {} columns besides time", values.size(),
                            s.columns.size() - 1),
                "/timeseries/" + name);
  impl_->requireFinite(values, time, "/timeseries/" + name);
  s.pending.push_back(time);
  s.pending.insert(s.pending.end(), values.begin(), values.end());
  if (s.pending.size() >= kBlockRows * s.columns.size()) impl_->writePending(name, s);
}

void H5Writer::addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::int64_t> cells,
                       CellType type) {
  const std::string base = "/meshes/" + mesh;
  const bool resumed = impl_->meshesToRedeclare.erase(mesh) > 0;
  if (!resumed && impl_->grids.count(mesh)) impl_->fail("mesh written twice", base);
  const auto k = static_cast<std::size_t>(type);
  if (nodes.size() % 3 != 0 || cells.size() % k != 0) impl_->fail("node or cell array has a wrong length", base);
  if (resumed) {  // the file's mesh stays; one of another size would not fit its snapshots
    const GridRef& g = impl_->grids.at(mesh);
    if (g.type != type || g.nodes.dims[0] != nodes.size() / 3 || g.cells.dims[0] != cells.size() / k)
      impl_->fail(fmt::format("the file's mesh has {} nodes and {} cells of {} nodes, the restarted program "
                              "declares {} nodes and {} cells of {}",
                              g.nodes.dims[0], g.cells.dims[0], static_cast<int>(g.type), nodes.size() / 3,
                              cells.size() / k, k),
                  base);
    return;
  }
  GridRef g;
  g.type = type;
  g.nodes = impl_->writeArray(base + "/nodes", nodes.data(), H5T_NATIVE_DOUBLE, nodes.size() / 3, 3);
  g.cells = impl_->writeArray(base + "/cells", cells.data(), H5T_NATIVE_INT64, cells.size() / k, k);
  g.cells.dims = {cells.size() / k, k};  // keep 2-D even for a single-column layout
  impl_->grids.emplace(mesh, std::move(g));
  impl_->gridOrder.push_back(mesh);
}

void H5Writer::writeMeshSnapshot(const std::string& mesh, double time, std::span<const double> currentNodes,
                                 const std::vector<Field>& pointData, const std::vector<Field>& cellData) {
  auto it = impl_->grids.find(mesh);
  if (it == impl_->grids.end() || it->second.particles) impl_->fail("mesh not declared", "/meshes/" + mesh);
  GridRef& g = it->second;
  const std::size_t nNodes = g.nodes.dims[0], nCells = g.cells.dims[0];
  const std::string step = stepGroup("/meshes/" + mesh, g.snapshots.size());
  impl_->requireFinite(currentNodes, time, step + "/nodes");
  for (const auto* fields : {&pointData, &cellData})
    for (const Field& f : *fields) impl_->requireFinite(f.data, time, step + "/" + f.name);
  SnapshotRef s{time, g.nodes, nCells, {}, {}};
  if (!currentNodes.empty()) {
    if (currentNodes.size() != 3 * nNodes) impl_->fail("current node array has a wrong length", step + "/nodes");
    s.geometry = impl_->writeArray(step + "/nodes", currentNodes.data(), H5T_NATIVE_DOUBLE, nNodes, 3);
  }
  s.attributes = impl_->writeFields(step + "/point/", pointData, nNodes, false);
  auto cellAttrs = impl_->writeFields(step + "/cell/", cellData, nCells, true);
  s.attributes.insert(s.attributes.end(), cellAttrs.begin(), cellAttrs.end());
  if (s.attributes.empty() && currentNodes.empty()) {
    Handle lcpl = impl_->linkProps();
    Handle grp(H5Gcreate2(impl_->file.get(), step.c_str(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  }
  impl_->setTime(step, time);
  g.snapshots.push_back(std::move(s));
  flush();
}

void H5Writer::writeParticles(const std::string& set, double time, std::span<const double> positions,
                              const std::vector<Field>& fields) {
  auto [it, fresh] = impl_->grids.try_emplace(set);
  GridRef& g = it->second;
  if (fresh) {
    g.particles = true;
    impl_->gridOrder.push_back(set);
  } else if (!g.particles) {
    impl_->fail("a mesh of this name exists", "/particles/" + set);
  }
  if (positions.size() % 3 != 0) impl_->fail("positions must hold N×3 values", "/particles/" + set);
  const std::size_t n = positions.size() / 3;
  const std::string step = stepGroup("/particles/" + set, g.snapshots.size());
  impl_->requireFinite(positions, time, step + "/position");
  for (const Field& f : fields) impl_->requireFinite(f.data, time, step + "/" + f.name);
  SnapshotRef s{time, impl_->writeArray(step + "/position", positions.data(), H5T_NATIVE_DOUBLE, n, 3), n, {}, {}};
  s.geometry.dims = {n, 3};
  s.attributes = impl_->writeFields(step + "/", fields, n, false);
  impl_->setTime(step, time);
  g.snapshots.push_back(std::move(s));
  flush();
}

void H5Writer::writeLines(const std::string& set, double time, std::span<const double> points,
                          std::span<const std::int64_t> lines, const std::vector<Field>& cellFields) {
  auto [it, fresh] = impl_->grids.try_emplace(set);
  GridRef& g = it->second;
  if (fresh) {
    g.type = CellType::kLine;
    impl_->gridOrder.push_back(set);
  } else if (g.particles || g.type != CellType::kLine || !g.cells.path.empty()) {
    impl_->fail("another grid of this name exists", "/networks/" + set);
  }
  if (points.size() % 3 != 0 || lines.size() % 2 != 0) impl_->fail("points must be N×3 and lines M×2", "/networks/" + set);
  const std::size_t n = points.size() / 3, m = lines.size() / 2;
  for (auto i : lines)
    if (i < 0 || static_cast<std::size_t>(i) >= n) impl_->fail("a line names a point that does not exist", "/networks/" + set);
  const std::string step = stepGroup("/networks/" + set, g.snapshots.size());
  impl_->requireFinite(points, time, step + "/points");
  for (const Field& f : cellFields) impl_->requireFinite(f.data, time, step + "/" + f.name);
  SnapshotRef s{time, impl_->writeArray(step + "/points", points.data(), H5T_NATIVE_DOUBLE, n, 3), m, {}, {}};
  s.geometry.dims = {n, 3};
  s.cells = impl_->writeArray(step + "/lines", lines.data(), H5T_NATIVE_INT64, m, 2);
  s.cells.dims = {m, 2};
  s.attributes = impl_->writeFields(step + "/", cellFields, m, true);
  impl_->setTime(step, time);
  g.snapshots.push_back(std::move(s));
  flush();
}

void H5Writer::writeArray(const std::string& path, std::span<const double> data, std::size_t cols) {
  if (cols == 0 || data.size() % cols != 0) impl_->fail("array length is not a multiple of its columns", path);
  if (impl_->resumed && impl_->exists(path)) impl_->remove(path);  // a restart writes its tables again
  impl_->writeArray(path, data.data(), H5T_NATIVE_DOUBLE, data.size() / cols, cols);
}

std::vector<double> readH5Array(const fs::path& file, const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Handle f(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (f.get() < 0) throw SimulationError(fmt::format("cannot open HDF5 file {}.", file.string()));
  if (H5Lexists(f.get(), path.c_str(), H5P_DEFAULT) <= 0)
    throw SimulationError(fmt::format("HDF5 file {} has no dataset {}.", file.string(), path));
  Handle d(H5Dopen2(f.get(), path.c_str(), H5P_DEFAULT), H5Dclose);
  Handle space(H5Dget_space(d.get()), H5Sclose);
  std::vector<double> out(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space.get())));
  if (H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw SimulationError(fmt::format("cannot read dataset {} of {}.", path, file.string()));
  return out;
}

void H5Writer::flush() {
  for (auto& [name, series] : impl_->series) impl_->writePending(name, series);
  if (H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL) < 0) impl_->fail("cannot flush", "/");
  impl_->writeXdmf(xdmfPath());
}

H5Extent H5Writer::checkpoint() {
  flush();
  H5Extent e;
  for (const auto& [name, s] : impl_->series) {
    e.series.push_back(name);
    e.rows.push_back(s.rows);
  }
  for (const auto& name : impl_->gridOrder) {
    e.grids.push_back(name);
    e.snapshots.push_back(impl_->grids.at(name).snapshots.size());
  }
  return e;
}

}  // namespace common
