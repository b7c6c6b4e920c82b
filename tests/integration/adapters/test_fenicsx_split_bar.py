#!/usr/bin/env python3
"""The split bar with its left half in FEniCSx (adapters/fenicsx/elastic_solid.py):

- static: the interface moves F L / (E A) = 2.5e-4 m, linear theory, to 1e-12;
- dynamic, against the monolithic fem_solver bar: the interface history agrees to 1e-6 at a load of 1 N;
  at 1000 N it differs by the geometric nonlinearity of fem_solver's total-Lagrangian truss, which the
  linear FEniCSx bar leaves out, so the difference grows with the load (× 1000 within 10 %);
- a 3-D block, its left half a FEniCSx box of tetrahedra, its right half fem_solver's tet4 on another
  mesh: the interface moves F (L/2)/(E A) to 0.5 %, the tip as in the monolithic fem_solver block to 0.5 %;
  explicit on both sides, FEniCSx the Neumann side and then the Dirichlet side, the tip's history as the
  monolithic block's to 1 % of its largest value.

Use: test_fenicsx_split_bar.py BIN_DIR REPO OUT
"""
import pathlib
import subprocess
import sys

import h5py
import numpy as np
import yaml

from checklist import check, finish  # noqa: E402 (this folder: the script's own)

bin_dir, repo, out = (pathlib.Path(a) for a in sys.argv[1:4])
configs = repo / "configs" / "verification"


def run(args):
    p = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if p.returncode:
        print(p.stdout[-2000:], p.stderr[-2000:])
    return p.returncode


rc = run([bin_dir / "cosim", configs / "split_bar_static_fenicsx.yaml", "--out", out / "static", "--quiet"])
u = yaml.safe_load((out / "static" / "left" / "summary.yaml").read_text())["results"]["interface_displacement"] if rc == 0 else 0
check("static: the interface moves F L / (E A)", rc == 0 and abs(u - 2.5e-4) < 1e-12 * 2.5e-4, f"({u!r})")

differences = {}
for load in ["1", "1000"]:
    right = f'participants.right.command=[fem_solver, split_bar_dynamic_right.yaml, --set, "loads[0].force=[{load}, 0, 0]"]'
    rc1 = run([bin_dir / "cosim", configs / "split_bar_dynamic_fenicsx.yaml", "--out", out / f"dynamic_{load}", "--quiet",
               "--set", right])
    rc2 = run([bin_dir / "fem_solver", configs / "split_bar_dynamic_monolithic.yaml", "--out", out / f"monolithic_{load}",
               "--quiet", "--set", f"loads[0].force=[{load}, 0, 0]"])
    if rc1 or rc2:
        check(f"dynamic at {load} N: both runs end with exit 0", False, f"({rc1}, {rc2})")
        continue
    with h5py.File(out / f"dynamic_{load}" / "left" / "fenicsx.h5", "r") as f:
        tc, uc = f["timeseries/probes/time"][()], f["timeseries/probes/interface_ux"][()]
    with h5py.File(out / f"monolithic_{load}" / "fem.h5", "r") as f:
        tm, um = f["timeseries/probes/time"][()], f["timeseries/probes/interface_ux"][()]
    idx = [int(np.argmin(np.abs(tm - t))) for t in tc]
    check(f"dynamic at {load} N: the same instants", len(tc) == 400 and np.abs(tm[idx] - tc).max() < 1e-12)
    differences[load] = np.abs(uc - um[idx]).max() / np.abs(um).max()
    unconverged = yaml.safe_load((out / f"dynamic_{load}" / "summary.yaml").read_text())["results"]["unconverged_windows"]
    check(f"dynamic at {load} N: every window converged", unconverged == 0, f"({unconverged})")
if len(differences) == 2:
    check("dynamic at 1 N: the monolithic history to 1e-6", differences["1"] < 1e-6, f"({differences['1']:.2e})")
    ratio = differences["1000"] / differences["1"]
    check("dynamic: the difference grows with the load, as the truss's geometric nonlinearity", 900 < ratio < 1100,
          f"({differences['1000']:.2e} at 1000 N, × {ratio:.0f})")
rc = run([bin_dir / "cosim", configs / "split_block_static_fenicsx.yaml", "--out", out / "block", "--quiet"])
rc2 = run([bin_dir / "fem_solver", configs / "split_block_monolithic.yaml", "--out", out / "block_monolithic", "--quiet"])
if rc == 0 and rc2 == 0:
    u = yaml.safe_load((out / "block" / "left" / "summary.yaml").read_text())["results"]["interface_displacement"]
    tip = yaml.safe_load((out / "block" / "right" / "summary.yaml").read_text())["results"]["tip_displacement"][0]
    mono = yaml.safe_load((out / "block_monolithic" / "summary.yaml").read_text())["results"]["tip_displacement"][0]
    check("block: the interface moves F (L/2) / (E A)", abs(u / 2.5e-7 - 1) < 5e-3, f"({u:.6e} m, {u / 2.5e-7 - 1:+.2e})")
    check("block: the tip as the monolithic block's", abs(tip / mono - 1) < 5e-3, f"({tip:.6e} against {mono:.6e} m)")
else:
    check("block: both runs end with exit 0", False, f"({rc}, {rc2})")
rc2 = run([bin_dir / "fem_solver", configs / "split_block_dynamic_monolithic.yaml", "--out", out / "block_dynamic_monolithic",
           "--quiet"])
for scene, side in [("split_block_dynamic_fenicsx.yaml", "Neumann"), ("split_block_dynamic_fenicsx_dirichlet.yaml", "Dirichlet")]:
    rc = run([bin_dir / "cosim", configs / scene, "--out", out / f"block_dynamic_{side}", "--quiet"])
    if rc or rc2:
        check(f"block, explicit, FEniCSx the {side} side: both runs end with exit 0", False, f"({rc}, {rc2})")
        continue
    with h5py.File(out / f"block_dynamic_{side}" / "right" / "fem.h5", "r") as f:
        tc, uc = f["timeseries/probes/time"][()], f["timeseries/probes/tip_ux"][()]
    with h5py.File(out / "block_dynamic_monolithic" / "fem.h5", "r") as f:
        tm, um = f["timeseries/probes/time"][()], f["timeseries/probes/tip_ux"][()]
    idx = [int(np.argmin(np.abs(tm - t))) for t in tc]
    difference = np.abs(uc - um[idx]).max() / np.abs(um).max()
    check(f"block, explicit, FEniCSx the {side} side: the tip's history as the monolithic block's",
          len(tc) == 800 and difference < 1e-2, f"({difference:.2e} of {np.abs(um).max():.3e} m)")
finish()
