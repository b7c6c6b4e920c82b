#pragma once
// The time steps a DEM scene may take, estimated from its bodies, walls and laws: what the scene's dt is
// checked against (dem/scene.hpp), what a diagnosis recommends (dem/stability_monitor.hpp) and what a
// coupled run's participant reports as its stable step (dem/coupled_dem.hpp).

namespace dem {

class Simulation;

/// The largest stable step over all spheres and the laws they use [s] (Rayleigh for Hertz–Mindlin, the
/// spring's period for the linear law): stability only, blind to the impact speed.
double criticalTimeStep(const Simulation& sim);
/// The shortest elastic head-on contact duration at `approachSpeed` over every free sphere and the laws it
/// uses, against a sphere of each material it can touch (its smallest radius and mass) or a wall / fixed
/// body (R* = R, m* = m) [s]. Hertz contacts shorten as the speed grows (t_c ∝ v^{-1/5}).
double contactDuration(const Simulation& sim, double approachSpeed);
/// The largest step the scene should take: min(dt_safety × criticalTimeStep, contactDuration(approachSpeed)
/// / steps_per_contact) [s].
double safeTimeStep(const Simulation& sim, double approachSpeed);
/// The fastest approach the scene can reach, estimated before it runs: the two fastest of the free bodies'
/// and walls' initial speeds head-on, plus the free-fall speed √(2 |g| H) over the scene's extent H along
/// gravity (sphere centres, plane points, mesh nodes) [m/s].
double approachSpeedEstimate(const Simulation& sim);

}  // namespace dem
