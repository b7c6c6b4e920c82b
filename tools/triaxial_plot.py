#!/usr/bin/env python3
"""Plots of triaxial tests (dem_solver scenes with `triaxial:`), like Kozicki & Donzé 2008, Figs. 17–18.

Usage:  tools/triaxial_plot.py RESULTS [RESULTS ...] [--out triaxial.png] [--network network.png]
                                [--peer CSV:LABEL ...] [--labels A,B,...]
        Each RESULTS is a `dem_solver configs/dem/triaxial.yaml --out RESULTS` folder (dem.h5,
        summary.yaml; peak.h5 for the network).
Writes --out: deviatoric stress q and volumetric strain ε_v against axial strain ε1 for every run on one
figure (compression positive; one colour per run, labelled by its confining pressure), and --network: the
normal force network at the peak of the first run, the contacts whose midpoints lie in the middle
quarter of the sample's depth (y), projected on the x–z plane, line width ∝ force (compression black,
tension red: bonds). With runs at two or more confining pressures it prints the Mohr–Coulomb envelope
through their peaks, σ1 = N σ3 + 2 c √N with N = (1 + sin φ)/(1 − sin φ) (least squares): φ and c.
--peer draws another code's curves (a CSV of tests/bench/peers/triaxial_yade.py) dashed on the same axes,
and prints its peak against the first run's.
"""
import argparse
import sys
from pathlib import Path

import h5py
import matplotlib
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_run(folder):
    h5 = folder / "dem.h5"
    summary = folder / "summary.yaml"
    if not h5.exists() or not summary.exists():
        raise SystemExit(f"triaxial_plot: {folder} has no dem.h5 and summary.yaml; run a triaxial scene with --out {folder}.")
    with h5py.File(h5, "r") as f:
        if "timeseries/triaxial" not in f:
            raise SystemExit(f"triaxial_plot: {h5} has no triaxial series (not a triaxial scene?).")
        g = f["timeseries/triaxial"]
        data = {k: g[k][()] for k in g.keys()}
    results = yaml.safe_load(summary.read_text()).get("results", {})
    return data, results


def envelope(runs):
    """(φ [°], c [Pa]) of the Mohr–Coulomb line through the runs' peaks, or None for fewer than two pressures."""
    s3 = np.array([r["confining_pressure"] for _, _, r in runs])
    s1 = s3 + np.array([r["peak_deviatoric_stress"] for _, _, r in runs])
    if len(set(s3)) < 2:
        return None
    slope, intercept = np.polyfit(s3, s1, 1)
    phi = np.degrees(np.arcsin((slope - 1) / (slope + 1)))
    return phi, intercept / (2 * np.sqrt(slope))


def read_peer(spec):
    path, _, label = spec.partition(":")
    data = np.genfromtxt(path, delimiter=",", names=True)
    return label or Path(path).stem, data


def plot_curves(runs, out, fit, peers=()):
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(6.5, 7.5))
    for label, data in peers:
        e1 = 100 * np.concatenate([[0.0], data["axial_strain"]])
        top.plot(e1, np.concatenate([[0.0], data["deviatoric_stress"]]) / 1e3, "--", lw=1.5, label=label)
        bottom.plot(e1, 100 * np.concatenate([[0.0], data["volumetric_strain"]]), "--", lw=1.5, label=label)
    for label, data, results in runs:
        if peers:
            label = f"dem_solver, {label}"
        # The compression rows, from the consolidated state (the last consolidation row, ε1 = 0).
        shear = data["phase"] > 0.5
        first = int(np.argmax(shear))
        if first > 0:
            shear[first - 1] = True
        e1 = 100 * data["axial_strain"][shear]
        top.plot(e1, data["deviatoric_stress"][shear] / 1e3, lw=1.5, label=label)
        bottom.plot(e1, 100 * data["volumetric_strain"][shear], lw=1.5, label=label)
        if "peak_deviatoric_stress" in results:
            top.plot(100 * results["axial_strain_at_peak"], results["peak_deviatoric_stress"] / 1e3, "k.", ms=6)
    top.set_ylabel("deviatoric stress q = σ1 − σ3 [kPa]")
    bottom.set_ylabel("volumetric strain ε_v [%] (compaction > 0)")
    bottom.set_xlabel("axial strain ε1 [%]")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
        ax.legend()
    bottom.axhline(0, color="0.5", lw=0.8)
    title = "Triaxial compression (dem_solver" + ("".join(f" vs {p[0]}" for p in peers)) + ")"
    if fit:
        title += f"\nMohr–Coulomb envelope of the peaks: φ = {fit[0]:.1f}°, c = {fit[1] / 1e3:.1f} kPa"
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    print(f"triaxial_plot: wrote {out}")


