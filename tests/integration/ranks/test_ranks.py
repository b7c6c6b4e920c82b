#!/usr/bin/env python3
"""configs/dem/pour.yaml on 2, 3 and 4 MPI ranks (oversubscribed on a small machine) against one rank.

Run with:  python3 test_ranks.py MPIRUN BIN_DIR SOURCE_DIR OUT_DIR

- To t = 0.2 s (3,672 steps, the spheres falling and the first of them landing, 336 touching pairs):
  the same sphere count and every centre within 1e-10 m of one rank's. Each sphere pair is computed on
  one rank, as on one rank; only the order in which a sphere's forces are summed differs (the share a
  neighbouring rank computed is added last), a round-off of 1e-16 of the force per step, which the
  collisions then amplify: 3e-14 to 2e-13 m at 0.2 s, 1e-6 m by 0.8 s (a ten-thousandth of a radius).
- The whole pour (1 s) on 2 ranks: the settled bed's coordination number within 2 % of one rank's,
  its packing fraction within 0.5 %, both at rest, and the energy ledger closing as well.
- The series at 0.2 s (the summed ledger, the walls' forces, two tracked bodies with their contact counts)
  within 1e-6 of one rank's (measured 1e-12 to 2e-10).
- Contacts from the first step across the cut (a row of free spheres on a row of fixed ones on the floor,
  row.yaml written here), on 2 and 3 ranks: every centre and series as one rank's (measured equal to the
  bit but for the ledger's sums, 2e-11). A first step without the other rank's forces, or a fixed
  sphere's wall contact counted on two ranks, moves them by 1e-7 m and the ledger by 1e-4 to 1e-1.
- The pour onto a triangulated floor (a mesh wall) to 0.3 s on 2 ranks: centres, wall contacts, series and
  the mesh's node forces as one rank's.
- configs/dem/bonded_block.yaml with 3 MPa bonds on 2 and 3 ranks: the same 540 bonds, broken bonds and
  pieces as one rank, the fracture energy within 1e-9 and the centres within 1e-10 m.
- Restart on as many ranks: the pour and the bonded block on 2 ranks, stopped after a checkpoint and
  restarted, equal to the bit the runs that never stopped; a checkpoint restarted on one rank, or without
  rank 1's share, is exit 2 saying why.
- Restart on another number of ranks: the pour 2 → 3 and 3 → 2 ranks, the bonded block 3 → 2 and the
  pour onto the mesh floor 2 → 3, each stopped halfway: the centres within 1e-10 m of the 2-rank runs that
  never stopped, the same touching pairs, wall contacts, broken bonds and pieces; a missing share is exit 2.
- Rigid clusters crossing the cut (three 64-sphere cubes under 196 loose spheres, the middle one spinning
  across the cut of 2 ranks) on 2 and 3 ranks: every sphere centre in every snapshot within 1e-10 m of one
  rank's, the tracked clusters' series within 1e-6, the same contacts.
- A scene a run on several ranks cannot take (rolling resistance) ends with exit 2 naming the key.
"""
import os
import pathlib
import shutil
import subprocess
import sys

import h5py
import numpy as np
import yaml

mpirun, bindir, src, out = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3]), pathlib.Path(sys.argv[4])
shutil.rmtree(out, ignore_errors=True)
out.mkdir(parents=True)
# Open MPI in containers and CI: runs as root, more ranks than cores (a waiting rank yields its core to
# the others instead of spinning), no single-copy shared memory.
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1",
           OMPI_MCA_btl_vader_single_copy_mechanism="none")
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def run(ranks, name, *sets, scene="configs/dem/pour.yaml"):
    folder = out / name
    command = [str(bindir / "dem_solver"), str(src / scene), "--out", str(folder), "--quiet", "--threads", "1"]
    for s in sets:
        command += ["--set", s]
    if ranks > 1:
        command = [mpirun, "-np", str(ranks)] + command
    r = subprocess.run(command, env=env, capture_output=True, text=True, timeout=240)
    summary = yaml.safe_load((folder / "summary.yaml").read_text()) if (folder / "summary.yaml").exists() else {}
    return r, summary, folder


