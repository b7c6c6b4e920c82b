#include "beam.hpp"

namespace lattice {

RodSprings Beam::springs(double length, const RelativeStiffness& k, const RodSection& section) const {
  const double axial = section.youngModulus * section.area / length;
  const double rotational = section.youngModulus * section.area * section.area / length;
  return {k.kl * axial, k.kb * axial, k.kt * rotational / 6.0, k.kb * rotational / 12.0};
}

}  // namespace lattice
