#pragma once
#include <string>

namespace dem {

/// A DEM material. Elastic constants feed Hertz–Mindlin and the Rayleigh time step.
struct Material {
  std::string name;
  double density = 0.0;        ///< ρ [kg/m³]
  double youngModulus = 0.0;   ///< E [Pa]
  double poissonRatio = 0.25;  ///< ν [-]
  double shearModulus() const { return youngModulus / (2.0 * (1.0 + poissonRatio)); }  ///< G [Pa]
};

}  // namespace dem