def centres(folder):
    with h5py.File(folder / "dem.h5") as f:
        steps = f["particles/spheres/steps"]
        return steps[sorted(steps.keys())[-1]]["position"][:]


early = ["end_time=0.2", "output={interval: 0.2, track: [0, 999]}"]


def series(folder, name):
    with h5py.File(folder / "dem.h5") as f:
        return {k: v[:] for k, v in f["timeseries"][name].items()}


def series_gap(one, other, name, floor=1e-300):
    """The largest difference of series `name` between two runs, per column relative to the first run's
    largest value there (at least `floor`); infinite if their columns differ."""
    a, b = series(one, name), series(other, name)
    if a.keys() != b.keys():
        return float("inf")
    return max(float(np.max(np.abs(a[c] - b[c])) / max(float(np.max(np.abs(a[c]))), floor)) for c in a)


one, s1, f1 = run(1, "early_1", *early)
check(one.returncode == 0, f"one rank to 0.2 s: exit {one.returncode} {one.stderr[-500:]}")
x1 = centres(f1)
for ranks in (2, 3, 4):
    r, s, f = run(ranks, f"early_{ranks}", *early)
    check(r.returncode == 0, f"{ranks} ranks to 0.2 s: exit {r.returncode} {r.stderr[-500:]}")
    if r.returncode != 0:
        continue
    x = centres(f)
    check(x.shape == x1.shape, f"{ranks} ranks: {len(x)} spheres written, one rank {len(x1)}")
    worst = float(np.max(np.abs(x - x1)))
    check(worst <= 1e-10, f"{ranks} ranks: centres within {worst:.2e} m of one rank's at 0.2 s (allowed 1e-10)")
    check(s["results"]["sphere_contacts_final"] == s1["results"]["sphere_contacts_final"],
          f"{ranks} ranks: {s['results']['sphere_contacts_final']} touching pairs, one rank "
          f"{s1['results']['sphere_contacts_final']}")
    # The series: the summed ledger and wall forces, and two tracked bodies with their contacts (a body's
    # pairs computed on another rank counted there).
    for name in ("energy", "walls", "body_0", "body_999"):
        worst = series_gap(f1, f, name)
        check(worst <= 1e-6, f"{ranks} ranks: series {name} within {worst:.1e} of one rank's")
    check(np.array_equal(series(f1, "body_0")["contacts"], series(f, "body_0")["contacts"]),
          f"{ranks} ranks: body 0's contact counts are one rank's")
    check(s["cost"]["ranks"] == ranks and s["cost"]["rank_migrations"] > 1,
          f"{ranks} ranks: cost.ranks {s['cost']['ranks']}, {s['cost']['rank_migrations']} cuts")

whole = ["output={interval: 0}"]
one, s1, _ = run(1, "pour_1", *whole)
two, s2, f2 = run(2, "pour_2", *whole)
check(one.returncode == 0 and two.returncode == 0, f"the whole pour: exits {one.returncode}, {two.returncode}")
if one.returncode == 0 and two.returncode == 0:
    a, b = s1["results"], s2["results"]
    check(a["spheres"] == b["spheres"] == 1000, f"spheres {a['spheres']}, {b['spheres']}")
    z1, z2 = a["coordination_number_final"], b["coordination_number_final"]
    check(abs(z2 - z1) <= 0.02 * z1, f"coordination number {z2:.4f} on 2 ranks, {z1:.4f} on one (within 2 %)")
    p1, p2 = a["packing_fraction"], b["packing_fraction"]
    check(abs(p2 - p1) <= 0.005 * p1, f"packing fraction {p2:.4f} on 2 ranks, {p1:.4f} on one (within 0.5 %)")
    check(a["kinetic_energy_final"] < 1e-4 and b["kinetic_energy_final"] < 1e-4,
          f"at rest: kinetic energy {a['kinetic_energy_final']:.2e} and {b['kinetic_energy_final']:.2e} J")
    check(b["energy_balance_error"] < 0.01, f"the ledger closes on 2 ranks: {b['energy_balance_error']:.4f}")
    check((f2 / "rank_1" / "summary.yaml").exists() and not (f2 / "rank_1" / "dem.h5").exists(),
          "rank 1 writes its log and summary in rank_1/, the results only rank 0")

