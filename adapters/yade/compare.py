#!/usr/bin/env python3
"""Rockfall c1 (or c2) with dem_solver and with YADE as the DEM participant, side by side, the causes of
their differences removed one at a time. Writes OUT/NAME_SIDE/ (each run), OUT/comparison.md and
OUT/comparison.png.

Run with:  python3 adapters/yade/compare.py build results/adapters [--level c2] [--only NAME …]

Variants (both DEM sides, same net, same coupling):
  on_node        the scene as given: the block lands on a node of the net
  off_node       the block 1/3 of a cell off the node, inside one facet
  rigid_mass     off_node, both dashpots given the block's mass alone, as against a rigid wall (YADE's usual
                 fixed facets; dem_solver without `areal_density`), to 0.05 s
  elastic        off_node, restitution 1 in both (no contact dashpot), to 0.3 s
  matched        elastic, and both moduli in YADE × √(3/2): dem_solver's facet stiffness (--match-stiffness)
"""
import argparse
import pathlib
import subprocess
import sys
import time

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]
# The block's centre: over the net's middle node (the scene as given), or over the centroid of the facet
# of cell (16, 16) next to it; the lowest sphere 1 cm above the flat net.
HEIGHT = {"c1": "0.26434", "c2": "0.24431"}
ON_NODE = ["1.95", "1.95"]
OFF_NODE = ["2.03125", "1.990625"]
SHORT = ["--set", "coupling.end_time=0.05"]
VARIANTS = {  # position, dem_solver's options, YADE's, the coupled run's
    "on_node": (ON_NODE, [], [], []),
    "off_node": (OFF_NODE, [], [], []),
    "rigid_mass": (OFF_NODE, ["--set", "walls[0].areal_density=null"], ["--rigid-net"], SHORT),
    "elastic": (OFF_NODE, ["--set", "interactions[0].restitution=1.0"], ["--restitution", "1.0"], []),
    "matched": (OFF_NODE, ["--set", "interactions[0].restitution=1.0"], ["--restitution", "1.0", "--match-stiffness"], []),
}
KEYS = ["max_deflection", "block_displacement", "peak_reaction_force", "peak_contact_force", "contact_duration",
        "rebound_velocity", "energy_balance_error", "mean_coupling_iterations"]


def run(cosim, out, dem_command, options):
    out.mkdir(parents=True, exist_ok=True)
    command = "[" + ", ".join(f'"{a}"' for a in dem_command) + "]"
    start = time.perf_counter()
    p = subprocess.run([str(cosim), "run", str(ROOT / "configs/rockfall/c1.yaml"), "--out", str(out), "--quiet",
                        "--set", f"participants.dem.command={command}", *options], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    report = subprocess.run([sys.executable, str(ROOT / "tools/rockfall_report.py"), str(out)], capture_output=True, text=True)
    results = yaml.safe_load((out / "summary.yaml").read_text()).get("results", {}) if (out / "summary.yaml").exists() else {}
    return dict(exit=p.returncode, seconds=seconds, results=results, report=report.returncode,
                error=(p.stderr.strip().splitlines() or [""])[-1] if p.returncode else "")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--only", nargs="*", default=list(VARIANTS))
    ap.add_argument("--level", choices=sorted(HEIGHT), default="c1")
    args = ap.parse_args()
    cluster = f"../dem/clusters/cube_{args.level}.yaml"
    cosim = args.build.resolve() / "bin" / "cosim"
    rows = {}
    for name in args.only:
        position, ours, theirs, options = VARIANTS[name]
        position = position + [HEIGHT[args.level]]
        dem = ["dem_solver", "block.yaml", "--set", f"clusters[0].file={cluster}",
               "--set", f"clusters[0].position=[{', '.join(position)}]"] + ours
        yade = ["yade", "-n", "-x", "../../adapters/yade/rockfall_block.py", "block.yaml", "--cluster", cluster,
                "--position"] + position + theirs
        for side, command in [("dem_solver", dem), ("yade", yade)]:
            print(f"== {name}: {side}", flush=True)
            rows[(name, side)] = r = run(cosim, args.out / f"{args.level}_{name}_{side}", command, options)
            print(f"   exit {r['exit']} in {r['seconds']:.1f} s {r['error']}", flush=True)
    lines = ["| variant | DEM | exit | wall [s] | " + " | ".join(KEYS) + " |", "|" + "---|" * (len(KEYS) + 4)]
    for (name, side), r in rows.items():
        values = [f"{r['results'][k]:.4g}" if k in r["results"] else "–" for k in KEYS]
        lines.append(f"| {name} | {side} | {r['exit']} | {r['seconds']:.0f} | " + " | ".join(values) + " |")
    lines.insert(0, f"Rockfall {args.level}, `python3 adapters/yade/compare.py` ({time.strftime('%Y-%m-%d')}):\n")
    lines += ["", "Runs that stopped:", ""] + [f"- {n} ({s}): {r['error']}" for (n, s), r in rows.items() if r["exit"]]
    lines.append("")
    lines.append("YADE relative to dem_solver:")
    lines.append("")
    lines.append("| variant | " + " | ".join(KEYS[:6]) + " |")
    lines.append("|" + "---|" * 7)
    for name in args.only:
        a, b = rows.get((name, "dem_solver")), rows.get((name, "yade"))
        if not a or not b or not all(k in a["results"] and k in b["results"] for k in KEYS[:6]):
            continue
        rel = [f"{(b['results'][k] - a['results'][k]) / abs(a['results'][k]) * 100:+.1f} %" for k in KEYS[:6]]
        lines.append(f"| {name} | " + " | ".join(rel) + " |")
    (args.out / f"comparison_{args.level}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    folders = [str(args.out / f"{args.level}_{n}_{s}") for (n, s), r in rows.items() if r["exit"] == 0]
    if folders:
        subprocess.run([sys.executable, str(ROOT / "tools/rockfall_report.py"), *folders, "--compare", str(args.out / f"comparison_{args.level}.png")],
                       capture_output=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
