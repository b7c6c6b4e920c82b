#!/usr/bin/env python3
"""Key results and plots of a rockfall run (configs/rockfall/*.yaml).

Run with:   python3 tools/rockfall_report.py results/c2 [results/c5 …] [--compare out.png]

Reads dem/dem.h5 (block trajectory and contact force F_C), fem/fem.h5 (support force F_R, centre
displacement) and coupling.h5 (iterations per window) of each results folder, adds under `results:` of
its summary.yaml: max_deflection (net centre, m), block_displacement (m), peak_reaction_force (N),
peak_contact_force (N), contact_duration (s), rebound_velocity (m/s, upward, at the end),
mean_coupling_iterations, energy_balance_error (coupled system, see energy_balance()),
interface_work_mismatch; and writes plots/rockfall.png (the paper's Figs. 9, 18, 19 quantities) and
plots/energy.png.
With several folders and --compare, one figure overlays them (Fig. 21-style comparison of levels).
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


def series(path, group):
    with h5py.File(path, "r") as f:
        g = f["timeseries"][group]
        return {k: g[k][()] for k in g.keys()}


def analyse(folder):
    dem = series(folder / "dem" / "dem.h5", "body_0")
    fem_r = series(folder / "fem" / "fem.h5", "reactions")
    fem_p = series(folder / "fem" / "fem.h5", "probes")
    coupling = series(folder / "coupling.h5", "windows")
    fc = np.sqrt(dem["fx"] ** 2 + dem["fy"] ** 2 + dem["fz"] ** 2)
    fr = np.sqrt(sum(fem_r[k] ** 2 for k in fem_r if k.startswith("boundary_f")))
    in_contact = dem["contacts"] > 0
    contact_time = dem["time"][in_contact]
    results = {
        "max_deflection": float(-fem_p["center_uz"].min()),
        "block_displacement": float(dem["z"][0] - dem["z"].min()),
        "peak_reaction_force": float(fr.max()),
        "peak_contact_force": float(fc.max()),
        "contact_duration": float(contact_time[-1] - contact_time[0]) if contact_time.size else 0.0,
        "rebound_velocity": float(dem["vz"][-1]),
        "mean_coupling_iterations": float(coupling["iterations"].mean()),
    }
    energy = energy_balance(folder)
    results["energy_balance_error"] = energy["error"]
    results["interface_work_mismatch"] = energy["mismatch"]
    return results, dem, fem_r["time"], fr, fc, energy


def energy_balance(folder):
    """Energy of the coupled system: block (kinetic, potential, contact elastic, dissipated by contact
    damping, friction, Cundall damping, bond fracture) + net (kinetic, strain, Rayleigh damping, minus the work of its
    own weight). Its change is the work the two sides' interface forces do on each other, which cancel
    when the coupling is consistent. The error is max |E(t) − E(0)| over the energy that enters the
    system: the block's initial kinetic energy plus its largest loss of potential energy."""
    d = series(folder / "dem" / "dem.h5", "energy")
    f = series(folder / "fem" / "fem.h5", "energy")
    t = d["time"]
    block = d["kinetic"] + d["potential"] + d["elastic"] + d["damping"] + d["friction"] + d["cundall"]
    if "bond_fracture" in d:  # a block of bonded spheres: what its breaking bonds released
        block = block + d["bond_fracture"]
    net_work_gravity = f["external_work"] - f["coupled_work"]
    net = f["kinetic"] + f["strain"] + f["damping"] - net_work_gravity
    net = np.interp(t, f["time"], net)
    total = block + net
    scale = d["kinetic"][0] + np.max(d["potential"][0] - d["potential"])
    return {
        "time": t,
        "block": block - block[0],
        "net": net - net[0],
        "total": total - total[0],
        "interface": d["wall_work"] + np.interp(t, f["time"], f["coupled_work"]),
        "scale": scale,
        "error": float(np.max(np.abs(total - total[0])) / scale),
        "mismatch": float(np.max(np.abs(d["wall_work"] + np.interp(t, f["time"], f["coupled_work"]))) / scale),
    }


def plot_energy(folder, e):
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(e["time"], e["block"], label="block: change of its energy")
    ax.plot(e["time"], e["net"], label="net: change of its energy")
    ax.plot(e["time"], e["total"], "k", label="coupled system: change (the balance error)")
    ax.plot(e["time"], e["interface"], ":", label="interface work mismatch (DEM wall + FEM coupled)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("energy [J]")
    ax.set_title(f"rockfall {folder.name}: energy balance error {100 * e['error']:.2f} % of {e['scale']:.0f} J")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(folder / "plots" / "energy.png", dpi=110)
    plt.close(fig)


def plot(folder, dem, tr, fr, fc):
    (folder / "plots").mkdir(exist_ok=True)
    fig, ax = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    ax[0].plot(dem["time"], dem["z"] - dem["z"][0])
    ax[0].set_ylabel("block displacement [m]")
    ax[1].plot(dem["time"], dem["vz"])
    ax[1].set_ylabel("block velocity [m/s]")
    ax[2].plot(dem["time"], fc / 1e3, label="contact force $F_C$")
    ax[2].plot(tr, fr / 1e3, label="reaction force $F_R$")
    ax[2].set_ylabel("force [kN]")
    ax[2].legend()
    ax[-1].set_xlabel("time [s]")
    for a in ax:
        a.grid(True, alpha=0.3)
    fig.suptitle(f"rockfall {folder.name}")
    fig.tight_layout()
    fig.savefig(folder / "plots" / "rockfall.png", dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=pathlib.Path)
    ap.add_argument("--compare", type=pathlib.Path, help="overlay all folders in one PNG")
    args = ap.parse_args(argv)
    runs = []
    for folder in args.folders:
        try:
            results, dem, tr, fr, fc, energy = analyse(folder)
        except (OSError, KeyError) as e:
            print(f"rockfall_report: {folder}: {e}", file=sys.stderr)
            return 2
        summary_file = folder / "summary.yaml"
        summary = yaml.safe_load(summary_file.read_text()) if summary_file.exists() else {}
        summary.setdefault("results", {}).update(results)
        summary_file.write_text(yaml.safe_dump(summary, sort_keys=False))
        plot(folder, dem, tr, fr, fc)
        plot_energy(folder, energy)
        runs.append((folder.name, dem, tr, fr, fc))
        print(f"{folder}: " + ", ".join(f"{k} {v:.4g}" for k, v in results.items()))
    if args.compare:
        fig, ax = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
        for name, dem, tr, fr, fc in runs:
            ax[0].plot(dem["time"], dem["z"] - dem["z"][0], label=name)
            ax[1].plot(dem["time"], fc / 1e3, label=name)
            ax[2].plot(tr, fr / 1e3, label=name)
        for a, label in zip(ax, ["block displacement [m]", "$F_C$ [kN]", "$F_R$ [kN]"]):
            a.set_ylabel(label)
            a.grid(True, alpha=0.3)
            a.legend()
        ax[-1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(args.compare, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
