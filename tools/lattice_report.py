#!/usr/bin/env python3
"""Stress-strain plots, crack patterns and a results table of lattice_solver runs.

Run with:   /usr/bin/python3 tools/lattice_report.py results/tension_5cm results/tension_10cm … \
                --out docs/validation/lattice [--name curves.png] [--labels "5 cm, 25 %" …]

Reads lattice.h5 (series /timeseries/curve, mesh /meshes/rods, removed rods /meshes/cracks) and
summary.yaml of each results folder and writes into --out:
  <name> (default lattice_curves.png)   all stress-strain curves in one figure (stress in MPa, strain in 1e-4)
  cracks_<folder>.png                   removed rods of each run projected on the plane of the loading axis,
                                        coloured by the increment of removal
  --size-effect FILE                   peak stress against specimen side, one series per aggregate fraction
and prints a Markdown table (case, rods, aggregate %, E, peak stress, strain at peak, rods removed,
increments, solves, solver iterations, wall time) on stdout. Needs Debian's python3-h5py,
python3-matplotlib, python3-yaml.
"""
import argparse
import pathlib
import sys

import h5py
import matplotlib
import numpy as np
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(folder):
    summary = yaml.safe_load((folder / "summary.yaml").read_text())
    with h5py.File(folder / "lattice.h5", "r") as f:
        curve = {k: f["timeseries/curve"][k][()] for k in f["timeseries/curve"].keys()}
        nodes = f["meshes/rods/nodes"][()]
        cracks = None
        if "meshes/cracks" in f:
            cells = f["meshes/cracks/cells"][()]
            inc = f["meshes/cracks/steps/000000/cell/increment"][()]
            cracks = (nodes[cells[:, 0]] + nodes[cells[:, 1]]) / 2, inc
    return summary, curve, nodes, cracks


def plot_curves(runs, path):
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, (summary, curve, _, _) in runs:
        sign = 1.0 if summary["results"].get("peak_stress", 0) * np.sign(curve["stress"].max() or 1) >= 0 else -1.0
        # The curve starts at the unloaded state, which the solver does not record.
        strain = np.concatenate(([0.0], np.abs(curve["strain"])))
        stress = np.concatenate(([0.0], sign * curve["stress"]))
        ax.plot(strain * 1e4, stress / 1e6, lw=1.4, label=label)
    ax.set_xlabel("strain [1e-4]")
    ax.set_ylabel("stress [MPa]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_cracks(label, summary, nodes, cracks, path, axis):
    fig, ax = plt.subplots(figsize=(5, 5))
    lateral = (axis + 1) % 3
    lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    if cracks is not None:
        mid, inc = cracks
        sc = ax.scatter(mid[:, lateral] * 100, mid[:, axis] * 100, c=inc, s=2, cmap="viridis")
        fig.colorbar(sc, ax=ax, label="increment of removal")
    ax.set_xlim(lo[lateral] * 100, hi[lateral] * 100)
    ax.set_ylim(lo[axis] * 100, hi[axis] * 100)
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[lateral] + " [cm]")
    ax.set_ylabel("xyz"[axis] + " [cm] (loading axis)")
    ax.set_title(f"{label}: {summary['results'].get('rods_removed', 0)} removed rods")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_size_effect(runs, path):
    series = {}
    for _, (summary, _, nodes, _) in runs:
        side = (nodes.max(axis=0) - nodes.min(axis=0)).min() * 100
        frac = round(100 * summary["results"].get("aggregate_fraction", 0))
        series.setdefault(frac, []).append((side, summary["results"]["peak_stress"] / 1e6))
    fig, ax = plt.subplots(figsize=(6, 4))
    for frac, pts in sorted(series.items()):
        pts.sort()
        sides = np.array([p[0] for p in pts])
        peaks = np.array([p[1] for p in pts])
        ax.plot(sides, peaks, "o", label=f"{frac} % aggregate")
        uniq = np.unique(sides)
        ax.plot(uniq, [peaks[sides == u].mean() for u in uniq], "-", color=ax.lines[-1].get_color(), alpha=0.6)
    ax.set_xlabel("specimen side [cm]")
    ax.set_ylabel("peak stress [MPa]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def row(label, summary):
    r = summary["results"]
    return (f"| {label} | {r['rods']:,} | {100 * r.get('aggregate_fraction', 0):.1f} | {r['youngs_modulus'] / 1e9:.2f} | "
            f"{r['peak_stress'] / 1e6:.3f} | {r['strain_at_peak']:.3g} | {r['rods_removed']:,} | {r['increments']} | "
            f"{r['solves']} | {r['solver_iterations']:,} | {summary['wall_time_s']:.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folders", nargs="+", type=pathlib.Path)
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--name", default="lattice_curves.png")
    ap.add_argument("--labels", nargs="*", help="one label per folder (default: the folder names)")
    ap.add_argument("--axis", type=int, default=2, help="loading axis 0/1/2 for the crack plots (default 2 = z)")
    ap.add_argument("--size-effect", type=pathlib.Path, help="also plot peak stress against specimen side into this PNG")
    ap.add_argument("--no-cracks", action="store_true", help="skip the crack-pattern plots")
    args = ap.parse_args()
    labels = args.labels or [f.name for f in args.folders]
    if len(labels) != len(args.folders):
        sys.exit("lattice_report: give one label per folder")
    runs = []
    for label, folder in zip(labels, args.folders):
        if not (folder / "lattice.h5").exists() or not (folder / "summary.yaml").exists():
            sys.exit(f"lattice_report: {folder} has no lattice.h5 and summary.yaml (is it a lattice_solver results folder?)")
        runs.append((label, load(folder)))
    args.out.mkdir(parents=True, exist_ok=True)
    plot_curves(runs, args.out / args.name)
    if args.size_effect:
        plot_size_effect(runs, args.out / args.size_effect)
    for folder, (label, (summary, _, nodes, cracks)) in zip(args.folders, runs):
        if not args.no_cracks:
            plot_cracks(label, summary, nodes, cracks, args.out / f"cracks_{folder.name}.png", args.axis)
    print("| case | rods | aggregate % | E [GPa] | peak stress [MPa] | strain at peak | rods removed | increments | solves "
          "| solver iterations | wall time [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for label, (summary, _, _, _) in runs:
        print(row(label, summary))


if __name__ == "__main__":
    main()