# Contacts from the first step across the cut: a row of 12 fixed spheres on the floor, pressed 5 µm into
# it, and on them a row of 12 free ones pressed 5 µm into their neighbours (within the 0.1 % overlap a
# scene may start with), pushed along the row. The first step's forces, a fixed sphere's ghost (infinite
# mass, no wall contact of its own on the other rank) and the contacts' histories all cross the cut.
rows = "".join(f"  - {{material: m, radius: 0.01, position: [{0.019995 * i:.6f}, 0, 0.009995], fixed: true}}\n"
               for i in range(12))
rows += "".join(f"  - {{material: m, radius: 0.01, position: [{0.019995 * i:.6f}, 0, 0.02999], "
                f"velocity: [{0.05 * (i % 3):.2f}, 0, 0]}}\n" for i in range(12))
(out / "row.yaml").write_text(
    "materials: {m: {density: 2500, young_modulus: 5.0e6, poisson_ratio: 0.25}}\n"
    "interactions: [{materials: [m, m], law: hertz_mindlin, restitution: 0.5, friction: 0.5}]\n"
    "spheres:\n" + rows +
    "walls: [{type: plane, name: floor, material: m, point: [0, 0, 0], normal: [0, 0, 1]}]\n"
    "dt: 2.0e-5\nend_time: 0.02\noutput: {interval: 0.02, track: [17]}\n")
one, r1, g1 = run(1, "row_1", scene=str(out / "row.yaml"))
check(one.returncode == 0, f"the row on one rank: exit {one.returncode} {one.stderr[-300:]}")
for ranks in (2, 3):
    r, rs, g = run(ranks, f"row_{ranks}", scene=str(out / "row.yaml"))
    check(r.returncode == 0, f"the row on {ranks} ranks: exit {r.returncode} {r.stderr[-300:]}")
    if r.returncode != 0 or one.returncode != 0:
        continue
    worst = float(np.max(np.abs(centres(g) - centres(g1))))
    check(worst <= 1e-12, f"the row on {ranks} ranks: centres within {worst:.1e} m of one rank's (allowed 1e-12)")
    for name in ("energy", "walls", "body_17"):
        gap = series_gap(g1, g, name)
        check(gap <= 1e-9, f"the row on {ranks} ranks: series {name} within {gap:.1e} of one rank's")

# The pour onto a triangulated floor (mesh wall) to 0.3 s: each rank's spheres touch all of the mesh, its
# node forces and the wall's force summed over the ranks; the mesh contacts' histories move with their
# spheres.
mesh = ["walls[0]={type: mesh, name: floor, material: wall, grid: {origin: [-0.05, -0.05, 0], size: [0.3, 0.3], "
        "divisions: [12, 12], pattern: random, jitter: 0.3, seed: 7}}", "end_time=0.3",
        "output={interval: 0.3, track: [0, 999]}"]
one, m1, h1 = run(1, "mesh_1", *mesh)
two, m2, h2 = run(2, "mesh_2", *mesh)
check(one.returncode == 0 and two.returncode == 0, f"the mesh floor: exits {one.returncode}, {two.returncode}")
if one.returncode == 0 and two.returncode == 0:
    worst = float(np.max(np.abs(centres(h2) - centres(h1))))
    check(worst <= 1e-10, f"the mesh floor on 2 ranks: centres within {worst:.1e} m of one rank's")
    check(m1["results"]["wall_contacts_final"] == m2["results"]["wall_contacts_final"] > 100,
          f"the mesh floor: {m2['results']['wall_contacts_final']} wall contacts on 2 ranks, "
          f"{m1['results']['wall_contacts_final']} on one")
    for name in ("energy", "walls", "body_0"):
        gap = series_gap(h1, h2, name)
        check(gap <= 1e-6, f"the mesh floor on 2 ranks: series {name} within {gap:.1e} of one rank's")
    with h5py.File(h1 / "dem.h5") as f, h5py.File(h2 / "dem.h5") as g:
        steps = sorted(f["meshes/floor/steps"].keys())
        at = f"meshes/floor/steps/{steps[-1]}/point/force"
        fa, fb = f[at][:], g[at][:]
        gap = float(np.max(np.abs(fa - fb)) / np.max(np.abs(fa)))
        check(gap <= 1e-6, f"the mesh floor on 2 ranks: node forces at 0.3 s within {gap:.1e} of one rank's")

