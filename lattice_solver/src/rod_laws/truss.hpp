#pragma once
#include "lattice/rod_law.hpp"

namespace lattice {

/// A central-force rod: only the normal spring k_n = k_l E₀A/L (the LGM with k_b = k_t = 0, "classical
/// bars", Kozicki & Donzé 2008 §2.2). Nodes have no rotational stiffness; the model drops those dofs.
class Truss : public RodLaw {
 public:
  std::string name() const override { return "truss"; }
  RodSprings springs(double length, const RelativeStiffness& k, const RodSection& section) const override;
};

}  // namespace lattice
