#!/usr/bin/env python3
"""A ball's impact on a clamped plate (configs/verification/slab_impact*.yaml), the plate in fem_solver's
tet4 and in FEniCSx on the same gmsh mesh, the ball in dem_solver both times; and the ball on a rigid plate
(dem_solver alone, the mesh wall fixed) against Hertz's solution (Johnson 1985, §11.4: peak force and
contact duration of two elastic spheres, here a sphere and a half-space).

Prints a table of both coupled runs and the rigid one: the peak contact force, the contact duration, the
ball's rebound speed, the plate's largest displacement under the impact, and the wall time; writes
OUT/slab_compare.yaml with the same figures and OUT/slab_compare.png (displacement under the impact and
contact force against time, both codes).

Use: compare_slab.py BUILD_DIR OUT [--no-run]    (--no-run: read OUT's earlier runs)
"""
import argparse
import math
import pathlib
import subprocess
import sys

import h5py
import numpy as np
import yaml

REPO = pathlib.Path(__file__).resolve().parent.parent.parent
CONFIGS = REPO / "configs" / "verification"
RUNS = {"fem_solver": "slab_impact.yaml", "fenicsx": "slab_impact_fenicsx.yaml"}


def call(command):
    """A run's exit code; its output's tail printed if it failed."""
    p = subprocess.run([str(c) for c in command], capture_output=True, text=True)
    if p.returncode:
        print(p.stdout[-2000:], p.stderr[-2000:], file=sys.stderr)
    return p.returncode


def run(bin_dir, out, name):
    """One coupled run into OUT/NAME; its exit code."""
    return call([bin_dir / "cosim", "run", CONFIGS / RUNS[name], "--out", out / name, "--quiet"])


def run_rigid(bin_dir, out):
    """The ball on the plate's top face held fixed: dem_solver alone."""
    return call([bin_dir / "dem_solver", CONFIGS / "slab_impact_ball.yaml", "--out", out / "rigid", "--quiet",
                 "--set", "walls[0].motion=fixed", "--set", "interface=null"])


def ball(dem_h5):
    """The ball's history: time, contact force z, velocity z, number of contacts."""
    with h5py.File(dem_h5, "r") as f:
        b = f["timeseries/body_0"]
        return b["time"][()], b["fz"][()], b["vz"][()], b["contacts"][()]


def impact_figures(dem_h5):
    t, fz, vz, contacts = ball(dem_h5)
    touching, several = t[fz > 0], t[contacts > 1]
    return dict(peak_contact_force=float(fz.max()), peak_time=float(t[fz.argmax()]),
                contact_duration=float(touching[-1] - touching[0]) if len(touching) else 0.0,
                rebound_velocity=float(vz[-1]), most_contacts=int(contacts.max()),
                several_contacts_from=float(several[0]) if len(several) else None,
                several_contacts_to=float(several[-1]) if len(several) else None)


def plate(out, name):
    """Time and u_z of the node under the impact."""
    path = out / name / "fem" / ("fenicsx.h5" if name == "fenicsx" else "fem.h5")
    with h5py.File(path, "r") as f:
        g = f["timeseries/probes"]
        return g["time"][()], g["under_impact_uz"][()]


def plate_energy(out, name):
    """The plate's kinetic and strain energy at the end of the run."""
    if name == "fenicsx":
        r = yaml.safe_load((out / name / "fem" / "summary.yaml").read_text())["results"]
        return float(r["kinetic_energy"] + r["strain_energy"])
    with h5py.File(out / name / "fem" / "fem.h5", "r") as f:
        e = f["timeseries/energy"]
        return float(e["kinetic"][-1] + e["strain"][-1])


def ball_scene():
    """The ball's radius, mass and speed, and its and the plate's materials, from its scene."""
    scene = yaml.safe_load((CONFIGS / "slab_impact_ball.yaml").read_text())
    sphere = scene["spheres"][0]
    # PyYAML reads 1.0e8 (no sign in the exponent) as a string: every number through float().
    ball_m, plate_m = ({key: float(value) for key, value in scene["materials"][k].items()}
                       for k in scene["interactions"][0]["materials"])
    r, v = float(sphere["radius"]), abs(float(sphere["velocity"][2]))
    return r, ball_m["density"] * 4.0 / 3.0 * math.pi * r ** 3, v, ball_m, plate_m