# configs/dem/bonded_block.yaml with 3 MPa bonds: 540 bonds, the impact's reflected wave splits the block.
# The bonds are created on the rank that computes their pair, move with it at the cuts, break there; the
# pieces are found from every rank's bonds.
def same_block(reference, reference_folder, summary, folder, what, than):
    """The bonded block's run in `folder` against the reference run: the same 540 bonds, broken bonds and
    pieces, the fracture energy within 1e-9 and the centres within 1e-10 m."""
    a, c = reference["results"], summary["results"]
    check(a["bonds_created"] == c["bonds_created"] == 540 and a["broken_bonds"] == c["broken_bonds"] > 0 and
          a["fragments"] == c["fragments"] > 1,
          f"{what}: {c['bonds_created']} bonds, {c['broken_bonds']} broken, {c['fragments']} pieces; {than} "
          f"{a['bonds_created']}, {a['broken_bonds']}, {a['fragments']}")
    gap = abs(c["bond_fracture_energy"] - a["bond_fracture_energy"]) / a["bond_fracture_energy"]
    check(gap <= 1e-9, f"{what}: fracture energy within {gap:.1e} of {than}'s")
    worst = float(np.max(np.abs(centres(folder) - centres(reference_folder))))
    check(worst <= 1e-10, f"{what}: centres within {worst:.1e} m of {than}'s")


weak = ["interactions[0].tensile_strength=3e6", "interactions[0].cohesion=3e6", "output={interval: 0.1}"]
one, k1, b1 = run(1, "block_1", *weak, scene="configs/dem/bonded_block.yaml")
for ranks in (2, 3):
    r, k, b = run(ranks, f"block_{ranks}", *weak, scene="configs/dem/bonded_block.yaml")
    check(one.returncode == 0 and r.returncode == 0, f"the bonded block on {ranks} ranks: exits {one.returncode}, "
          f"{r.returncode} {r.stderr[-300:]}")
    if one.returncode != 0 or r.returncode != 0:
        continue
    same_block(k1, b1, k, b, f"the bonded block on {ranks} ranks", "one rank")

# Restart on as many ranks: a run stopped after its checkpoint and restarted with --restart ends with the
# uninterrupted run's results to the bit (every rank takes up its own share: bodies, contacts, ghosts, the
# slabs and when the next cut is due). The pour (cuts before and after the checkpoint) and the bonded block
# (bonds breaking after it) on 2 ranks. Restarting on one rank, or without a rank's share, is exit 2 and
# says why. (An explicit dt: dt_fraction fits the step to the end time.)
compare = [sys.executable, str(src / "tools" / "compare_runs.py"), "--rtol", "0"]
sets_of, whole_of = {}, {}  # per scene: its settings, and the 2-rank run that never stopped
for name, scene, end, sets in (("pour", "configs/dem/pour.yaml", 0.3,
                                ["output={interval: 0.05, series_interval: 1.0e-3, checkpoint_interval: 0.1}",
                                 "dt=5.0e-5", "dt_fraction=null"]),
                               ("block", "configs/dem/bonded_block.yaml", 0.1,
                                weak[:2] + ["output={interval: 0.02, series_interval: 1.0e-4, checkpoint_interval: 0.04}",
                                            "dt=5.0e-6", "dt_fraction=null"])):
    a, ka, fa = run(2, f"restart_{name}_A", *sets, f"end_time={end}", scene=scene)
    sets_of[name], whole_of[name] = sets, (fa, ka)
    b, _, fb = run(2, f"restart_{name}_B", *sets, f"end_time={end / 2}", scene=scene)
    again = subprocess.run([mpirun, "-np", "2", str(bindir / "dem_solver"), str(src / scene), "--out", str(fb),
                            "--quiet", "--threads", "1", "--restart", "--set", f"end_time={end}"] +
                           [x for s in sets for x in ("--set", s)], env=env, capture_output=True, text=True, timeout=240)
    kb = yaml.safe_load((fb / "summary.yaml").read_text()) if (fb / "summary.yaml").exists() else {}
    at = (kb.get("cost") or {}).get("restarted_at_step")
    check(a.returncode == b.returncode == again.returncode == 0 and isinstance(at, int) and 0 < at < ka["steps"],
          f"the {name} on 2 ranks restarted at step {at} of {ka.get('steps')}: exits {a.returncode}, {b.returncode}, "
          f"{again.returncode} {again.stderr[-300:]}")
    same = subprocess.run(compare + [str(fa), str(fb)], capture_output=True, text=True)
    check(same.returncode == 0, f"the {name} restarted on 2 ranks equals the run that never stopped: "
          f"{same.stdout.strip().splitlines()[-1] if same.stdout.strip() else same.stderr[-300:]}")

