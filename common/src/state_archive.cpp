#include "common/state_archive.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

#include <fmt/format.h>
#include <hdf5.h>

#include "common/errors.hpp"

namespace fs = std::filesystem;

namespace common {

namespace {

constexpr int kFormat = 1;

// Owns one HDF5 identifier.
class Id {
 public:
  Id() = default;
  Id(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Id(Id&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}
  Id& operator=(Id&& o) noexcept {
    reset();
    id_ = std::exchange(o.id_, H5I_INVALID_HID);
    close_ = o.close_;
    return *this;
  }
  ~Id() { reset(); }
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = H5I_INVALID_HID;
  }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }

 private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

void writeScalarAttribute(hid_t object, const char* name, hid_t type, const void* value) {
  Id space(H5Screate(H5S_SCALAR), H5Sclose);
  if (H5Aexists(object, name) > 0) H5Adelete(object, name);
  Id attr(H5Acreate2(object, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!attr.valid() || H5Awrite(attr.get(), type, value) < 0)
    throw SimulationError(fmt::format("cannot write the attribute {} of a checkpoint", name));
}

bool readScalarAttribute(hid_t object, const char* name, hid_t type, void* value) {
  if (H5Aexists(object, name) <= 0) return false;
  Id attr(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
  return attr.valid() && H5Aread(attr.get(), type, value) >= 0;
}

std::string readStringAttribute(hid_t object, const char* name) {
  if (H5Aexists(object, name) <= 0) return {};
  Id attr(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
  Id type(H5Aget_type(attr.get()), H5Tclose);
  const std::size_t n = H5Tget_size(type.get());
  std::string s(n, '\0');
  Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(mem.get(), n);
  if (H5Aread(attr.get(), mem.get(), s.data()) < 0) return {};
  s.resize(std::strlen(s.c_str()));
  return s;
}

void writeStringAttribute(hid_t object, const char* name, const std::string& value) {
  Id type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type.get(), std::max<std::size_t>(1, value.size()));
  Id space(H5Screate(H5S_SCALAR), H5Sclose);
  Id attr(H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!attr.valid() || H5Awrite(attr.get(), type.get(), value.c_str()) < 0)
    throw SimulationError(fmt::format("cannot write the attribute {} of a checkpoint", name));
}

// The program that writes a checkpoint: its record layouts are this build's.
std::string writerBuild() { return fmt::format("{} {}", __VERSION__, sizeof(void*) * 8); }

}  // namespace

struct StateArchive::File {
  Id file;
};

namespace {
// Memory and file types of a tag (file types are little-endian, as the protocol).
std::pair<hid_t, hid_t> types(int tag) {
  switch (tag) {
    case 1: return {H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE};
    case 2: return {H5T_NATIVE_FLOAT, H5T_IEEE_F32LE};
    case 3: return {H5T_NATIVE_INT8, H5T_STD_I8LE};
    case 4: return {H5T_NATIVE_UINT8, H5T_STD_U8LE};
    case 5: return {H5T_NATIVE_INT16, H5T_STD_I16LE};
    case 6: return {H5T_NATIVE_UINT16, H5T_STD_U16LE};
    case 7: return {H5T_NATIVE_INT32, H5T_STD_I32LE};
    case 8: return {H5T_NATIVE_UINT32, H5T_STD_U32LE};
    case 9: return {H5T_NATIVE_INT64, H5T_STD_I64LE};
    case 10: return {H5T_NATIVE_UINT64, H5T_STD_U64LE};
    default: return {H5T_NATIVE_UINT8, H5T_STD_U8LE};
  }
}
}  // namespace

StateArchive StateArchive::create(const fs::path& path, const std::string& kind) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  StateArchive a;
  a.path_ = path;
  a.file_ = std::make_unique<File>();
  const fs::path tmp = fs::path(path).concat(".tmp");
  a.file_->file = Id(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!a.file_->file.valid()) throw SimulationError(fmt::format("cannot create the checkpoint {}", tmp.string()));
  const hid_t root = a.file_->file.get();
  const int format = kFormat, complete = 0;
  writeScalarAttribute(root, "format", H5T_NATIVE_INT, &format);
  writeScalarAttribute(root, "complete", H5T_NATIVE_INT, &complete);
  writeStringAttribute(root, "kind", kind);
  writeStringAttribute(root, "build", writerBuild());
  return a;
}

std::string StateArchive::verify(const fs::path& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  std::string kind;
  {
    if (!fs::exists(path) || H5Fis_hdf5(path.c_str()) <= 0)
      throw ConfigError(fmt::format("{}: missing, or not a readable HDF5 file (truncated or damaged checkpoint)", path.string()));
    Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file.valid()) throw ConfigError(fmt::format("{}: cannot be opened (truncated or damaged checkpoint)", path.string()));
    kind = readStringAttribute(file.get(), "kind");
  }
  StateArchive a = open(path, kind);
  // Every dataset read once: a checksum that fails is found now, not in the middle of a restart.
  struct Visit {
    const fs::path* path;
    std::string bad;
  } visit{&path, {}};
  auto each = [](hid_t group, const char* name, const H5L_info_t*, void* data) -> herr_t {
    auto* v = static_cast<Visit*>(data);
    H5O_info_t info;
    if (H5Oget_info_by_name(group, name, &info, H5P_DEFAULT) < 0 || info.type != H5O_TYPE_DATASET) return 0;
    Id ds(H5Dopen2(group, name, H5P_DEFAULT), H5Dclose);
    Id space(H5Dget_space(ds.get()), H5Sclose);
    Id type(H5Dget_type(ds.get()), H5Tclose);
    const hssize_t n = H5Sget_simple_extent_npoints(space.get());
    std::vector<unsigned char> buffer(static_cast<std::size_t>(std::max<hssize_t>(n, 0)) * H5Tget_size(type.get()));
    if (n > 0 && H5Dread(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()) < 0) {
      v->bad = name;
      return 1;
    }
    return 0;
  };
  if (H5Lvisit(a.file_->file.get(), H5_INDEX_NAME, H5_ITER_NATIVE, each, &visit) != 0 || !visit.bad.empty())
    throw ConfigError(fmt::format("{}: {} cannot be read (damaged checkpoint: checksum or size)", path.string(),
                                  visit.bad.empty() ? std::string("a dataset") : visit.bad));
  return kind;
}

StateArchive StateArchive::open(const fs::path& path, const std::string& kind) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  StateArchive a;
  a.path_ = path;
  a.reading_ = true;
  a.file_ = std::make_unique<File>();
  if (!fs::exists(path)) throw ConfigError(fmt::format("{}: no such checkpoint", path.string()));
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw ConfigError(fmt::format("{}: not a readable HDF5 file (truncated or damaged checkpoint)", path.string()));
  a.file_->file = Id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!a.file_->file.valid())
    throw ConfigError(fmt::format("{}: cannot be opened (truncated or damaged checkpoint)", path.string()));
  const hid_t root = a.file_->file.get();
  int format = 0, complete = 0;
  if (!readScalarAttribute(root, "format", H5T_NATIVE_INT, &format) || format != kFormat)
    throw ConfigError(fmt::format("{}: not a checkpoint of format {} (it states {})", path.string(), kFormat, format));
  if (!readScalarAttribute(root, "complete", H5T_NATIVE_INT, &complete) || complete != 1)
    throw ConfigError(fmt::format("{}: an incomplete checkpoint (its writer stopped before the end)", path.string()));
  if (const std::string k = readStringAttribute(root, "kind"); k != kind)
    throw ConfigError(fmt::format("{}: a checkpoint of {}, not of {}", path.string(), k.empty() ? "unknown kind" : k, kind));
  if (const std::string b = readStringAttribute(root, "build"); b != writerBuild())
    throw ConfigError(fmt::format("{}: written by another build ({}; this one is {}): its record layouts may differ",
                                  path.string(), b, writerBuild()));
  return a;
}

