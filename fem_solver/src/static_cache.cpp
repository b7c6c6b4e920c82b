#include "fem/static_cache.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <fmt/format.h>

#include "common/log.hpp"

namespace fem {

namespace fs = std::filesystem;

namespace {

// FNV-1a over the bytes of what the static state depends on.
class Hash {
 public:
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h_ = (h_ ^ c[i]) * 1099511628211ull;
  }
  template <class T>
  void value(const T& v) {
    bytes(&v, sizeof(v));
  }
  template <class T>
  void range(const std::vector<T>& v) {
    value(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  std::uint64_t get() const { return h_; }

 private:
  std::uint64_t h_ = 1469598103934665603ull;
};

fs::path cacheDir() {
  if (const char* d = std::getenv("COSIM_CACHE_DIR"); d && *d) return fs::path(d) / "static";
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) return fs::path(d) / "cosim" / "static";
  if (const char* d = std::getenv("HOME"); d && *d) return fs::path(d) / ".cache" / "cosim" / "static";
  return {};
}

constexpr std::uint64_t kMagic = 0x636f73696d535431ull;  // "cosimST1"

}  // namespace

std::uint64_t staticFingerprint(const Model& model, const StaticSettings& s) {
  Hash h;
  for (const auto& x : model.reference) h.value(x.x()), h.value(x.y()), h.value(x.z());
  // A fixed, smooth probe displacement: each block's forces and energy there depend on every one of its
  // material and section parameters, its prestress included.
  std::vector<double> probe(model.dofs());
  for (std::size_t i = 0; i < probe.size(); ++i) probe[i] = 1e-4 * std::sin(0.37 * static_cast<double>(i) + 0.1);
  for (const auto& b : model.blocks) {
    const std::string name = b->name();
    h.bytes(name.data(), name.size());
    h.range(b->connectivity());
    std::vector<double> slots(3 * b->connectivity().size());
    b->internalForces(probe, slots);  // per element, in its own slots: the same bits on any thread count
    h.range(slots);
  }
  h.range(model.nodeMass());
  h.range(model.deadLoad);
  h.range(model.fixed);
  h.range(model.prescribed);
  h.value(static_cast<int>(s.method)), h.value(s.fallback), h.value(s.relaxationIterations), h.value(s.loadSteps);
  h.value(s.loadFactor), h.value(s.maxIterations), h.value(s.tolerance), h.value(s.continuationStart);
  // And the solver that made it: a rebuilt executable (a changed static solver) solves again.
  std::error_code ec;
  const fs::path exe = fs::canonical("/proc/self/exe", ec);
  if (!ec) {
    h.value(fs::file_size(exe, ec));
    h.value(fs::last_write_time(exe, ec).time_since_epoch().count());
  }
  return h.get();
}

CachedStatic solveStaticCached(Model& model, const StaticSettings& settings) {
  auto log = common::logger("fem");
  const std::uint64_t key = staticFingerprint(model, settings);
  const fs::path dir = cacheDir();
  const fs::path file = dir.empty() ? fs::path() : dir / fmt::format("{:016x}.bin", key);
  const std::size_t n = model.dofs();
  std::error_code exists;
  if (!file.empty() && fs::exists(file, exists) && !exists) {
    std::ifstream in(file, std::ios::binary);
    std::uint64_t magic = 0, stored = 0, count = 0, checksum = 0;
    in.read(reinterpret_cast<char*>(&magic), 8).read(reinterpret_cast<char*>(&stored), 8);
    in.read(reinterpret_cast<char*>(&count), 8);
    std::vector<double> u(n);
    if (in && magic == kMagic && stored == key && count == n) {
      in.read(reinterpret_cast<char*>(u.data()), static_cast<std::streamsize>(n * sizeof(double)));
      in.read(reinterpret_cast<char*>(&checksum), 8);
      Hash h;
      h.range(u);
      if (in && checksum == h.get()) {
        model.setDisplacement(u);
        log->info("static state reused from {} (the same structure, loads and settings)", file.string());
        return {StaticReport{}, true};
      }
    }
    log->warn("static cache file {} does not read back whole; solving again and replacing it", file.string());
  }
  CachedStatic out{model.solveStatic(settings), false};
  if (file.empty()) return out;
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path tmp = fs::path(file).concat(fmt::format(".{}.tmp", ::getpid()));
  {
    std::ofstream f(tmp, std::ios::binary);
    const auto& u = model.displacement();
    const std::uint64_t count = n;
    Hash h;
    h.range(u);
    const std::uint64_t checksum = h.get();
    f.write(reinterpret_cast<const char*>(&kMagic), 8).write(reinterpret_cast<const char*>(&key), 8);
    f.write(reinterpret_cast<const char*>(&count), 8);
    f.write(reinterpret_cast<const char*>(u.data()), static_cast<std::streamsize>(n * sizeof(double)));
    f.write(reinterpret_cast<const char*>(&checksum), 8);
    if (!f) {
      log->warn("cannot write the static cache file {}; the next run solves again", tmp.string());
      fs::remove(tmp, ec);
      return out;
    }
  }
  fs::rename(tmp, file, ec);
  if (ec) fs::remove(tmp, ec);
  return out;
}

}  // namespace fem