# Restart on another number of ranks: the checkpoint of the run on P ranks taken up by P' ranks, rank r
# reading the shares r, r + P', …, the bodies with their contacts' histories and bonds moved to P' new
# slabs as in a cut. After it each sphere pair is computed as on one rank, so the run goes on as the one
# that never stopped within round-off (the order in which a sphere's forces add differs from then on):
# the pour 2 → 3 and 3 → 2 ranks, and the bonded block 3 → 2 (bonds breaking after the restart), against
# the 2-rank runs that never stopped.
def reshare(name, scene, end, sets, before, after):
    part = out / f"reshare_{name}_{before}_{after}"
    r, _, _ = run(before, part.name, *sets, f"end_time={end / 2}", scene=scene)
    again = subprocess.run([mpirun, "-np", str(after), str(bindir / "dem_solver"), str(src / scene), "--out", str(part),
                            "--quiet", "--threads", "1", "--restart", "--set", f"end_time={end}"] +
                           [x for s in sets for x in ("--set", s)], env=env, capture_output=True, text=True, timeout=240)
    summary = yaml.safe_load((part / "summary.yaml").read_text()) if (part / "summary.yaml").exists() else {}
    at = (summary.get("cost") or {}).get("restarted_at_step")
    ok = r.returncode == again.returncode == 0 and isinstance(at, int) and at > 0 and summary["cost"]["ranks"] == after
    check(ok, f"the {name} from {before} ranks restarted on {after} at step {at}: exits {r.returncode}, "
          f"{again.returncode} {again.stderr[-300:]}")
    return summary if ok else None, part


for before, after in ((2, 3), (3, 2)):
    k, part = reshare("pour", "configs/dem/pour.yaml", 0.3, sets_of["pour"], before, after)
    if k is None:
        continue
    fa, ka = whole_of["pour"]
    worst = float(np.max(np.abs(centres(part) - centres(fa))))
    check(worst <= 1e-10, f"the pour from {before} ranks on {after}: centres at 0.3 s within {worst:.1e} m of the "
          f"run that never stopped (allowed 1e-10)")
    check(k["results"]["sphere_contacts_final"] == ka["results"]["sphere_contacts_final"],
          f"the pour from {before} ranks on {after}: {k['results']['sphere_contacts_final']} touching pairs, "
          f"{ka['results']['sphere_contacts_final']} in the run that never stopped")
    for name in ("energy", "walls"):
        gap = series_gap(fa, part, name)
        check(gap <= 1e-6, f"the pour from {before} ranks on {after}: series {name} within {gap:.1e}")
