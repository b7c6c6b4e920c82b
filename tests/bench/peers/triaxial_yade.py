# The triaxial test of configs/dem/triaxial.yaml in YADE 2023.02a (Debian /usr/bin/yade) on the same
# sample, with the same laws and loading (docs/validation/triaxial.md):
#   spheres, walls and bonds: dem_solver's consolidated state, read from its dem.h5
#     (/triaxial/consolidated_spheres: x y z r; /triaxial/consolidated_box: lo, hi; /triaxial/bonds: the
#     pairs it cemented); our z (axial) is YADE's y (TriaxialStressController's height), so
#     (x, y, z) -> (x, z, y);
#   CohFrictMat: young = E, poisson = k_s/k_n (YADE's Ip2_CohFrictMat_CohFrictMat_CohFrictPhys takes
#     k_n = 2 E_a R_a E_b R_b / (E_a R_a + E_b R_b) and k_s = poisson × k_n for equal materials: ours),
#     friction atan(mu), fragile bonds without moments; YADE's adhesions are cohesion × min(R_a, R_b)²,
#     ours σ × π min(R_a, R_b)²: normalCohesion = π σ_t, shearCohesion = π c;
#     positions, radii and bonds carry over, the contacts' shear forces do not (they start at zero, as
#     the pairs' normal forces stay those of the same overlaps): the state compressed is ours. YADE's first
#     step bonds its touching pairs (setCohesionNow, which like ours keeps a bonded pair's compression),
#     then every bond that is not one of ours is undone and each of ours that YADE did not bond is made:
#     the bond sets are equal, and the counts are printed;
#   platens: frictionless rigid boxes (modulus 1e30): YADE's sphere–box stiffness is then 2 E r, the
#     sphere's spring alone. dem_solver's rigid planes take 4 E r (E_h → 2E with R* = r), so
#     tests/bench/triaxial_vs_yade.sh runs ours with the platen pair's modulus at E/2, which gives 2 E r;
#   Cundall damping 0.2 (NewtonIntegrator), dt as ours, TriaxialStressController with the lateral walls
#     at σ3 (goal < 0: compression) and the platens closing at a constant speed ε̇ h0 as ours (its goal2 is
#     a rate of the current height, so it is set to ε̇ h0 / h as h shrinks), to the same engineering
#     strain (h0 − h) / h0 = STRAIN_END.
#
# Usage:
#   H5=results/triaxial_100/dem.h5 SIGMA3=1e5 RATE=1.0 STRAIN_END=0.12 DT=1.19e-6 OUT=yade.csv \
#     yade -n -x -j1 tests/bench/peers/triaxial_yade.py
# Env (defaults = configs/dem/triaxial.yaml): E=1e8 ALPHA=0.25 MU=0.5 RHO=2650 TENSILE=2e5 COHESION=2e5
#   DAMPING=0.2 SERIES=0.001 (a row every Δε1).
# Output: OUT, a CSV with columns axial_strain, volumetric_strain, deviatoric_stress, sigma_axial,
#   sigma_lateral (compression positive, from the walls), broken_bonds; and one line
#   "RESULT yade N=<N> steps=<steps> seconds=<t> peak_q=<q> strain_at_peak=<e>" where <t> is the wall time
#   of the compression's O.run only.
import math
import os
import time

import h5py

from yade import O, utils
from yade.wrapper import (CohFrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb, Bo1_Box_Aabb,
                          InteractionLoop, Ig2_Sphere_Sphere_ScGeom6D, Ig2_Box_Sphere_ScGeom6D,
                          Ip2_CohFrictMat_CohFrictMat_CohFrictPhys, Law2_ScGeom6D_CohFrictPhys_CohesionMoment,
                          NewtonIntegrator, TriaxialStressController)
from yade.minieigenHP import Vector3

env = os.environ.get
h5 = env("H5")
sigma3 = float(env("SIGMA3", 1e5))
rate = float(env("RATE", 1.0))
strain_end = float(env("STRAIN_END", 0.12))
dt = float(env("DT", 1.1923512797337067e-06))
out = env("OUT", "yade_triaxial.csv")
E, alpha, mu, rho = float(env("E", 1e8)), float(env("ALPHA", 0.25)), float(env("MU", 0.5)), float(env("RHO", 2650))
tensile, cohesion = float(env("TENSILE", 2e5)), float(env("COHESION", 2e5))
damping, series = float(env("DAMPING", 0.2)), float(env("SERIES", 0.001))


def swap(v):  # ours (x, y, z) -> YADE's (x, z, y): our axial z is its height y
    return Vector3(v[0], v[2], v[1])


with h5py.File(h5, "r") as f:
    spheres = f["/triaxial/consolidated_spheres"][()]
    box = f["/triaxial/consolidated_box"][()].reshape(2, 3)
    ours = {(int(a), int(b)) for a, b in f["/triaxial/bonds"][()].reshape(-1, 2)}
lo, hi = swap(box[0]), swap(box[1])