StateArchive::StateArchive(StateArchive&&) noexcept = default;
StateArchive& StateArchive::operator=(StateArchive&&) noexcept = default;

StateArchive::~StateArchive() {
  if (file_ && !reading_ && file_->file.valid()) {  // never committed: leave no half-written .tmp
    file_->file.reset();
    std::error_code ec;
    fs::remove(fs::path(path_).concat(".tmp"), ec);
  }
}

void StateArchive::commit() {
  if (reading_ || !file_ || !file_->file.valid()) return;
  const int complete = 1;
  writeScalarAttribute(file_->file.get(), "complete", H5T_NATIVE_INT, &complete);
  const fs::path tmp = fs::path(path_).concat(".tmp");
  if (H5Fflush(file_->file.get(), H5F_SCOPE_GLOBAL) < 0)
    throw SimulationError(fmt::format("cannot flush the checkpoint {}", tmp.string()));
  const herr_t closed = H5Fclose(file_->file.release());
  // On disk before it replaces anything (a power cut after the rename leaves the new file whole); a file
  // that cannot be made durable (disk full, I/O error) never replaces the previous checkpoint.
  auto durable = [](const fs::path& p) {
    const int fd = ::open(p.c_str(), O_RDONLY);
    if (fd < 0) return false;
    const bool synced = ::fsync(fd) == 0;
    return ::close(fd) == 0 && synced;
  };
  if (closed < 0 || !durable(tmp)) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw SimulationError(fmt::format("cannot write the checkpoint {} to disk (full, or an I/O error): the previous "
                                      "checkpoint is kept",
                                      tmp.string()));
  }
  std::error_code ec;
  fs::rename(tmp, path_, ec);
  if (ec) throw SimulationError(fmt::format("cannot rename {} to {}: {}", tmp.string(), path_.string(), ec.message()));
  durable(path_.has_parent_path() ? path_.parent_path() : fs::path("."));  // the rename itself
}