k, part = reshare("block", "configs/dem/bonded_block.yaml", 0.1, sets_of["block"], 3, 2)
if k is not None:
    fa, ka = whole_of["block"]
    same_block(ka, fa, k, part, "the bonded block from 3 ranks on 2", "the 2-rank run that never stopped")
    gap = series_gap(fa, part, "energy")
    check(gap <= 1e-6, f"the bonded block from 3 ranks on 2: series energy within {gap:.1e}")
# The mesh floor's contacts (their histories keyed by triangle feature) from 2 ranks on 3.
mesh_sets = mesh[:1] + sets_of["pour"]
ref, kr, fr = run(2, "reshare_mesh_ref", *mesh_sets, "end_time=0.3")
k, part = reshare("mesh floor", "configs/dem/pour.yaml", 0.3, mesh_sets, 2, 3)
if k is not None and ref.returncode == 0:
    worst = float(np.max(np.abs(centres(part) - centres(fr))))
    check(worst <= 1e-10, f"the mesh floor from 2 ranks on 3: centres within {worst:.1e} m of the run that never "
          f"stopped")
    check(k["results"]["wall_contacts_final"] == kr["results"]["wall_contacts_final"] > 100,
          f"the mesh floor from 2 ranks on 3: {k['results']['wall_contacts_final']} wall contacts, "
          f"{kr['results']['wall_contacts_final']} in the run that never stopped")
    gap = series_gap(fr, part, "walls")
    check(gap <= 1e-6, f"the mesh floor from 2 ranks on 3: series walls within {gap:.1e}")
# A share missing on the way to another number of ranks: exit 2 on every rank, naming it.
lost, _, lost_folder = run(3, "reshare_lost", *sets_of["pour"], "end_time=0.15")
for share in (lost_folder / "checkpoint" / "rank_2").glob("*.h5"):
    share.unlink()
r = subprocess.run([mpirun, "-np", "2", str(bindir / "dem_solver"), str(src / "configs/dem/pour.yaml"), "--out",
                    str(lost_folder), "--quiet", "--restart"] + [x for s in sets_of["pour"] for x in ("--set", s)],
                   env=env, capture_output=True, text=True, timeout=240)
check(lost.returncode == 0 and r.returncode == 2 and "rank_2" in r.stderr,
      f"a 3-rank checkpoint without rank 2's share restarted on 2: exit {r.returncode}, {r.stderr[-200:]}")

fb = out / "restart_pour_B"
r = subprocess.run([str(bindir / "dem_solver"), str(src / "configs/dem/pour.yaml"), "--out", str(fb), "--quiet",
                    "--restart"], env=env, capture_output=True, text=True, timeout=240)
check(r.returncode == 2 and "2 ranks or more" in r.stderr,
      f"a 2-rank checkpoint restarted on one rank: exit {r.returncode}, {r.stderr[-200:]}")
for share in (fb / "checkpoint" / "rank_1").glob("*.h5"):
    share.unlink()
r = subprocess.run([mpirun, "-np", "2", str(bindir / "dem_solver"), str(src / "configs/dem/pour.yaml"), "--out",
                    str(fb), "--quiet", "--restart"], env=env, capture_output=True, text=True, timeout=240)
check(r.returncode == 2 and "rank_1" in r.stderr, f"a restart without rank 1's share: exit {r.returncode}, {r.stderr[-200:]}")

