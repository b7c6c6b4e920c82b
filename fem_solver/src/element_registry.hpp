#pragma once
// The element types (common/registry.hpp; CONTRIBUTING.md, "Adding one unit of physics"): each entry reads its
// own keys from its `elements[i]` entry, so a key of another type is an unknown key there (exit 2).

#include <memory>
#include <span>
#include <vector>

#include "common/config.hpp"
#include "common/registry.hpp"
#include "fem/element.hpp"

namespace fem {

struct ElementMaterial {
  double young, poisson, density;  ///< E [Pa], ν [-], ρ [kg/m³]
};

struct ElementType {
  const char* name;  ///< the scene's `type:`, equal to the file name
  int dimension;     ///< of the mesh group it is built on: 1 lines, 2 triangles, 3 tetrahedra
  std::unique_ptr<Element> (*make)(const common::Config& keys, const std::vector<std::uint32_t>& connectivity,
                                   const std::vector<Vec3>& reference, const ElementMaterial& material);
};

const common::Registry<ElementType>& elementTypes();

}  // namespace fem
