#pragma once
// The triaxial compression test of Kozicki & Donzé 2008 (§2.1, Figs. 17–18;
// dem_solver/README.md §Triaxial test). A scene with a `triaxial:` section is one: a specimen of spheres
// is generated (`specimen:`), grown to its porosity, consolidated isotropically to the confining
// pressure σ3 by six servo-controlled plane walls, then compressed axially (z) at a constant strain rate
// while the four lateral walls hold σ3.
//
// Conventions (soil mechanics): stresses and strains positive in compression; ε1 = (H0 − H)/H0 from the
// walls, ε_v = (V0 − V)/V0 from the box between them, both measured from the consolidated state;
// q = σ1 − σ3 with σ1 the axial wall stress and σ3 the mean lateral one.

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "common/config.hpp"
#include "dem/simulation.hpp"

namespace common {
class Summary;
}

namespace dem {

/// `specimen:` — how the sample is made.
struct SpecimenSettings {
  std::string material;
  std::uint32_t count = 0;
  double rmin = 0.0, rmax = 0.0;  ///< radii uniform in [rmin, rmax] (no sieve)
  /// Sieve curve instead: (radius [m], fraction of the mass in smaller grains), increasing, from 0 to 1.
  std::vector<std::pair<double, double>> sieve;
  Vec3 aspect = Vec3(1, 1, 2);  ///< box proportions x : y : z
  double porosity = 0.4;        ///< target after the growth [-]
  double compactionFriction = 0.0;  ///< μ while growing: lower gives a denser sample [-]
  int growthIncrements = 40;
  int relaxSteps = 300;  ///< steps after each growth increment
  std::uint64_t seed = 1;
};

/// A generated sample: spheres in the box [lo, hi].
struct Specimen {
  std::vector<Vec3> centre;
  std::vector<double> radius;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
};

/// The radii (drawn by number from the uniform range or the sieve curve), largest first, and the box of
/// the aspect that holds them at the target porosity; no centres. Deterministic for a seed.
Specimen specimenRadii(const SpecimenSettings& s);
/// specimenRadii(), and the spheres placed in the box at random without overlap, shrunk by `shrink`
/// (random sequential addition). Deterministic for a seed. Throws std::runtime_error if they do not fit.
Specimen randomSpecimen(const SpecimenSettings& s, double shrink);

/// `triaxial:` — the loading.
struct TriaxialSettings {
  std::string wallMaterial;
  double confining = 0.0;       ///< σ3 [Pa]
  double strainRate = 0.0;      ///< axial ε̇ [1/s]
  double strainEnd = 0.1;       ///< stop at this ε1 [-]
  double servoGain = 0.25;      ///< a wall moves by gain × (force error) / (its contact stiffness) per step [-]
  double tolerance = 0.01;      ///< consolidated when every wall stress is within this of σ3 [-]
  double unbalancedLimit = 0.01;  ///< … and the unbalanced force ratio below this [-]
  double maxConsolidationTime = 1.0;  ///< [s]
  double seriesStrain = 0.001;  ///< a series row every Δε1 [-]
  double snapshotStrain = 0.01;  ///< particles and force network every Δε1 [-]
  double macroCohesion = 0.0;   ///< cohesion c of the Mohr–Coulomb fit of the friction angle estimate [Pa]
  double dtFraction = 0.2;      ///< dt = this × the critical step [-]
  double localDamping = 0.2;    ///< Cundall λ (the scene's local_damping) [-]
};

struct TriaxialScene {
  common::Config cfg;  ///< the scene (materials and interactions are built per phase from it)
  SpecimenSettings specimen;
  TriaxialSettings test;
};

/// Whether the scene is a triaxial test.
bool isTriaxialScene(const common::Config& cfg);
/// Reads and checks it (located ConfigErrors, exit 2).
TriaxialScene loadTriaxialScene(const common::Config& cfg);
/// Runs it, writing `outDir`/dem.h5 (+ .xdmf; series `triaxial`, `energy`, `walls`, particle and force
/// network snapshots), `outDir`/peak.h5 (+ .xdmf: the state at the peak deviatoric stress) and the
/// summary results.
void runTriaxial(TriaxialScene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress);

/// The friction angle φ [rad] of the Mohr–Coulomb envelope with cohesion c through a peak q at σ3:
/// q = (q + 2 σ3) sin φ + 2 c cos φ.
double frictionAngle(double q, double sigma3, double cohesion);

}  // namespace dem
