#!/usr/bin/env python3
"""dem_solver as a coupled participant on 2 MPI ranks: configs/rockfall/debris.yaml (1,200 stones onto the
rockfall net, implicit parallel coupling with IQN-ILS) to 0.04 s, against the same run with the DEM on one rank.

Run with:  python3 test_coupled_ranks.py MPIRUN BIN_DIR SOURCE_DIR OUT_DIR

1. The reference: cosim launches both participants, the DEM on one rank.
2. cosim launches the DEM as `mpirun -np 2 dem_solver …` (participants.dem.command; mpirun finds this
   build's dem_solver on the PATH the coupler gives it).
3. Across machines, here on loopback: the coupler listens on tcp://127.0.0.2:PORT with CURVE and its own
   key pair, the DEM is an external participant with a listed key, started by this script with mpirun on 2
   ranks and the run's token, as on nodes of its own (docs/guide.md, "A coupled run across machines").
In 2, 3 and 4: the run ends ok with the reference's windows and coupling iterations, every stone's centre
within 1e-10 m of the reference's and the net's sag and support force within 1e-9 relative (measured equal
to the bit: the stones' contacts with the net are each one rank's, and the node forces summed over 2 ranks
round alike here). The stones cross the slabs' cut (1.5 m/s across it), so the coupler's repeated windows
restore shares that a cut has changed since their start.
4. A spinning rigid block (a cluster of 8 spheres) among the stones, launched on 2 ranks, against one rank,
   compared as in 2 and 3 (measured: centres within 4e-17 m).
5. The DEM on 2 ranks diverging (energy_tolerance 1e-12, which the ledger exceeds once the stones press the
net, at 0.0326 s): every rank and the coupler end with exit 3 after the same window, and rank 1's summary
says what rank 0 stopped with.
Exit 0 if all holds, 1 with the reasons otherwise.
"""
import os
import pathlib
import shutil
import socket
import subprocess
import sys

import h5py
import numpy as np
import yaml

mpirun, bindir, src, out = (sys.argv[1], *(pathlib.Path(a).resolve() for a in sys.argv[2:5]))
shutil.rmtree(out, ignore_errors=True)
out.mkdir(parents=True)
scene = src / "configs" / "rockfall" / "debris.yaml"
dem_scene = src / "configs" / "rockfall" / "debris_dem.yaml"
cosim, dem_solver = str(bindir / "cosim"), str(bindir / "dem_solver")
# Open MPI in containers and CI: runs as root, more ranks than cores, no single-copy shared memory.
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1",
           OMPI_MCA_btl_vader_single_copy_mechanism="none")
# Not this build's bin/: the coupler puts it first on its participants' PATH, where mpirun finds dem_solver.
for var in ("COSIM_TOKEN", "COSIM_TOKEN_FILE", "COSIM_CURVE_SERVER_KEY", "COSIM_CURVE_SECRET_KEY",
            "COSIM_CURVE_SECRET_KEY_FILE", "COSIM_COUPLER_PID"):
    env.pop(var, None)
END = ["--set", "coupling.end_time=0.04"]
TOKEN = "debris-on-two-ranks-0123456789ab"
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        failures.append(what)


def load(path):
    return yaml.safe_load(pathlib.Path(path).read_text()) if pathlib.Path(path).exists() else {}


def tail(path, n=3000):
    return pathlib.Path(path).read_text()[-n:] if pathlib.Path(path).exists() else ""


def results(folder):
    with h5py.File(folder / "dem" / "dem.h5") as f:
        steps = f["particles/spheres/steps"]
        last = sorted(steps.keys())[-1]
        centres = steps[last]["position"][:]
    coupler = load(folder / "summary.yaml").get("results", {})
    fem = load(folder / "fem" / "summary.yaml").get("results", {})
    return {"last snapshot": last, "centres": centres, "windows": coupler.get("windows"),
            "iterations": coupler.get("mean_coupling_iterations"), "sag": fem.get("center_sag"),
            "support": fem.get("reaction_boundary", [0, 0, 0])[2]}