bool StateArchive::has(const std::string& name) const {
  const std::string full = prefix_ + name;
  const hid_t root = file_->file.get();
  // Every link on the way must exist (H5Lexists fails on a missing intermediate group).
  for (std::size_t pos = full.find('/'); ; pos = full.find('/', pos + 1)) {
    const std::string part = pos == std::string::npos ? full : full.substr(0, pos);
    if (H5Lexists(root, part.c_str(), H5P_DEFAULT) <= 0) return false;
    if (pos == std::string::npos) return true;
  }
}

void StateArchive::shape(const std::string& shape) {
  std::string stored = shape;
  const std::string saved = prefix_;
  prefix_.clear();
  io("shape", stored);
  prefix_ = saved;
  if (reading_ && stored != shape)
    throw ConfigError(fmt::format("{}: a checkpoint of another scene: it holds {}; this scene has {}", path_.string(),
                                  stored, shape));
}

std::size_t StateArchive::count(const std::string& name, std::size_t size, Tag tag) {
  const std::string full = prefix_ + name;
  if (!has(name)) throw ConfigError(fmt::format("{}: the checkpoint lacks {} (written by another version?)", path_.string(), full));
  Id ds(H5Dopen2(file_->file.get(), full.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds.valid()) throw ConfigError(fmt::format("{}: {} cannot be read (damaged checkpoint)", path_.string(), full));
  Id space(H5Dget_space(ds.get()), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  std::uint64_t recordSize = 0;
  if (!readScalarAttribute(ds.get(), "record_size", H5T_NATIVE_UINT64, &recordSize) || recordSize != size)
    throw ConfigError(fmt::format("{}: {} holds records of {} bytes, this program's are {} (written by another version?)",
                                  path_.string(), full, recordSize, size));
  if (n < 0) throw ConfigError(fmt::format("{}: {} cannot be read (damaged checkpoint)", path_.string(), full));
  const std::size_t values = static_cast<std::size_t>(n);
  if (tag == Tag::kBytes) {
    if (values % size != 0)
      throw ConfigError(fmt::format("{}: {} holds {} bytes, not whole records of {}", path_.string(), full, values, size));
    return values / size;
  }
  return values;
}

void StateArchive::transfer(const std::string& name, void* data, std::size_t n, std::size_t size, Tag tag,
                            bool fixedCount) {
  const std::string full = prefix_ + name;
  const auto [memType, fileType] = types(static_cast<int>(tag));
  const hsize_t values = tag == Tag::kBytes ? static_cast<hsize_t>(n * size) : static_cast<hsize_t>(n);
  const hid_t root = file_->file.get();
  if (reading_) {
    if (fixedCount) {
      if (const std::size_t m = count(name, size, tag); m != n)
        throw ConfigError(fmt::format("{}: {} holds {} values, this program expects {}", path_.string(), full, m, n));
    }
    if (values == 0) return;
    Id ds(H5Dopen2(root, full.c_str(), H5P_DEFAULT), H5Dclose);
    // A Fletcher-32 mismatch fails the read: a damaged checkpoint is never used.
    if (!ds.valid() || H5Dread(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
      throw ConfigError(fmt::format("{}: {} cannot be read (damaged checkpoint: checksum or size)", path_.string(), full));
    return;
  }
  Id lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (values > 0) {
    const hsize_t chunk = std::min<hsize_t>(values, hsize_t{1} << 18);
    H5Pset_chunk(dcpl.get(), 1, &chunk);
    H5Pset_fletcher32(dcpl.get());
  }
  Id space(H5Screate_simple(1, &values, nullptr), H5Sclose);
  Id ds(H5Dcreate2(root, full.c_str(), fileType, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT), H5Dclose);
  if (!ds.valid()) throw SimulationError(fmt::format("{}: cannot create {} (named twice?)", path_.string(), full));
  if (values > 0 && H5Dwrite(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw SimulationError(fmt::format("{}: cannot write {}", path_.string(), full));
  const std::uint64_t recordSize = size;
  writeScalarAttribute(ds.get(), "record_size", H5T_NATIVE_UINT64, &recordSize);
}

}  // namespace common
