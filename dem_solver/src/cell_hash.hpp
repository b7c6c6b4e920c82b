#pragma once
// A sparse grid of cubic cells holding ids by position: for the one-off neighbour searches of scene
// building (bonds at the start, a specimen's random placement), where the simulation's own cell list is
// not there yet.
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace dem::detail {

class CellHash {
 public:
  /// Cells of edge `cell` > 0: ids within `cell` of a point lie in its cell or the 26 around.
  explicit CellHash(double cell) : cell_(cell) {}
  void insert(std::uint32_t id, const Eigen::Vector3d& x) { cells_[keyOf(x)].push_back(id); }
  /// Calls near(id) for every id in the 27 cells around x, until it returns false; false if one did.
  template <class Near>
  bool forEachNear(const Eigen::Vector3d& x, Near&& near) const {
    const Key k = keyOf(x);
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz)
          if (auto it = cells_.find(Key{k.x + dx, k.y + dy, k.z + dz}); it != cells_.end())
            for (auto id : it->second)
              if (!near(id)) return false;
    return true;
  }

 private:
  struct Key {
    std::int64_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      return static_cast<std::size_t>(k.x * 73856093 ^ k.y * 19349663 ^ k.z * 83492791);
    }
  };
  Key keyOf(const Eigen::Vector3d& x) const {
    return {static_cast<std::int64_t>(std::floor(x.x() / cell_)), static_cast<std::int64_t>(std::floor(x.y() / cell_)),
            static_cast<std::int64_t>(std::floor(x.z() / cell_))};
  }
  double cell_;
  std::unordered_map<Key, std::vector<std::uint32_t>, Hash> cells_;
};

}  // namespace dem::detail