def compare(name, folder, ref):
    got = results(folder)
    check(got["windows"] == ref["windows"] and got["iterations"] == ref["iterations"],
          f"{name}: {got['windows']} windows, {got['iterations']} iterations each (one rank: {ref['windows']}, "
          f"{ref['iterations']})")
    check(got["last snapshot"] == ref["last snapshot"] and got["centres"].shape == ref["centres"].shape,
          f"{name}: snapshot {got['last snapshot']} of {got['centres'].shape[0]} stones")
    if got["centres"].shape == ref["centres"].shape:
        d = float(np.abs(got["centres"] - ref["centres"]).max())
        check(d <= 1e-10, f"{name}: every centre within 1e-10 m of one rank's (largest {d:.3g} m)")
    for key in ("sag", "support"):
        r = abs(got[key] - ref[key]) / abs(ref[key])
        check(r <= 1e-9, f"{name}: the net's {key} {got[key]:.12g} within 1e-9 of one rank's {ref[key]:.12g} ({r:.2g})")
    dem = load(folder / "dem" / "summary.yaml")
    cost = dem.get("cost", {})
    check(cost.get("ranks") == 2 and cost.get("rank_migrations", 0) > 2,
          f"{name}: the DEM ran on {cost.get('ranks')} ranks, cut {cost.get('rank_migrations')} times")
    return dem


# 1. The reference, one rank.
ref_folder = out / "one_rank"
r = subprocess.run([cosim, "run", str(scene), "--out", str(ref_folder), "--quiet", *END], env=env, timeout=300)
check(r.returncode == 0, f"one rank: cosim exits 0 (got {r.returncode})")
if r.returncode != 0:
    sys.exit(1)
ref = results(ref_folder)
check(ref["sag"] > 0.05, f"one rank: the stones have reached the net (sag {ref['sag']:.4f} m)")

# 2. cosim launches the DEM on 2 ranks.
launched = out / "launched"
r = subprocess.run([cosim, "run", str(scene), "--out", str(launched), "--quiet", *END, "--set",
                    f"participants.dem.command=[{mpirun}, -np, '2', dem_solver, debris_dem.yaml]"],
                   env=env, timeout=300)
check(r.returncode == 0, f"launched by cosim on 2 ranks: cosim exits 0 (got {r.returncode}) {tail(launched / 'dem.console.log')}")
if r.returncode == 0:
    compare("launched by cosim on 2 ranks", launched, ref)


# 3. Across machines, on loopback: tcp with CURVE, the DEM external and started here.
def free_port(host):
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


for prefix in ("coupler", "dem"):
    subprocess.run([cosim, "keys", str(out / prefix)], env=env, check=True, stdout=subprocess.DEVNULL)
coupler_public = (out / "coupler.public").read_text().splitlines()[0]
dem_public = (out / "dem.public").read_text().splitlines()[0]
tcp = out / "tcp"
for attempt in range(3):  # a port taken between free_port() and the bind: another
    shutil.rmtree(tcp, ignore_errors=True)
    endpoint = f"tcp://127.0.0.2:{free_port('127.0.0.2')}"
    coupler = subprocess.Popen(
        [cosim, "run", str(scene), "--out", str(tcp), "--quiet", *END,
         "--set", "participants.dem.command=null", "--set", "participants.dem.threads=null",
         "--set", "participants.dem.external=true",
         "--set", f"participants.dem.token={TOKEN}", "--set", f"coupling.endpoint={endpoint}",
         "--set", f"coupling.curve.secret_key_file={out / 'coupler.secret'}",
         "--set", f'coupling.curve.allowed_keys=["{dem_public}"]'], env=env)
    denv = dict(env, COSIM_TOKEN=TOKEN, COSIM_CURVE_SERVER_KEY=coupler_public,
                COSIM_CURVE_SECRET_KEY_FILE=str(out / "dem.secret"))
    with open(out / "tcp_dem.log", "w") as log:
        dem = subprocess.Popen([mpirun, "-np", "2", dem_solver, str(dem_scene), "--couple", endpoint, "--name", "dem",
                                "--out", str(tcp / "dem"), "--quiet", "--threads", "1"],
                               env=denv, stdout=log, stderr=subprocess.STDOUT)
        try:
            coupler_rc = coupler.wait(timeout=300)
        except subprocess.TimeoutExpired:
            coupler.kill()
            coupler_rc = coupler.wait()
        try:
            dem_rc = dem.wait(timeout=120)
        except subprocess.TimeoutExpired:
            dem.kill()
            dem_rc = dem.wait()
    if coupler_rc != 0 and "ddress already in use" in tail(tcp / "cosim.log", 100000) and attempt < 2:
        continue
    break
