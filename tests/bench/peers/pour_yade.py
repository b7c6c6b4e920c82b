# "pour" peer benchmark for YADE 2023.02a (Debian /usr/bin/yade).
# Identical physics to pour.liggghts and our own solver's pour benchmark:
#   N = nx*ny*nz spheres, R = 0.01 m, rho = 2500, E = 5e6 Pa, nu = 0.25,
#   read from $INITIAL (peers/initial_state.py: x y z r per line): dem_solver's generated sites, a
#   cubic lattice of s = 0.021 m, site (i,j,k) at ((i+.5)s, (j+.5)s, (k+.5)s) jittered by up to ±0.025 R,
#   5 planar walls (floor z=0, x=0, x=nx*s, y=0, y=ny*s), no ceiling,
#   Hertz-Mindlin with tangential history, mu = 0.5, e = 0.5, gravity 9.81,
#   no global (Cundall) damping, dt = 2.42e-4 s (20 % of the Rayleigh step π R √(ρ/G)/(0.1631 ν + 0.8766) = 1.2108e-3 s)
#   up to 25 layers, shorter above (../pour_shape.sh, passed as dt in the environment by run_peers.sh).
#
# Usage (see run_peers.sh):
#   nx=25 ny=20 nz=20 steps=20000 INITIAL=initial_N10000.txt yade -n -x -j1 pour_yade.py
# Optional env: DEBUG=1 (print contact parameters and final position extents),
#               VERLET=<m> (collider verletDist; default: YADE's own, -0.5 = 0.5*min radius).
# Output: one line "RESULT yade N=<N> steps=<steps> seconds=<t> particle_steps_per_s=<x> contacts_per_sphere=<c>"
# where <t> is the wall-clock time of O.run(steps, True) only.
import os
import sys
import time
from math import atan

from yade import O, utils
from yade.wrapper import (FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,
                          Bo1_Wall_Aabb, InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                          Ig2_Wall_Sphere_ScGeom, Ip2_FrictMat_FrictMat_MindlinPhys,
                          Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, Sphere)

nx = int(os.environ.get("nx", 25))
ny = int(os.environ.get("ny", 20))
nz = int(os.environ.get("nz", 20))
steps = int(os.environ.get("steps", 20000))
debug = int(os.environ.get("DEBUG", 0))

R = 0.01
s = 0.021
xhi, yhi = nx * s, ny * s

mat = O.materials.append(FrictMat(young=5e6, poisson=0.25, density=2500,
                                  frictionAngle=atan(0.5), label="grain"))

# 5 planar walls of the same material; sense=+1/-1 = spheres interact from the inside only.
O.bodies.append([
    utils.wall(0.0, axis=2, sense=1, material=mat),    # floor z = 0
    utils.wall(0.0, axis=0, sense=1, material=mat),    # x = 0
    utils.wall(xhi, axis=0, sense=-1, material=mat),   # x = nx*s
    utils.wall(0.0, axis=1, sense=1, material=mat),    # y = 0
    utils.wall(yhi, axis=1, sense=-1, material=mat),   # y = ny*s
])

with open(os.environ["INITIAL"]) as f:
    sites = [[float(v) for v in line.split()] for line in f if line.strip()]
O.bodies.append([utils.sphere((x, y, z), r, material=mat) for x, y, z, r in sites])

collider = InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb()])
if "VERLET" in os.environ:
    collider.verletDist = float(os.environ["VERLET"])

O.engines = [
    ForceResetter(),
    collider,
    InteractionLoop(
        # hertzian=True: the wall acts as a sphere of 1e8*R (effective radius ~R, the Hertz
        # sphere-plane limit, as in LIGGGHTS). YADE's default (False) gives the wall the sphere's
        # own radius, i.e. R_eff = R/2 for wall contacts.
        [Ig2_Sphere_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom(hertzian=True)],
        [Ip2_FrictMat_FrictMat_MindlinPhys(en=0.5, es=0.5)],
        [Law2_ScGeom_MindlinPhys_Mindlin()],
    ),
    NewtonIntegrator(damping=0.0, gravity=(0, 0, -9.81)),
]
O.dt = float(os.environ.get("dt", 2.42e-4))  # run_peers.sh scales it with the height

n_spheres = sum(1 for b in O.bodies if isinstance(b.shape, Sphere))
assert n_spheres == nx * ny * nz, (n_spheres, nx * ny * nz)

t0 = time.time()
O.run(steps, True)
elapsed = time.time() - t0

if debug:
    ps = [b.state.pos for b in O.bodies if isinstance(b.shape, Sphere)]
    masses = sum(b.state.mass for b in O.bodies if isinstance(b.shape, Sphere))
    ke = sum(0.5 * b.state.mass * b.state.vel.squaredNorm() for b in O.bodies if isinstance(b.shape, Sphere))
    print("DEBUG yade threads=%d spheres=%d total_mass=%.8g ke=%.6g" % (O.numThreads, n_spheres, masses, ke))
    for ax, name in enumerate("xyz"):
        print("DEBUG yade %s: min=%.7g max=%.7g" % (name, min(p[ax] for p in ps), max(p[ax] for p in ps)))
    for i in O.interactions:
        if i.isReal:
            kind = "wall" if i.id1 < 5 or i.id2 < 5 else "sphere"
            print("DEBUG yade first %s contact: betan=%.6g betas=%.6g kno=%.6g kso=%.6g tanPhi=%.4g" % (
                kind, i.phys.betan, i.phys.betas, i.phys.kno, i.phys.kso, i.phys.tangensOfFrictionAngle))
            break

N = nx * ny * nz
pairs = sum(1 for i in O.interactions if i.isReal and i.id1 >= 5 and i.id2 >= 5)  # bodies 0-4: the walls
print("RESULT yade N=%d steps=%d seconds=%.6f particle_steps_per_s=%.6g contacts_per_sphere=%.4g" % (
    N, steps, elapsed, N * steps / elapsed, 2.0 * pairs / N))
sys.stdout.flush()
