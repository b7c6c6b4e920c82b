#!/usr/bin/env python3
"""Every rockfall level of the paper (Table 3) and the c1 time-step study (Table 4), end to end.

Run with:   python3 tools/rockfall_study.py BUILD_DIR OUT_DIR [--levels c1 c2 …] [--dt-study] [--dem-dt 2e-5]
                                                   [--tolerance-study]

For each level: `cosim run configs/rockfall/LEVEL.yaml`, then tools/rockfall_report.py on it. Writes
OUT_DIR/rockfall_table.md (max deflection, peak F_R, peak F_C, contact duration, rebound velocity,
energy balance error, wall time, DEM/FEM solver time, time outside the solvers, coupling iterations per
window), OUT_DIR/levels.png (block displacement, F_C, F_R of all levels overlaid, Figs. 9/18/19),
OUT_DIR/wall_time.png (wall time against spheres, Fig. 21), and with --dt-study the c1 runs at
dt = 2e-5, 6e-6, 1e-6 s with OUT_DIR/c1_dt.png (F_C and F_R together, Fig. 20). With --tolerance-study,
instead of the levels: the first level at the coupling tolerances 1e-5 … 1e-3 with constant and linear
extrapolation against a reference run (linear, --reference-tolerance, default 1e-6), OUT_DIR/tolerance_table.md and OUT_DIR/tolerance.png
(error against wall time).
"""
import argparse
import pathlib
import subprocess
import sys

import h5py
import matplotlib
import numpy as np
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
LEVELS = ["c1", "c2", "c3", "c4", "c5", "c6", "c7", "c5_a"]


def dem_command(level, dt):
    """The level's DEM command with `--set dt=…` appended (None: the scene's dt)."""
    scene = yaml.safe_load((ROOT / "configs/rockfall" / f"{level}.yaml").read_text())
    cmd = list(scene["participants"]["dem"]["command"])
    if dt is not None:
        cmd += ["--set", f"dt={dt:g}"]
    return "participants.dem.command=[" + ", ".join(f"'{c}'" for c in cmd) + "]"


def run(bin_dir, level, out, dt=None, sets=()):
    cmd = [str(bin_dir / "cosim"), "run", str(ROOT / "configs/rockfall" / f"{level}.yaml"), "--out", str(out), "--quiet"]
    if dt is not None:
        cmd += ["--set", dem_command(level, dt)]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    summary = yaml.safe_load((out / "summary.yaml").read_text())
    if summary["exit_code"] != 0:
        print(f"{level}: failed: {summary['status']}", file=sys.stderr)
        return None
    subprocess.run([sys.executable, str(ROOT / "tools/rockfall_report.py"), str(out)], check=True, stdout=subprocess.DEVNULL)
    summary = yaml.safe_load((out / "summary.yaml").read_text())
    dem = yaml.safe_load((out / "dem" / "summary.yaml").read_text())
    summary["spheres"] = dem["results"]["spheres"]
    return summary


def series(folder):
    with h5py.File(folder / "dem" / "dem.h5", "r") as f:
        b = {k: f["timeseries/body_0"][k][()] for k in ("time", "z", "vz", "fx", "fy", "fz")}
    with h5py.File(folder / "fem" / "fem.h5", "r") as f:
        r = f["timeseries/reactions"]
        fr = np.sqrt(r["boundary_fx"][()] ** 2 + r["boundary_fy"][()] ** 2 + r["boundary_fz"][()] ** 2)
        tr = r["time"][()]
    return b, tr, fr


def history_error(folder, reference):
    """max |z − z_ref| over the largest block displacement, and max |F_C − F_C,ref| over the peak F_C."""
    b, _, _ = series(folder)
    r, _, _ = series(reference)
    n = min(len(b["time"]), len(r["time"]))
    fc = np.sqrt(b["fx"][:n] ** 2 + b["fy"][:n] ** 2 + b["fz"][:n] ** 2)
    fr = np.sqrt(r["fx"][:n] ** 2 + r["fy"][:n] ** 2 + r["fz"][:n] ** 2)
    dz = np.max(np.abs(b["z"][:n] - r["z"][:n])) / np.max(np.abs(r["z"][:n] - r["z"][0]))
    return dz, np.max(np.abs(fc - fr)) / np.max(fr)


