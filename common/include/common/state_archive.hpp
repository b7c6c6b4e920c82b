#pragma once
// A solver's state on disk (restart): one HDF5 file of named datasets, written and read
// by the same code. A component describes its state once, in a function that calls io(name, member)
// for each member; the same function writes (a StateArchive made by create()) and reads (one made by
// open()), so no list of fields is kept twice and a member cannot be written but forgotten on read.
//
//   void Integrator::archive(common::StateArchive& a) {
//     a.io("time", time_);
//     a.io("velocity", velocity_);   // std::vector<Vec3>: raw records, their size checked on read
//   }
//
// Values: arithmetic scalars and enums; std::string; std::vector and std::array of trivially
// copyable elements (arithmetic ones as typed datasets h5py reads, others as raw bytes with their
// record size); plain structs that own no memory (raw bytes); vectors of vectors and of strings;
// std::pair; dense column vectors (Eigen::VectorXd, a typed dataset); any type with a member
// `void archive(StateArchive&)` (a group). A name may contain '/' (nested groups); a scope() prefixes
// every name inside it.
//
// Integrity: the file is written as FILE.tmp and renamed by commit(), so a crash mid-write leaves the
// previous checkpoint intact; every dataset carries a Fletcher-32 checksum; the root group states the
// format, the program that wrote it and `complete` (set last). Reading a truncated, damaged or foreign
// file, a missing dataset or one whose record size differs throws common::ConfigError naming the file
// and the dataset (exit 2): a checkpoint is never used half-read.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <utility>
#include <vector>

namespace common {

class StateArchive {
 public:
  /// A new archive at `path`, written to `path`.tmp until commit(). `kind` names the writer
  /// ("dem_solver", "cosim"): open() checks it.
  static StateArchive create(const std::filesystem::path& path, const std::string& kind);
  /// An archive commit()ted earlier, for reading; `kind` must match the writer's.
  static StateArchive open(const std::filesystem::path& path, const std::string& kind);
  /// Checks a checkpoint of any kind without using it: complete, of this build, every dataset's
  /// checksum. Throws ConfigError naming the file (a coupler checks its participants' before it starts
  /// them). Returns the kind.
  static std::string verify(const std::filesystem::path& path);
  StateArchive(StateArchive&&) noexcept;
  StateArchive& operator=(StateArchive&&) noexcept;
  ~StateArchive();

  bool reading() const { return reading_; }
  const std::filesystem::path& path() const { return path_; }
  /// Writing: closes the file, flushes it to disk and renames it into place. Reading: nothing.
  void commit();
  /// A new archive at `path` filled by `fill(archive)`, then commit()ted.
  template <class Fill>
  static void write(const std::filesystem::path& path, const std::string& kind, Fill&& fill) {
    StateArchive a = create(path, kind);
    fill(a);
    a.commit();
  }

  /// Every name until the scope ends is prefixed by `name`/.
  class Scope {
   public:
    Scope(StateArchive& a, const std::string& name) : a_(a), saved_(a.prefix_) { a.prefix_ += name + "/"; }
    ~Scope() { a_.prefix_ = saved_; }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    StateArchive& a_;
    std::string saved_;
  };
  Scope scope(const std::string& name) { return Scope(*this, name); }
  /// Whether the archive holds `name` (reading: optional state of an older writer).
  bool has(const std::string& name) const;
  /// The dimensions of what wrote it (a solver's own description: bodies, spheres, nodes, …): written,
  /// or on reading compared with `shape`, a ConfigError naming both when they differ (a checkpoint of
  /// another scene). Read it before anything is changed on the strength of the checkpoint.
  void shape(const std::string& shape);

