// The particles' side of a bridging domain (Xiao & Belytschko 2004; Kozicki & Donzé 2008 §2.3;
// docs/validation/bridging.md): in the overlap the particles carry the share β of their energy. The
// kinetic energy is weighted through the masses (β at each body's centre), the bonds' elastic energy
// through their constants (β at the bond's midpoint), so that the weighted Hamiltonian's forces are the
// ordinary ones of a scaled model and the integrator needs no change. Contacts that are not bonds are
// not weighted: the overlap is meant to stay bonded (elastic); where it breaks, the continuum should not
// reach.
#include <fmt/format.h>

#include "common/errors.hpp"
#include "dem/simulation.hpp"
#include "integrator.hpp"

namespace dem {

void BondSet::weigh(const std::function<double(const Bond&)>& weight) {
  for (Bond& b : bonds_) {
    const double w = weight(b);
    b.kn *= w, b.ks *= w, b.tensile *= w, b.cohesion *= w, b.gammaN *= w, b.gammaT *= w;
    b.shearForce *= w;
  }
}

void Simulation::weighBridgingZone() {
  const common::BridgingZone& zone = *settings_.bridging;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const double w = zone.massWeight(bodies_.position[b]);
    if (w >= 1.0) continue;
    if (bodies_.sphereCount[b] != 1 || bodies_.fixed[b])
      throw common::ConfigError(fmt::format("bridging: body {} at ({:.6g}, {:.6g}, {:.6g}) lies in the zone but is {}; "
                                            "the overlap holds free single spheres only",
                                            b, bodies_.position[b].x(), bodies_.position[b].y(), bodies_.position[b].z(),
                                            bodies_.fixed[b] ? "fixed" : "a cluster"));
    bodies_.mass[b] *= w;
    bodies_.inertia[b] *= w;
    bodies_.angularMomentum[b] *= w;
  }
  const Vec3* at = bodies_.position.data();
  const auto& body = spheres_.body;
  bonds_.weigh([&](const Bond& bond) { return zone.massWeight(0.5 * (at[body[bond.a]] + at[body[bond.b]])); });
  integrator_->prepare(bodies_, loneSpheres_);  // its lone-sphere inertia is the weighted one
}

}  // namespace dem