grain = O.materials.append(CohFrictMat(young=E, poisson=alpha, frictionAngle=math.atan(mu), density=rho,
                                       normalCohesion=math.pi * tensile, shearCohesion=math.pi * cohesion,
                                       isCohesive=True, fragile=True, momentRotationLaw=False, label="grain"))
platen = O.materials.append(CohFrictMat(young=1e30, poisson=alpha, frictionAngle=0.0, density=0.0,
                                        isCohesive=False, label="platen"))
thickness = 0.1 * float((hi - lo).norm())
walls = O.bodies.append(utils.aabbWalls([lo, hi], thickness=thickness, material="platen"))
ids = O.bodies.append([utils.sphere(swap(s[:3]), s[3], material="grain") for s in spheres])

triax = TriaxialStressController(
    wall_left_id=walls[0], wall_right_id=walls[1], wall_bottom_id=walls[2], wall_top_id=walls[3],
    wall_back_id=walls[4], wall_front_id=walls[5], thickness=thickness, internalCompaction=False,
    stressMask=7, goal1=-sigma3, goal2=-sigma3, goal3=-sigma3, max_vel=rate * float(hi[1] - lo[1]),
    label="triax")
ip2 = Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=False, setCohesionOnNewContacts=False)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom6D(), Ig2_Box_Sphere_ScGeom6D()], [ip2],
                    [Law2_ScGeom6D_CohFrictPhys_CohesionMoment()]),
    triax,
    NewtonIntegrator(damping=damping),
]
O.dt = dt


def bonded(broken):
    return sum(1 for i in O.interactions
               if i.isReal and getattr(i.phys, "cohesionBroken", True) == broken and getattr(i.phys, "normalAdhesion", 0) > 0)


# One step makes the contacts and bonds YADE's touching pairs; then the bond set is made ours.
ip2.setCohesionNow = True
O.step()
ip2.setCohesionNow = False
first = ids[0]
undone = made = 0
for i in O.interactions:
    pair = (i.id1 - first, i.id2 - first)
    if i.isReal and min(pair) >= 0 and not i.phys.cohesionBroken and pair not in ours:
        i.phys.cohesionBroken, i.phys.normalAdhesion, i.phys.shearAdhesion = True, 0.0, 0.0
        undone += 1
for a, b in sorted(ours):
    i = O.interactions[a + first, b + first] if O.interactions.has(a + first, b + first) else None
    if i is None or not i.isReal:
        i = utils.createInteraction(a + first, b + first)
    if i.phys.cohesionBroken or i.phys.normalAdhesion == 0:
        r = min(O.bodies[a + first].shape.radius, O.bodies[b + first].shape.radius)
        i.phys.cohesionBroken = False
        i.phys.normalAdhesion, i.phys.shearAdhesion = math.pi * tensile * r * r, math.pi * cohesion * r * r
        made += 1
bonds0 = bonded(False)
print(f"BONDS ours={len(ours)} yade={bonds0} undone={undone} made={made}")


def state():
    w, h, d = triax.width, triax.height, triax.depth
    fy = abs(O.forces.f(walls[3])[1] + 0.0)
    fx = 0.5 * (abs(O.forces.f(walls[0])[0]) + abs(O.forces.f(walls[1])[0]))
    fz = 0.5 * (abs(O.forces.f(walls[4])[2]) + abs(O.forces.f(walls[5])[2]))
    s_axial, s_lat = fy / (w * d), 0.5 * (fx / (h * d) + fz / (w * h))
    return w, h, d, s_axial, s_lat


w0, h0, d0, _, _ = state()
v0 = w0 * h0 * d0
triax.stressMask = 5  # x and z at σ3, y (axial) at a strain rate
triax.goal2 = -rate
rows, nxt, peak, peak_strain = [], series, -1.0, 0.0
chunk = max(1, int(round(series / rate / dt / 4)))  # four looks per row
start = time.perf_counter()
steps, e1 = 0, 0.0
while e1 + 1e-12 < strain_end:
    # The last chunk only as long as the strain still to go needs (at the speed ε̇ h0).
    n = max(1, min(chunk, int(math.ceil((strain_end - e1) / rate / dt))))
    O.run(n, True)
    steps += n
    w, h, d, s_axial, s_lat = state()
    triax.goal2 = -rate * h0 / h  # the platens' speed ε̇ h0, as ours
    e1 = (h0 - h) / h0
    if e1 + 1e-12 >= nxt or e1 + 1e-12 >= strain_end:
        broken = bonds0 - bonded(False)
        q = s_axial - s_lat
        rows.append((e1, (v0 - w * h * d) / v0, q, s_axial, s_lat, broken))
        if q > peak:
            peak, peak_strain = q, e1
        nxt += series
seconds = time.perf_counter() - start
with open(out, "w") as f:
    f.write("axial_strain,volumetric_strain,deviatoric_stress,sigma_axial,sigma_lateral,broken_bonds\n")
    for r in rows:
        f.write(",".join(f"{x:.9g}" for x in r) + "\n")
print(f"RESULT yade N={len(ids)} steps={steps} seconds={seconds:.3f} peak_q={peak:.6g} strain_at_peak={peak_strain:.5f} "
      f"bonds={bonds0} bonds_ours={len(ours)}")
