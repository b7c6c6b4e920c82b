#!/usr/bin/env python3
"""Serial against parallel implicit coupling on the rockfall scenes: each case run under both schemes in
turn (A B A B …, the pairs keep a drifting machine's ratio fair), the medians of wall time, passes per window,
the coupling's own time per pass beside the machine's bare ZeroMQ round trip of the same run, and the
physics of each scheme's last run (rockfall_report.py). Prints one markdown table (docs/performance.md).

Usage:  tools/scheme_table.py BUILD_DIR OUT [--pairs N] [--cases c1 c5 c5_dt2e-5 …]
"""
import argparse
import statistics
import subprocess
import sys
from pathlib import Path

import yaml

from rockfall_report import analyse

ROOT = Path(__file__).resolve().parent.parent
# Case name → scene and the overrides that make it.
CASES = {f"c{i}": (f"configs/rockfall/c{i}.yaml", []) for i in range(1, 8)}
CASES["c5_a"] = ("configs/rockfall/c5_a.yaml", [])
CASES["c5_dt2e-5"] = ("configs/rockfall/c5.yaml", ["dem:dt=2e-5"])
SCHEMES = ("implicit", "implicit_parallel")


def run(build, scene, sets, scheme, out):
    command = [str(build / "bin" / "cosim"), "run", str(ROOT / scene), "--out", str(out), "--quiet",
               "--set", f"coupling.scheme={scheme}"]
    for s in sets:
        command += ["--set", s]
    code = subprocess.run(command, cwd=ROOT).returncode
    summary = yaml.safe_load((out / "summary.yaml").read_text())
    if code != 0:
        raise SystemExit(f"{' '.join(command)}: exit {code}: {summary.get('status')}")
    return summary


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    a = ap.parse_args(argv)
    rows = []
    for case in a.cases:
        scene, sets = CASES[case]
        runs = {s: [] for s in SCHEMES}
        for k in range(a.pairs):
            for s in SCHEMES:
                out = a.out / case / s
                runs[s].append(run(a.build, scene, sets, s, out))
                print(f"{case} {s} run {k + 1}: {runs[s][-1]['wall_time_s']:.2f} s", file=sys.stderr, flush=True)
        physics = {s: analyse(a.out / case / s)[0] for s in SCHEMES}
        ratios = [p["wall_time_s"] / q["wall_time_s"] for p, q in zip(runs["implicit_parallel"], runs["implicit"])]

        def med(s, key):
            return statistics.median(r["results"][key] if key in r["results"] else r[key] for r in runs[s])

        rows.append((case, med("implicit", "wall_time_s"), med("implicit_parallel", "wall_time_s"),
                     statistics.median(ratios), min(ratios), max(ratios),
                     med("implicit", "mean_coupling_iterations"), med("implicit_parallel", "mean_coupling_iterations"),
                     med("implicit", "outside_solvers_per_pass_s"), med("implicit_parallel", "outside_solvers_per_pass_s"),
                     med("implicit", "zmq_round_trip_s"), med("implicit_parallel", "zmq_round_trip_s"), physics))
    print("| case | wall serial / parallel [s] | parallel / serial (pairs) | passes per window | outside the solvers "
          "per pass [ms] | ZeroMQ round trip [ms] | max deflection [m] | peak F_R [kN] | peak F_C [kN] | energy balance "
          "error |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for (case, ws, wp, r, rmin, rmax, ps, pp, os_, op, rs, rp, ph) in rows:
        s, p = ph["implicit"], ph["implicit_parallel"]
        print(f"| {case} | {ws:.2f} / {wp:.2f} | {r:.3f} ({rmin:.3f}–{rmax:.3f}) | {ps:.2f} / {pp:.2f} | "
              f"{os_ * 1e3:.3f} / {op * 1e3:.3f} | {rs * 1e3:.3f} / {rp * 1e3:.3f} | "
              f"{s['max_deflection']:.4f} / {p['max_deflection']:.4f} | "
              f"{s['peak_reaction_force'] / 1e3:.2f} / {p['peak_reaction_force'] / 1e3:.2f} | "
              f"{s['peak_contact_force'] / 1e3:.2f} / {p['peak_contact_force'] / 1e3:.2f} | "
              f"{100 * s['energy_balance_error']:.2f} / {100 * p['energy_balance_error']:.2f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
