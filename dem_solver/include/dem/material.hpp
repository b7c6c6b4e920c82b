#pragma once
#include <string>

namespace dem {

/// A DEM material. Elastic constants feed Hertz–Mindlin and the Rayleigh time step.
struct Material {
  std::string name;
  double density = 0.0;        ///< ρ [kg/m³]
  double youngModulus = 0.0;   ///< E [Pa]
  double poissonRatio = 0.25;  ///< ν [-]
  /// A wall that does not deform (`rigid: true`): its compliances (1 − ν²)/E and (2 − ν)/G are 0 in the
  /// contact's E* and G*. Walls only: a body needs a finite stiffness for its own time step.
  bool rigid = false;
  double shearModulus() const { return youngModulus / (2.0 * (1.0 + poissonRatio)); }  ///< G [Pa]
  double normalCompliance() const { return rigid ? 0.0 : (1 - poissonRatio * poissonRatio) / youngModulus; }  ///< [1/Pa]
  double shearCompliance() const { return rigid ? 0.0 : (2 - poissonRatio) / shearModulus(); }             ///< [1/Pa]
};

}  // namespace dem
