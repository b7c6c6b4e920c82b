#pragma once
// What a run reads of its contacts between steps — summaries, snapshots' force networks, the stability
// monitor, the triaxial test's servo, the bodies' momentum — as free functions over the simulation's
// components, outside Simulation, which keeps the step.

#include <cstdint>
#include <tuple>
#include <vector>

#include "dem/simulation.hpp"

namespace dem {

/// The stable step of the contact network as it is now [s]: per free body, the Gershgorin bound of the
/// mass-normalised normal stiffness ω² ≤ Σ_c k_c (1/m_b + 1/√(m_b m_c)) (walls: k/m_b) and of the
/// dashpots alike, ζ = Σγ/(2 √(Σk m_b)), then 2/ω (√(1+ζ²) − ζ), central differences with damping
/// (Belytschko et al. 2000, §6.3). Compressed Hertz contacts stiffen (k = 2 E* √(R* δ)) and a sphere
/// with many of them needs a smaller step than the Rayleigh one. Infinite when nothing touches.
double contactStableStep(const Simulation& sim);

/// The force network now: one line per touching sphere pair between the two centres, with its elastic
/// normal force [N] (the dashpot's share, which needs the velocities, left out), and one per bond.
struct NetworkLine {
  Vec3 a, b;
  double normalForce;
};
std::vector<NetworkLine> contactNetwork(const Simulation& sim);

/// Per plane wall, the summed normal stiffness dF_n/dδ of its touching contacts at the last step [N/m]:
/// how much its force changes per metre it moves (a servo's gain follows from it).
std::vector<double> planeContactStiffness(const Simulation& sim);

/// Contacts at the last force pass: sphere-pair candidates (within the skin), touching sphere pairs,
/// touching sphere–wall contacts (planes and meshes).
struct ContactCounts {
  std::int64_t pairCandidates = 0, pairs = 0, walls = 0;
};
ContactCounts contactCounts(const Simulation& sim);

/// The sphere pair with the largest overlap right now: (a, b, overlap); overlap ≤ 0 when none touch.
std::tuple<std::uint32_t, std::uint32_t, double> largestSphereOverlap(const Simulation& sim);

/// Angular momentum of all free bodies about the origin (translation + spin), at the half step [kg m²/s].
Vec3 totalAngularMomentum(const Bodies& bodies);

}  // namespace dem
