#include "lattice/rod_law.hpp"

#include <stdexcept>

#include "rod_laws/beam.hpp"
#include "rod_laws/truss.hpp"

namespace lattice {

// The registration list: an explicit list, not self-registration (a static library drops those).
std::unique_ptr<RodLaw> makeRodLaw(const std::string& name) {
  if (name == "beam") return std::make_unique<Beam>();
  if (name == "truss") return std::make_unique<Truss>();
  throw std::invalid_argument("unknown rod law \"" + name + "\"");
}

const std::vector<std::string>& rodLawNames() {
  static const std::vector<std::string> names{"beam", "truss"};
  return names;
}

}  // namespace lattice
