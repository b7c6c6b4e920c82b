#pragma once
// Sizes taken from a scene are checked against the machine before anything is allocated: a rod length
// of 1e-7 m or a grid of 1e9 × 1e9 cells ends with "needs 48 GB, this machine has 24" (exit 2), not
// with the machine swapping for an hour or std::bad_alloc (issue 30).

#include <optional>
#include <string>

namespace common {

/// Physical memory of this machine [bytes].
double physicalMemoryBytes();

/// "needs 48.0 GB for WHAT, this machine has 24.0 GB" if `bytes` exceeds the physical memory, else
/// nothing. The caller turns it into a located input error.
std::optional<std::string> memoryShortfall(double bytes, const std::string& what);

}  // namespace common
