#include "truss.hpp"

namespace lattice {

RodSprings Truss::springs(double length, const RelativeStiffness& k, const RodSection& section) const {
  return {k.kl * section.youngModulus * section.area / length, 0.0, 0.0, 0.0};
}

}  // namespace lattice
