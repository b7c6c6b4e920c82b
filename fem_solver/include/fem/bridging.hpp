#pragma once
// The continuum's side of a bridging domain (Xiao & Belytschko 2004; Kozicki & Donzé 2008 §2.3;
// docs/validation/bridging.md): in the overlap each element carries the share α_e of its energy, α at
// its centroid (common::BridgingZone, raised to min_weight), so its internal forces, strain energy and
// lumped mass are scaled by α_e and the nodal masses become Σ_e α_e m_e,I. The coupler's multipliers
// then tie the nodes to the particles inside the elements.
#include <cstdint>
#include <vector>

#include "common/bridging_zone.hpp"
#include "fem/model.hpp"

namespace fem {

/// Sets every block's element weights from the zone (blocks entirely outside it stay unweighted).
void weighBridgingZone(Model& model, const common::BridgingZone& zone);

/// The overlap: the elements with a node in the zone (a weight below one there: every point of the zone
/// lies in one of them), as cells of their nodes (local indices), and those nodes (model indices) in the
/// order of the cells' first use.
struct BridgeCells {
  std::vector<std::uint32_t> nodes;
  int nodesPerCell = 0;  ///< 2 segments, 3 triangles, 4 tetrahedra
  std::vector<std::uint32_t> cells;
};
/// Throws common::ConfigError when the zone holds no element, or elements of different kinds.
BridgeCells bridgeCells(const Model& model, const common::BridgingZone& zone);

}  // namespace fem