check(coupler_rc == 0 and dem_rc == 0,
      f"tcp with CURVE, the DEM external on 2 ranks: cosim exits {coupler_rc}, mpirun {dem_rc} (both 0) "
      f"{tail(out / 'tcp_dem.log')} {tail(tcp / 'cosim.log')}")
if coupler_rc == 0 and dem_rc == 0:
    check(f"coupler listening on {endpoint}" in (tcp / "cosim.log").read_text(), f"tcp: the coupler listened on {endpoint}")
    compare("tcp with CURVE, the DEM external on 2 ranks", tcp, ref)

# 4. A spinning rigid block among the stones: a cluster's per-sphere sums in repeated windows across cuts,
# launched on 2 ranks against one.
cube = (src / "configs" / "dem" / "clusters" / "cube_c2.yaml").resolve()
block = ["--set", f"dem:clusters=[{{file: {cube}, material: granite, mass: 180, position: [0.75, 1.95, 0.3], "
         "velocity: [1.5, 0, -3], angular_velocity: [0, 4, 0]}]"]
ref_block, ranks_block = out / "block_one_rank", out / "block_launched"
r1 = subprocess.run([cosim, "run", str(scene), "--out", str(ref_block), "--quiet", *END, *block], env=env, timeout=300)
r2 = subprocess.run([cosim, "run", str(scene), "--out", str(ranks_block), "--quiet", *END, *block, "--set",
                     f"participants.dem.command=[{mpirun}, -np, '2', dem_solver, debris_dem.yaml]"],
                    env=env, timeout=300)
check(r1.returncode == 0 and r2.returncode == 0, f"a block among the stones: cosim exits {r1.returncode}, {r2.returncode}")
if r1.returncode == 0 and r2.returncode == 0:
    compare("a block among the stones on 2 ranks", ranks_block, results(ref_block))

# 5. A divergence on 2 ranks ends every rank and the coupler with exit 3.
failed = out / "diverged"
r = subprocess.run([cosim, "run", str(scene), "--out", str(failed), "--quiet", *END, "--set",
                    f"participants.dem.command=[{mpirun}, -np, '2', dem_solver, debris_dem.yaml, --set, "
                    "energy_tolerance=1.0e-12]"], env=env, timeout=300)
zero, one = load(failed / "dem" / "summary.yaml"), load(failed / "dem" / "rank_1" / "summary.yaml")
check(r.returncode == 3, f"diverged: cosim exits 3 (got {r.returncode})")
check(zero.get("exit_code") == 3 and one.get("exit_code") == 3,
      f"diverged: rank 0 and rank 1 exit 3 (got {zero.get('exit_code')}, {one.get('exit_code')})")
windows = (zero.get("results", {}).get("coupling_windows"), one.get("results", {}).get("coupling_windows"))
check(windows[0] == windows[1], f"diverged: both ranks stopped after window {windows[0]} ({windows[1]})")
check("rank 0:" in str(one.get("status")) and "energy" in str(one.get("status")),
      f"diverged: rank 1's status names rank 0's diagnosis: {one.get('status')!r}")

if failures:
    print(f"\n{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
print("\nall checks passed")
