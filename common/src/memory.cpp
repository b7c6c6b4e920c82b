#include "common/memory.hpp"

#include <unistd.h>

#include <fmt/format.h>

namespace common {

double physicalMemoryBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && size > 0 ? static_cast<double>(pages) * static_cast<double>(size) : 0.0;
}

std::optional<std::string> memoryShortfall(double bytes, const std::string& what) {
  const double have = physicalMemoryBytes();
  if (have <= 0 || !(bytes > have)) return std::nullopt;  // NaN/inf estimates are refused too (!(x > have) is false)
  const auto gb = [](double b) { return b >= 1e15 ? fmt::format("{:.2g} GB", b / 1e9) : fmt::format("{:.1f} GB", b / 1e9); };
  return fmt::format("needs {} for {}, this machine has {}", gb(bytes), what, gb(have));
}

}  // namespace common
