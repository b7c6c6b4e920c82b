#pragma once
// HDF5 result files with an XDMF sidecar for ParaView.
//
// Layout of FILE.h5 (all floating data float64, connectivity int64, 0-based):
//   /timeseries/<series>/<column>          1-D, appendable; the first column is "time" [s]
//   /meshes/<mesh>/nodes                   N×3 reference coordinates [m]
//   /meshes/<mesh>/cells                   M×k connectivity (k = 2 line, 3 triangle, 4 tetrahedron)
//   /meshes/<mesh>/steps/<i>/nodes         N×3 current coordinates, only when the snapshot gives them
//   /meshes/<mesh>/steps/<i>/point/<field> N or N×c;   .../cell/<field> M or M×c;  attribute "time"
//   /particles/<set>/steps/<i>/position    N×3 (N may change between snapshots); .../<field> N or N×c
//   /networks/<set>/steps/<i>/points       N×3; .../lines M×2 (0-based into points); .../<field> M or M×c
// FILE.xdmf (XDMF 3) is rewritten, through a temporary file and a rename, after every snapshot and at
// flush(): a run that stops at any moment leaves an .h5 and an .xdmf that agree. A file with no
// snapshot gets no .xdmf (a Domain without a grid crashes ParaView's reader).
//
// Call order: construct → add series / meshes → append / snapshot / flush in any order → destroy.
// Restart: checkpoint() gives the file's extent, which the solver stores with its state; the restarted
// run constructs the writer with that extent, declares its series and meshes again, and continues.
// Errors (HDF5 failures, wrong shapes, unknown names) throw common::SimulationError naming the file and
// the dataset. Not thread safe: one writer per thread.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace common {

class StateArchive;

/// A field to store: `data` holds rows × components values, row-major.
struct Field {
  std::string name;
  int components = 1;
  std::span<const double> data;
};

enum class CellType { kLine = 2, kTriangle = 3, kTetrahedron = 4 };

/// Where a writer's file stands: the rows of each time series and the snapshots of each grid (mesh,
/// particle set, line network). A checkpoint records it; a restart cuts the file back to it.
struct H5Extent {
  std::vector<std::string> series;
  std::vector<std::uint64_t> rows;  ///< parallel to `series`
  std::vector<std::string> grids;
  std::vector<std::uint64_t> snapshots;  ///< parallel to `grids`
  void archive(StateArchive& a);
};

class H5Writer {
 public:
  /// Creates (or truncates) `h5Path` and writes its sidecar next to it (same stem, .xdmf).
  explicit H5Writer(const std::filesystem::path& h5Path);
  /// Reopens `h5Path`, written by an earlier run of the same program, and cuts it back to `extent`: rows of a
  /// series after extent's count and snapshots of a grid after its count are removed (a series or grid not
  /// in extent keeps nothing). The program then declares its series and meshes again as on a fresh run:
  /// addSeries/addMesh find them in the file (columns and mesh sizes must match, else SimulationError
  /// naming the file and the series or mesh) and continue after them; writeArray replaces a dataset the
  /// earlier run wrote. The XDMF sidecar is rewritten at once and lists the kept snapshots. A missing or
  /// unreadable file, or one holding less than `extent`, throws SimulationError.
  H5Writer(const std::filesystem::path& h5Path, const H5Extent& extent);
  ~H5Writer();
  H5Writer(const H5Writer&) = delete;
  H5Writer& operator=(const H5Writer&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path xdmfPath() const;

  /// Declares a time series. `columns` excludes "time", which is always the first column.
  void addSeries(const std::string& series, const std::vector<std::string>& columns);
  /// Appends one row: time then one value per declared column. Rows are buffered and written in blocks
  /// of 256; flush() (and every snapshot) writes them, so call it at each output step.
  void append(const std::string& series, double time, std::span<const double> values);

  /// Writes a mesh once. `nodes` is N×3 row-major, `cells` is M×(int)type row-major.
  void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::int64_t> cells,
               CellType type);
  /// Writes a snapshot of `mesh` at `time`, optionally with current node coordinates (N×3, else empty).
  /// Flushes the file and rewrites the XDMF.
  void writeMeshSnapshot(const std::string& mesh, double time, std::span<const double> currentNodes,
                         const std::vector<Field>& pointData, const std::vector<Field>& cellData = {});
  /// Writes a particle snapshot: positions N×3 and per-particle fields. Flushes, rewrites the XDMF.
  void writeParticles(const std::string& set, double time, std::span<const double> positions,
                      const std::vector<Field>& fields);

  /// Writes a snapshot of line cells whose number changes from snapshot to snapshot (a contact network):
  /// `points` N×3, `lines` M×2 indices into them, one value (or c) per line in each field. Flushes,
  /// rewrites the XDMF (a Polyline grid per snapshot, its own topology).
  void writeLines(const std::string& set, double time, std::span<const double> points,
                  std::span<const std::int64_t> lines, const std::vector<Field>& cellFields);

  /// Writes (once) a plain dataset, `data` holding rows × cols values (state for restarts, tables).
  void writeArray(const std::string& path, std::span<const double> data, std::size_t cols = 1);

  /// Flushes HDF5 buffers to disk and rewrites the XDMF.
  void flush();
  /// Writes every buffered row to the file and returns its extent (what a checkpoint taken now must keep).
  H5Extent checkpoint();
  /// Reopened from a checkpoint's extent: what a fresh run writes first (an initial snapshot) is there.
  bool resumed() const;

 private:
  struct Impl;
  std::filesystem::path path_;
  std::unique_ptr<Impl> impl_;
};

/// Reads a float64 dataset of an HDF5 file (any shape, flattened row-major). Throws SimulationError
/// naming the file and the dataset when either is missing.
std::vector<double> readH5Array(const std::filesystem::path& file, const std::string& path);

}  // namespace common
