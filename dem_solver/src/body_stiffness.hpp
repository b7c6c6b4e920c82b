#pragma once
// Per body, the normal stiffness and damping of its touching contacts: what dem::contactStableStep
// turns into the contact network's stable step (DEM README, "Run-time checks"). Each contact component
// adds its own contacts (addStiffness), so a new kind of contact adds itself here too.
#include <cmath>
#include <cstdint>
#include <vector>

#include "dem/model.hpp"

namespace dem {

struct BodyStiffness {
  std::vector<double> k, c;  ///< per body: Σ k_n [N/m], Σ c_n [N s/m]

  explicit BodyStiffness(std::size_t bodies) : k(bodies, 0.0), c(bodies, 0.0) {}
  /// A contact of `body` with something that does not move with it (a wall).
  void add(std::uint32_t body, double stiffness, double damping) {
    k[body] += stiffness;
    c[body] += damping;
  }
  /// A contact between bodies a and b: row b of M^{-1/2} K M^{-1/2} has the diagonal k/m_b and the
  /// coupling k/√(m_a m_b); scaled back by m_b, body b sees k (1 + √(m_b/m_a)) (k alone against a fixed
  /// body).
  void addPair(const Bodies& bodies, std::uint32_t a, std::uint32_t b, double stiffness, double damping) {
    add(pairTerms(bodies, a, b, stiffness, damping));
  }
  /// What addPair adds, computed apart from the sums (on any thread): a, k_a, c_a, b, k_b, c_b.
  struct PairTerms {
    std::uint32_t a, b;
    double ka, ca, kb, cb;
  };
  static PairTerms pairTerms(const Bodies& bodies, std::uint32_t a, std::uint32_t b, double stiffness, double damping) {
    const double ma = bodies.mass[a], mb = bodies.mass[b];
    // Equal masses (any monodisperse sample): 1 + √1 = 2 exactly, without the two roots and divisions
    // that are most of this per contact.
    if (ma == mb && !infiniteMass(bodies.fixed[a]) && !infiniteMass(bodies.fixed[b]))
      return {a, b, stiffness * 2.0, damping * 2.0, stiffness * 2.0, damping * 2.0};
    const double couplingA = infiniteMass(bodies.fixed[b]) ? 1.0 : 1.0 + std::sqrt(ma / mb);
    const double couplingB = infiniteMass(bodies.fixed[a]) ? 1.0 : 1.0 + std::sqrt(mb / ma);
    return {a, b, stiffness * couplingA, damping * couplingA, stiffness * couplingB, damping * couplingB};
  }
  void add(const PairTerms& t) {
    add(t.a, t.ka, t.ca);
    add(t.b, t.kb, t.cb);
  }
};

}  // namespace dem
