#pragma once
// Damping from a coefficient of restitution, solved once at setup (dem_solver/README.md §Damping).
//
// A head-on collision with a normal force clamped at zero (no attraction) reduces, after scaling, to a
// one-parameter ODE whose solution does not depend on the impact speed:
//   linear:  s'' = −max(0, s + c s')                    (time 1/ω, ω² = k/m*; length v0/ω)
//   Hertz:   s'' = −max(0, s^{3/2} + c √(3/2) s^{1/4} s')  (length (m* v0²/K)^{2/5}, time length/v0)
// with s(0) = 0, s'(0) = 1; the restitution is −s' when s returns to 0. The dimensional damping is
//   linear: c_n = c √(m* k_n);   Hertz: γ_n = c √(S_n m*), S_n = 2E*√(R*δ)
// (for Hertz, c = −2√(5/6) β of the Tsuji form; the inversion here recovers the requested e exactly,
// where the Tsuji β(e), taken from the linear oscillator, does not).

namespace dem {

enum class NormalModel { kLinear, kHertz };

struct DimensionlessImpact {
  double restitution;  ///< e achieved
  double duration;     ///< contact duration in scaled time
  double maxOverlap;   ///< largest s
};

/// Integrates the scaled collision (RK4, h = 2e-4) for damping coefficient c ≥ 0.
DimensionlessImpact solveImpact(NormalModel model, double c);

/// The c whose collision gives restitution e ∈ (0, 1] (1e-10 on e); results are cached.
/// Throws std::invalid_argument when e is outside (0, 1] or below what c ≤ 50 can reach.
double dampingForRestitution(NormalModel model, double e);

/// Schwager & Pöschel (2007) closed form of e(ζ) for the linear dashpot with the force clamped at zero,
/// ζ = c/2 (used to validate solveImpact).
double linearRestitutionClamped(double zeta);

}  // namespace dem
