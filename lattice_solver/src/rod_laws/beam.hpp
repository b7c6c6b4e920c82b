#pragma once
#include "lattice/rod_law.hpp"

namespace lattice {

/// The LGM rod as a beam-like rigid-body-spring element (Kawai 1978; Bolander & Saito 1998): two rigid
/// halves joined at the rod's midpoint by a normal spring k_n = k_l E₀A/L, two shear springs
/// k_s = k_b E₀A/L (they resist the change of angle between the rod and its nodes, the LGM's bending),
/// a torsion spring k_T = k_t E₀ A²/(6L) and two rotational bending springs k_R = k_b E₀ A²/(12L)
/// (square section: I = A²/12, I_p = A²/6). README "Rod law" has the derivation.
class Beam : public RodLaw {
 public:
  std::string name() const override { return "beam"; }
  RodSprings springs(double length, const RelativeStiffness& k, const RodSection& section) const override;
};

}  // namespace lattice