def hertz():
    """Peak force and contact duration of the ball on a rigid, flat half-space of the plate's material
    (Johnson 1985, eqs. 11.45–11.47): δ* = (15 m v² / (16 E* √R))^(2/5), F* = 4/3 E* √R δ*^(3/2),
    t_c = 2.9432 δ*/v."""
    r, m, v, ball_m, plate_m = ball_scene()
    e_star = 1.0 / ((1 - ball_m["poisson_ratio"] ** 2) / ball_m["young_modulus"]
                    + (1 - plate_m["poisson_ratio"] ** 2) / plate_m["young_modulus"])
    delta = (15 * m * v * v / (16 * e_star * math.sqrt(r))) ** 0.4
    return dict(peak_contact_force=4.0 / 3.0 * e_star * math.sqrt(r) * delta ** 1.5, contact_duration=2.9432 * delta / v)


def coupled_figures(out, name):
    """The figures of one coupled run in OUT/NAME: the ball's impact, the plate's largest displacement under
    it, the coupler's summary, and the energy the ball lost against the plate's at the end."""
    fig = impact_figures(out / name / "dem" / "dem.h5")
    t, uz = plate(out, name)
    summary = yaml.safe_load((out / name / "summary.yaml").read_text())
    _, m, v, _, _ = ball_scene()
    fig.update(max_displacement=float(-uz.min()), max_displacement_time=float(t[uz.argmin()]),
               wall_time_s=float(summary["wall_time_s"]),
               mean_coupling_iterations=float(summary["results"]["mean_coupling_iterations"]),
               interface_energy_error=float(summary["results"]["interface_energy_error_dem_fem"]),
               plate_energy=plate_energy(out, name), ball_energy_lost=0.5 * m * (v * v - fig["rebound_velocity"] ** 2))
    return fig


def compare(out):
    """The figures of the runs in OUT, by run."""
    figures = {name: coupled_figures(out, name) for name in RUNS}
    figures["rigid"] = impact_figures(out / "rigid" / "dem.h5")
    figures["hertz"] = hertz()
    a, b = (plate(out, name) for name in RUNS)
    figures["same_instants"] = bool(len(a[0]) == len(b[0]) and np.abs(a[0] - b[0]).max() < 1e-12)
    figures["displacement_history_difference"] = (float(np.abs(a[1] - b[1]).max() / np.abs(a[1]).max())
                                                  if figures["same_instants"] else float("inf"))
    return figures


def table(fig):
    a, b = fig["fem_solver"], fig["fenicsx"]
    rows = [("peak contact force [kN]", "peak_contact_force", 1e-3), ("contact duration [ms]", "contact_duration", 1e3),
            ("rebound speed [m/s]", "rebound_velocity", 1.0), ("max displacement under the impact [mm]", "max_displacement", 1e3),
            ("wall time [s]", "wall_time_s", 1.0)]
    lines = ["| | fem_solver tet4 | FEniCSx | difference | rigid plate (dem_solver) | Hertz, rigid half-space |",
             "|---|---|---|---|---|---|"]
    for label, key, scale in rows:
        rigid = fig["rigid"].get(key)
        exact = fig["hertz"].get(key)
        diff = f"{b[key] / a[key] - 1:+.1e}" if key != "wall_time_s" else f"× {b[key] / a[key]:.2f}"
        lines.append(f"| {label} | {a[key] * scale:.5g} | {b[key] * scale:.5g} | {diff} | "
                     f"{'' if rigid is None else f'{rigid * scale:.5g}'} | {'' if exact is None else f'{exact * scale:.5g}'} |")
    return "\n".join(lines)


def plot(out, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for name, style in (("fem_solver", "-"), ("fenicsx", "--")):
        t, uz = plate(out, name)
        top.plot(t * 1e3, uz * 1e3, style, label=f"plate: {name}")
        tb, fz, _, _ = ball(out / name / "dem" / "dem.h5")
        bottom.plot(tb * 1e3, fz * 1e-3, style, label=f"plate: {name}")
    tb, fz, _, _ = ball(out / "rigid" / "dem.h5")
    bottom.plot(tb * 1e3, fz * 1e-3, ":", label="rigid plate")
    top.set_ylabel("u_z under the impact [mm]")
    bottom.set_ylabel("contact force [kN]")
    bottom.set_xlabel("time [ms]")
    top.legend()
    bottom.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--no-run", action="store_true")
    args = ap.parse_args()
    bin_dir = args.build / "bin"
    if not args.no_run:
        for name in RUNS:
            if run(bin_dir, args.out, name):
                print(f"error: the {name} run failed; see {args.out / name}", file=sys.stderr)
                return 1
        if run_rigid(bin_dir, args.out):
            return 1
    fig = compare(args.out)
    print(table(fig))
    print(f"displacement under the impact, largest difference over the run: {fig['displacement_history_difference']:.1e} "
          "of its peak")
    (args.out / "slab_compare.yaml").write_text(yaml.safe_dump(fig, sort_keys=False))
    plot(args.out, args.out / "slab_compare.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