  template <class T>
  void io(const std::string& name, T& value) {
    if constexpr (requires(T& t, StateArchive& a) { t.archive(a); }) {
      auto s = scope(name);
      value.archive(*this);
    } else if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
      std::span<T> one(&value, 1);
      records(name, one, true);
    } else if constexpr (kRecord<T> && !IsArray<T>::value && !IsPair<T>::value) {  // a plain struct
      std::span<T> one(&value, 1);
      records(name, one, true);
    } else if constexpr (std::is_same_v<T, std::string>) {
      std::vector<char> bytes(value.begin(), value.end());
      io(name, bytes);
      if (reading_) value.assign(bytes.begin(), bytes.end());
    } else if constexpr (IsPair<T>::value) {
      auto s = scope(name);
      io("first", value.first);
      io("second", value.second);
    } else if constexpr (IsArray<T>::value && kRecord<typename T::value_type>) {
      std::span<typename T::value_type> all(value.data(), value.size());
      records(name, all, true);
    } else if constexpr (IsVector<T>::value) {
      using E = typename T::value_type;
      if constexpr (std::is_same_v<E, bool>) {
        std::vector<std::uint8_t> bytes(value.begin(), value.end());
        io(name, bytes);
        if (reading_) value.assign(bytes.begin(), bytes.end());
      } else if constexpr (kRecord<E>) {
        if (reading_) value.resize(count(name, sizeof(E), typeTag<E>()));
        std::span<E> all(value.data(), value.size());
        records(name, all, false);
      } else {
        auto s = scope(name);
        std::uint64_t n = value.size();
        io("size", n);
        if (reading_) value.resize(n);
        for (std::size_t i = 0; i < value.size(); ++i) io(std::to_string(i), value[i]);
      }
    } else if constexpr (kDenseVector<T>) {
      using E = typename T::value_type;
      if (reading_) value.resize(static_cast<decltype(value.size())>(count(name, sizeof(E), typeTag<E>())));
      std::span<E> all(value.data(), static_cast<std::size_t>(value.size()));
      records(name, all, false);
    } else {
      static_assert(sizeof(T) == 0, "StateArchive::io: give the type a member archive(StateArchive&)");
    }
  }

 private:
  StateArchive() = default;
  // Values stored as their bytes: what owns no memory and points nowhere (Eigen's fixed-size vectors and
  // the plain structs made of them are not trivially copyable, but are trivially destructible).
  template <class E>
  static constexpr bool kRecord = std::is_trivially_destructible_v<E> && !std::is_pointer_v<E> &&
                                  std::is_copy_assignable_v<E>;
  // A resizable column of numbers that is not a std::vector (Eigen::VectorXd and its kin).
  template <class T>
  static constexpr bool kDenseVector = requires(T& t) {
    typename T::value_type;
    requires std::is_arithmetic_v<typename T::value_type>;
    requires T::ColsAtCompileTime == 1;
    t.data();
    t.resize(t.size());
  };
  template <class T> struct IsVector : std::false_type {};
  template <class E, class A> struct IsVector<std::vector<E, A>> : std::true_type {};
  template <class T> struct IsArray : std::false_type {};
  template <class E, std::size_t N> struct IsArray<std::array<E, N>> : std::true_type {};
  template <class T> struct IsPair : std::false_type {};
  template <class A, class B> struct IsPair<std::pair<A, B>> : std::true_type {};

  // The dataset's element type: an HDF5 number type for arithmetic elements, raw bytes otherwise.
  enum class Tag : int { kBytes, kF64, kF32, kI8, kU8, kI16, kU16, kI32, kU32, kI64, kU64 };
  template <class E>
  static constexpr Tag typeTag() {
    if constexpr (std::is_enum_v<E>) return typeTag<std::underlying_type_t<E>>();
    else if constexpr (std::is_same_v<E, bool>) return Tag::kU8;
    else if constexpr (std::is_floating_point_v<E>) return sizeof(E) == 8 ? Tag::kF64 : sizeof(E) == 4 ? Tag::kF32 : Tag::kBytes;
    else if constexpr (std::is_integral_v<E>) {
      constexpr bool s = std::is_signed_v<E>;
      if constexpr (sizeof(E) == 1) return s ? Tag::kI8 : Tag::kU8;
      else if constexpr (sizeof(E) == 2) return s ? Tag::kI16 : Tag::kU16;
      else if constexpr (sizeof(E) == 4) return s ? Tag::kI32 : Tag::kU32;
      else return s ? Tag::kI64 : Tag::kU64;
    } else return Tag::kBytes;
  }
  template <class E>
  void records(const std::string& name, std::span<E> values, bool fixedCount) {
    transfer(name, values.data(), values.size(), sizeof(E), typeTag<E>(), fixedCount);
  }
  // Writes `n` records of `size` bytes at `data`, or reads them there (a fixed count must match).
  void transfer(const std::string& name, void* data, std::size_t n, std::size_t size, Tag tag, bool fixedCount);
  // Reading: how many records of `size` bytes the dataset holds (checked against `tag`).
  std::size_t count(const std::string& name, std::size_t size, Tag tag);

  struct File;
  std::unique_ptr<File> file_;
  std::filesystem::path path_;
  std::string prefix_;
  bool reading_ = false;
};

}  // namespace common