def plot_network(folder, out):
    path = folder / "peak.h5"
    if not path.exists():
        raise SystemExit(f"triaxial_plot: {path} does not exist (the run reached no peak?).")
    with h5py.File(path, "r") as f:
        steps = f["networks/contacts/steps"]
        step = steps[sorted(steps)[-1]]
        points = step["points"][()]
        lines = step["lines"][()]
        force = step["normal_force"][()].ravel()
        time = float(step.attrs["time"])
    a, b = points[lines[:, 0]], points[lines[:, 1]]
    # A slab through the middle: the whole depth projected hides the chains behind each other.
    y = 0.5 * (a[:, 1] + b[:, 1])
    lo, hi = y.min(), y.max()
    keep = np.abs(y - 0.5 * (lo + hi)) <= 0.125 * (hi - lo)
    a, b, force = a[keep], b[keep], force[keep]
    scale = 3.0 / max(np.abs(force).max(), 1e-300)
    fig, ax = plt.subplots(figsize=(5, 8))
    from matplotlib.collections import LineCollection

    segments = np.stack([a[:, [0, 2]], b[:, [0, 2]]], axis=1)
    colours = np.where(force >= 0, "black", "red")
    ax.add_collection(LineCollection(segments, linewidths=np.abs(force) * scale, colors=colours))
    ax.autoscale()
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(f"normal forces at the peak (t = {time:.4g} s)\nmiddle quarter in y; width ∝ force;\n"
                 "black compression, red tension", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    print(f"triaxial_plot: wrote {out}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, default=Path("triaxial.png"))
    ap.add_argument("--network", type=Path, help="also draw the first run's force network at the peak here")
    ap.add_argument("--peer", action="append", default=[], help="CSV:LABEL of another code's run, drawn dashed")
    ap.add_argument("--labels", help="comma-separated legend labels of the runs (default: their σ3)")
    args = ap.parse_args(argv)
    runs = []
    labels = args.labels.split(",") if args.labels else []
    for k, folder in enumerate(args.results):
        data, results = read_run(folder)
        sigma3 = results.get("confining_pressure")
        label = labels[k] if k < len(labels) else f"σ3 = {sigma3 / 1e3:.0f} kPa" if sigma3 else folder.name
        runs.append((label, data, results))
    fit = envelope(runs) if not args.labels else None
    if fit:
        print(f"triaxial_plot: Mohr–Coulomb envelope through {len(runs)} peaks: φ = {fit[0]:.2f}°, c = {fit[1]:.4g} Pa")
    peers = [read_peer(p) for p in args.peer]
    for label, data in peers:
        ours = runs[0][2]
        q = data["deviatoric_stress"]
        k = int(np.argmax(q))
        print(f"triaxial_plot: {label}: peak q = {q[k]:.6g} Pa at ε1 = {data['axial_strain'][k]:.4f}; "
              f"{runs[0][0]}: {ours['peak_deviatoric_stress']:.6g} Pa at {ours['axial_strain_at_peak']:.4f} "
              f"(ratio {ours['peak_deviatoric_stress'] / q[k]:.3f})")
    plot_curves(runs, args.out, fit, peers)
    if args.network:
        plot_network(args.results[0], args.network)
    return 0


if __name__ == "__main__":
    sys.exit(main())