def tolerance_study(bin_dir, level, dt, out, reference_tolerance):
    """Coupling tolerance and first-iteration extrapolation: error against wall time (one level)."""
    ref = out / f"{level}_reference"
    reference_run = run(bin_dir, level, ref, dt, ["coupling.extrapolation=linear", f"coupling.tolerance.relative={reference_tolerance}"])
    if reference_run is None:
        return
    rows = []
    for extrapolation in ("constant", "linear"):
        for tol in ("1e-5", "1e-4", "2e-4", "3e-4", "1e-3"):
            if float(tol) <= float(reference_tolerance) and extrapolation == "linear":
                continue
            folder = out / f"{level}_{extrapolation}_{tol}"
            s = run(bin_dir, level, folder, dt, [f"coupling.extrapolation={extrapolation}", f"coupling.tolerance.relative={tol}"])
            if s is None:
                rows.append((extrapolation, tol, None, None, None))
                continue
            rows.append((extrapolation, tol, s, *history_error(folder, ref)))
            print(f"{extrapolation} {tol}: {s['wall_time_s']:.1f} s, {s['results']['mean_coupling_iterations']:.2f} "
                  f"iterations, energy {100 * s['results']['energy_balance_error']:.2f} %", flush=True)
    reference = reference_run["results"]
    with open(out / "tolerance_table.md", "w") as f:
        f.write(f"| {level}: extrapolation | relative tolerance | iterations / window | wall [s] | coupling share | "
                "block z error | F_C history error | peak F_C | max deflection | rebound | energy balance error |\n")
        f.write("| --- " * 11 + "|\n")
        f.write(f"| reference: linear | {reference_tolerance} | {reference['mean_coupling_iterations']:.2f} | "
                f"{reference_run['wall_time_s']:.1f} | "
                f"{100 * reference['coupling_overhead_share']:.0f} % | — | — | {reference['peak_contact_force'] / 1e3:.2f} kN | "
                f"{reference['max_deflection']:.4f} m | {reference['rebound_velocity']:.3f} m/s | "
                f"{100 * reference['energy_balance_error']:.2f} % |\n")
        for extrapolation, tol, s, dz, dfc in rows:
            if s is None:
                f.write(f"| {extrapolation} | {tol} | failed | | | | | | | | |\n")
                continue
            r = s["results"]
            f.write(f"| {extrapolation} | {tol} | {r['mean_coupling_iterations']:.2f} | {s['wall_time_s']:.1f} | "
                    f"{100 * r['coupling_overhead_share']:.0f} % | {dz:.1e} | {dfc:.1e} | "
                    f"{r['peak_contact_force'] / 1e3:.2f} kN | {r['max_deflection']:.4f} m | {r['rebound_velocity']:.3f} m/s | "
                    f"{100 * r['energy_balance_error']:.2f} % |\n")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for extrapolation, marker in (("constant", "o-"), ("linear", "s-")):
        sel = [x for x in rows if x[0] == extrapolation and x[2] is not None]
        wall = [x[2]["wall_time_s"] for x in sel]
        ax[0].loglog(wall, [x[4] for x in sel], marker, label=extrapolation)
        ax[1].semilogx(wall, [100 * x[2]["results"]["energy_balance_error"] for x in sel], marker, label=extrapolation)
        for x, w in zip(sel, wall):
            ax[0].annotate(x[1], (w, x[4]), textcoords="offset points", xytext=(3, 3), fontsize=7)
    ax[0].set_ylabel(f"F_C history error (to tolerance {reference_tolerance})")
    ax[1].set_ylabel("energy balance error [%]")
    for axis in ax:
        axis.set_xlabel("wall time [s]")
        axis.grid(True, which="both", alpha=0.3)
        axis.legend(title="first iteration")
    fig.suptitle(f"rockfall {level}" + (f", DEM dt {dt:g} s" if dt else "") + ": coupling tolerance, error against run time",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "tolerance.png", dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--levels", nargs="+", default=LEVELS)
    ap.add_argument("--dt-study", action="store_true")
    ap.add_argument("--dem-dt", type=float, default=None, help="DEM time step for every level (default: the scene's)")
    ap.add_argument("--tolerance-study", action="store_true", help="coupling tolerance study of the first level only")
    ap.add_argument("--reference-tolerance", default="1e-6", help="tolerance study: the reference run's relative tolerance")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="an override for every level's coupled scene, e.g. coupling.scheme=implicit")
    a = ap.parse_args()
    bin_dir = a.build.resolve() / "bin"
    a.out.mkdir(parents=True, exist_ok=True)
    if a.tolerance_study:
        tolerance_study(bin_dir, a.levels[0], a.dem_dt, a.out, a.reference_tolerance)
        return
    rows = []
    for level in a.levels:
        s = run(bin_dir, level, a.out / level, a.dem_dt, a.set)
        if s is None:
            continue
        r = s["results"]
        solvers = r["solver_time_dem"] + r["solver_time_fem"]
        rows.append((level, s["spheres"], r, s["wall_time_s"], solvers))
        print(f"{level}: {s['spheres']} spheres, {s['wall_time_s']:.1f} s wall, deflection {r['max_deflection']:.3f} m, "
              f"F_R {r['peak_reaction_force'] / 1e3:.1f} kN, F_C {r['peak_contact_force'] / 1e3:.1f} kN, "
              f"energy {100 * r['energy_balance_error']:.2f} %", flush=True)
    with open(a.out / "rockfall_table.md", "w") as f:
        f.write("| level | spheres | max deflection [m] | peak F_R [kN] | peak F_C [kN] | contact [s] | rebound [m/s] | "
                "energy error | wall [s] | DEM [s] | FEM [s] | outside solvers | iterations / window |\n")
        f.write("| --- " * 13 + "|\n")
        for level, n, r, wall, solvers in rows:
            f.write(f"| {level} | {n} | {r['max_deflection']:.3f} | {r['peak_reaction_force'] / 1e3:.1f} | "
                    f"{r['peak_contact_force'] / 1e3:.1f} | {r['contact_duration']:.3f} | {r['rebound_velocity']:.2f} | "
                    f"{100 * r['energy_balance_error']:.1f} % | {wall:.1f} | {r['solver_time_dem']:.1f} | "
                    f"{r['solver_time_fem']:.1f} | {100 * (1 - solvers / wall):.0f} % | {r['mean_coupling_iterations']:.2f} |\n")
    if rows:
        fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
        for level, *_ in rows:
            b, tr, fr = series(a.out / level)
            fc = np.sqrt(b["fx"] ** 2 + b["fy"] ** 2 + b["fz"] ** 2)
            ax[0].plot(b["time"], b["z"] - b["z"][0], label=level)
            ax[1].plot(b["time"], fc / 1e3, label=level)
            ax[2].plot(tr, fr / 1e3, label=level)
        for axis, label in zip(ax, ["block displacement [m]", "contact force $F_C$ [kN]", "reaction force $F_R$ [kN]"]):
            axis.set_ylabel(label)
            axis.grid(True, alpha=0.3)
            axis.legend(ncol=4, fontsize=8)
        ax[-1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(a.out / "levels.png", dpi=110)
        plt.close(fig)
        fig, ax = plt.subplots(figsize=(6, 4))
        n = [x[1] for x in rows if x[0] != "c5_a"]
        ax.loglog(n, [x[3] for x in rows if x[0] != "c5_a"], "o-", label="wall time")
        ax.loglog(n, [x[2]["solver_time_dem"] for x in rows if x[0] != "c5_a"], "s--", label="DEM solver")
        ax.loglog(n, [x[2]["solver_time_fem"] for x in rows if x[0] != "c5_a"], "^--", label="FEM solver")
        for level, spheres, _, wall, _ in rows:
            if level != "c5_a":
                ax.annotate(level, (spheres, wall), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.set_xlabel("spheres in the cluster")
        ax.set_ylabel("time for 0.3 s simulated [s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(a.out / "wall_time.png", dpi=110)
        plt.close(fig)
    if a.dt_study:
        fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
        with open(a.out / "c1_dt_table.md", "w") as f:
            f.write("| c1, DEM dt [s] | peak F_C [kN] | peak F_R [kN] | max deflection [m] | wall [s] |\n| --- | --- | --- | --- | --- |\n")
            for i, dt in enumerate([2e-5, 6e-6, 1e-6]):
                out = a.out / f"c1_dt{dt:g}"
                s = run(bin_dir, "c1", out, dt)
                if s is None:
                    continue
                r = s["results"]
                f.write(f"| {dt:g} | {r['peak_contact_force'] / 1e3:.2f} | {r['peak_reaction_force'] / 1e3:.2f} | "
                        f"{r['max_deflection']:.3f} | {s['wall_time_s']:.1f} |\n")
                b, tr, fr = series(out)
                fc = np.sqrt(b["fx"] ** 2 + b["fy"] ** 2 + b["fz"] ** 2)
                ax[i].plot(b["time"], fc / 1e3, label="$F_C$")
                ax[i].plot(tr, fr / 1e3, label="$F_R$")
                ax[i].set_ylabel("force [kN]")
                ax[i].set_title(f"c1, DEM dt = {dt:g} s", fontsize=9)
                ax[i].grid(True, alpha=0.3)
                ax[i].legend()
                print(f"c1 dt {dt:g}: F_C {r['peak_contact_force'] / 1e3:.2f} kN, F_R {r['peak_reaction_force'] / 1e3:.2f} kN", flush=True)
        ax[-1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(a.out / "c1_dt.png", dpi=110)
        plt.close(fig)


if __name__ == "__main__":
    main()