# Rigid clusters crossing the cut: three 64-sphere cubes on a floor under 196 loose spheres, the outer two
# sliding into the middle one, which spins on the cut of 2 ranks (the sphere-count median: its members lie
# on both sides). A cluster is owned by the rank of its centre of mass; every rank its members may touch
# holds it whole as a ghost; forces and torques on a ghost come back to its owner.
cube = (src / "configs" / "dem" / "clusters" / "cube_c3.yaml").resolve()
(out / "clusters.yaml").write_text(f"""
materials:
  concrete: {{density: 2600, young_modulus: 1.0e8, poisson_ratio: 0.25}}
  floor: {{density: 7800, young_modulus: 2.0e11, poisson_ratio: 0.3}}
interactions:
  - {{materials: [concrete, floor], law: hertz_mindlin, restitution: 0.5, friction: 0.5}}
  - {{materials: [concrete, concrete], law: hertz_mindlin, restitution: 0.5, friction: 0.5}}
generate:
  - {{material: concrete, count: 196, radius: [0.03, 0.04], box: {{min: [-1.2, -0.3, 0.75], max: [1.2, 0.3, 0.85]}}, seed: 5}}
clusters:
  - {{file: {cube}, material: concrete, mass: 180, position: [-0.8, 0.05, 0.35], velocity: [1.5, 0, 0],
     orientation: [0.9, 0.1, 0.3, 0.2]}}
  - {{file: {cube}, material: concrete, mass: 180, position: [0, 0, 0.3], angular_velocity: [0, 0, 3]}}
  - {{file: {cube}, material: concrete, mass: 180, position: [0.8, -0.05, 0.4], velocity: [-1.5, 0, 0],
     orientation: [0.5, 0.5, 0.5, 0.5]}}
walls:
  - {{type: plane, name: floor, material: floor, point: [0, 0, 0], normal: [0, 0, 1]}}
gravity: [0, 0, -9.81]
dt: 2.0e-5
end_time: 0.4
output: {{interval: 0.1, track: [196, 197, 198]}}
""")


def snapshots(folder):
    with h5py.File(folder / "dem.h5") as f:
        steps = f["particles/spheres/steps"]
        return [(steps[k]["position"][:], steps[k]["body"][:]) for k in sorted(steps.keys())]


one, c1, g1 = run(1, "clusters_1", scene=str(out / "clusters.yaml"))
check(one.returncode == 0, f"the clusters on one rank: exit {one.returncode} {one.stderr[-300:]}")
for ranks in (2, 3):
    r, c, g = run(ranks, f"clusters_{ranks}", scene=str(out / "clusters.yaml"))
    check(r.returncode == 0, f"the clusters on {ranks} ranks: exit {r.returncode} {r.stderr[-300:]}")
    if one.returncode != 0 or r.returncode != 0:
        continue
    a, b = snapshots(g1), snapshots(g)
    worst = max(float(np.max(np.abs(x[0] - y[0]))) for x, y in zip(a, b)) if len(a) == len(b) else float("inf")
    check(len(a) == len(b) == 5 and worst <= 1e-10,
          f"the clusters on {ranks} ranks: every sphere centre in {len(b)} snapshots within {worst:.1e} m of one rank's")
    for name in ("body_196", "body_197", "body_198", "energy"):
        gap = series_gap(g1, g, name, floor=1.0)
        check(gap <= 1e-6, f"the clusters on {ranks} ranks: series {name} within {gap:.1e} of one rank's")
    k1, k = c1["results"], c["results"]
    check(k["sphere_contacts_final"] == k1["sphere_contacts_final"] and k["wall_contacts_final"] == k1["wall_contacts_final"]
          and k["bodies"] == k1["bodies"] == 199 and k["spheres"] == k1["spheres"] == 388,
          f"the clusters on {ranks} ranks: {k['bodies']} bodies, {k['spheres']} spheres, {k['sphere_contacts_final']} "
          f"sphere and {k['wall_contacts_final']} wall contacts (one rank: {k1['sphere_contacts_final']}, "
          f"{k1['wall_contacts_final']})")
    if ranks == 2:
        spans = [float(min(np.median(p[:, 0]) - p[body == 197, 0].min(), p[body == 197, 0].max() - np.median(p[:, 0])))
                 for p, body in b]
        check(min(spans) > 0.05, f"the middle cluster lies across the cut of 2 ranks (the median) in every snapshot, "
              f"at least {min(spans):.3f} m on each side")

bad, _, folder = run(2, "rolling", "interactions[0].rolling_friction=0.05")
status = yaml.safe_load((folder / "summary.yaml").read_text())["status"] if (folder / "summary.yaml").exists() else ""
check(bad.returncode == 2 and "rolling_friction" in status,
      f"a scene with rolling resistance on 2 ranks: exit {bad.returncode}, {status[:120]}")

print(f"{len(failures)} failure(s)" if failures else "all passed")
sys.exit(1 if failures else 0)
