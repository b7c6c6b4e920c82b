#!/usr/bin/env python3
"""Mass-ratio study of the dynamic split bar (issue 5, docs/validation/coupling.md).

Run with:   python3 tools/mass_ratio_study.py BUILD_DIR OUT_DIR [--ratios 1 10 100 1000]

The left (Neumann) half of configs/verification/split_bar_dynamic.yaml is thinned by the mass ratio
r = A_right / A_left (same material: same wave speed and time step, the interface node masses differ
by r, and the impedance jump reflects part of the wave). For each r it runs the monolithic bar, then
the coupled bar with weak coupling (explicit_serial) and with implicit Gauss–Seidel under constant
relaxation (ω = 0.1), Aitken and IQN-ILS. It writes OUT_DIR/mass_ratio.md (a Markdown table: status,
mean iterations per window, max relative error of the interface displacement history against the
monolithic run) and OUT_DIR/mass_ratio.png (iterations against r; the histories at r = 100).
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
SCENE = ROOT / "configs/verification/split_bar_dynamic.yaml"
MONO = ROOT / "configs/verification/split_bar_dynamic_monolithic.yaml"
VARIANTS = [
    ("weak (explicit serial)", ["coupling.scheme=explicit_serial", "coupling.max_iterations=null", "coupling.tolerance=null", "coupling.extrapolation=null", "coupling.acceleration=null"]),
    ("constant ω = 0.1", ["coupling.acceleration.type=constant", "coupling.acceleration.relaxation=0.1"]),
    ("Aitken", ["coupling.acceleration.type=aitken"]),
    ("IQN-ILS", ["coupling.acceleration.type=iqn_ils"]),
]


def probe(path, column):
    with h5py.File(path, "r") as f:
        g = f["timeseries/probes"]
        return g["time"][()], g[column][()]


def run(cmd, out):
    subprocess.run(cmd + ["--out", str(out), "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return yaml.safe_load((out / "summary.yaml").read_text())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--ratios", type=float, nargs="+", default=[1, 10, 100, 1000])
    a = ap.parse_args()
    bin_dir = a.build.resolve() / "bin"
    a.out.mkdir(parents=True, exist_ok=True)
    rows, iterations, histories = [], {name: [] for name, _ in VARIANTS}, {}
    for r in a.ratios:
        area = 1e-4 / r
        mono_out = a.out / f"r{r:g}" / "monolithic"
        s = run([str(bin_dir / "fem_solver"), str(MONO), "--set", f"elements[0].area={area:.6g}"], mono_out)
        if s["exit_code"] != 0:
            sys.exit(f"monolithic run failed for r = {r:g}: {s['status']}")
        tm, um = probe(mono_out / "fem.h5", "interface_ux")
        histories[(r, "monolithic")] = (tm, um)
        for name, sets in VARIANTS:
            out = a.out / f"r{r:g}" / name.split()[0].lower()
            left = f"participants.left.command=[fem_solver, split_bar_dynamic_left.yaml, --set, 'elements[0].area={area:.6g}']"
            cmd = [str(bin_dir / "cosim"), "run", str(SCENE), "--set", left]
            for x in sets:
                cmd += ["--set", x]
            s = run(cmd, out)
            res = s.get("results") or {}
            it = res.get("mean_coupling_iterations", float("nan"))
            if s["exit_code"] == 0:
                t, u = probe(out / "left" / "fem.h5", "interface_ux")
                err = np.max(np.abs(u - np.interp(t, tm, um))) / np.max(np.abs(um))
                histories[(r, name)] = (t, u)
                status = "stable" if err < 0.05 else "wrong"
            else:
                err, status = float("nan"), "diverged"
                it = float("nan")
            iterations[name].append(it if name != VARIANTS[0][0] else float("nan"))
            rows.append((r, name, status, it, err, res.get("unconverged_windows", "—")))
            print(f"r = {r:g}  {name:24s} {status:9s} iterations {it:.3g}  error {err:.3g}", flush=True)

    with open(a.out / "mass_ratio.md", "w") as f:
        f.write("| mass ratio m_R/m_L | coupling | result | iterations / window | max rel. error vs monolithic | unconverged windows |\n")
        f.write("| --- | --- | --- | --- | --- | --- |\n")
        for r, name, status, it, err, unconv in rows:
            its = "1 (no iteration)" if name.startswith("weak") and status != "diverged" else ("—" if np.isnan(it) else f"{it:.2f}")
            errs = "—" if np.isnan(err) else f"{err:.1e}"
            f.write(f"| {r:g} | {name} | {status} | {its} | {errs} | {unconv} |\n")

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for name, _ in VARIANTS[1:]:
        ax[0].semilogx(a.ratios, iterations[name], "o-", label=name)
    ax[0].set_xlabel("mass ratio m_R / m_L")
    ax[0].set_ylabel("mean iterations per window")
    ax[0].set_title("Gauss–Seidel iterations (missing point: diverged)")
    ax[0].legend()
    r_show = 100 if 100 in a.ratios else a.ratios[-1]
    tm, um = histories[(r_show, "monolithic")]
    ax[1].plot(tm * 1e3, um * 1e3, "k-", lw=3, alpha=0.4, label="monolithic")
    for name, _ in VARIANTS:
        if (r_show, name) in histories:
            t, u = histories[(r_show, name)]
            ax[1].plot(t * 1e3, u * 1e3, "--", label=name)
    ax[1].set_xlabel("time [ms]")
    ax[1].set_ylabel("interface displacement [mm]")
    ax[1].set_title(f"r = {r_show:g}")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(a.out / "mass_ratio.png", dpi=120)


if __name__ == "__main__":
    main()
