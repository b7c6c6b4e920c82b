#!/usr/bin/env python3
"""The bridging domain's wave study (docs/validation/bridging.md): configs/verification/bridging_wave.yaml
with the overlap narrowed and the truss coarsened, against d'Alembert's solution and the bar as one truss.

Usage:  tools/bridging_study.py BUILD_DIR OUT [--pairs N]

For each case it writes the three scenes into OUT/CASE, runs `cosim run`, and reads summary.yaml and the
snapshots: the reflected and transmitted energy fractions, the coupled energy drift, the largest
difference between the pulse in the chain at the end and f(x − ct) (as a share of the amplitude), and the
wall time. Prints a Markdown table (also OUT/bridging.md) and draws OUT/bridging_wave.png: the pulse
before, in and after the overlap (truss and chain) over the one-truss bar and d'Alembert's solution.

Then the slab (configs/verification/bridging_slab.yaml) coupled, coupled with the spheres' spin left
free, and as spheres throughout (bridging_slab_all_dem.yaml): the vertical displacement under the impact
and 0.7 m from it against time, their largest difference (OUT/bridging_slab.md, OUT/bridging_slab.png);
and the cost, the slab 1 m and 3 m long (the continuum taking the extra length): the coupled run and the
spheres throughout in turn, N pairs, each pair's ratio, and the medians.
"""
import argparse
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "configs/verification"
C, CENTER, HALF, AMPLITUDE, R = 1000.0, 0.4, 0.2, 1.0e-5, 0.005
GAP = 1e-9  # bridging_wave_dem.yaml's spheres are 1 nm apart


def exact(x, t):
    xi = (x - C * t - CENTER) / HALF
    return np.where(np.abs(xi) < 1, AMPLITUDE * 0.5 * (1 + np.cos(np.pi * xi)), 0.0)


def write_case(folder, width, elements):
    """The wave scene with an overlap of `width` ending at x = 1.0 and the truss in `elements` elements."""
    folder.mkdir(parents=True, exist_ok=True)
    start = 1.0 - width
    fem = yaml.safe_load((SCENES / "bridging_wave_fem.yaml").read_text())
    fem["mesh"]["line"]["elements"] = elements
    fem["bridging"].update({"full": start, "none": 1.0})
    dem = yaml.safe_load((SCENES / "bridging_wave_dem.yaml").read_text())
    count = int(round((2.0 - start) / (2 * R)))
    template = dem["spheres"][0]
    dem["spheres"] = [dict(template, position=[start + R + (2 * R + GAP) * i, 0, 0]) for i in range(count)]
    dem["bridging"].update({"full": 1.0, "none": start})
    (folder / "bridging_wave_fem.yaml").write_text(yaml.safe_dump(fem))
    (folder / "bridging_wave_dem.yaml").write_text(yaml.safe_dump(dem))
    (folder / "bridging_wave.yaml").write_text((SCENES / "bridging_wave.yaml").read_text())
    return folder / "bridging_wave.yaml"


def snapshots(h5, group):
    g = h5[group]
    return [(float(g[k].attrs["time"]), g[k]) for k in sorted(g.keys())]


def chain_error(dem_h5, starts):
    with h5py.File(dem_h5) as h:
        t, s = snapshots(h, "particles/spheres/steps")[-1]
        x = starts[s["body"][:].astype(int)]
        return float(np.abs(s["position"][:, 0] - x - exact(x, t)).max() / AMPLITUDE)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--pairs", type=int, default=1, help="slab runs timed in turn, coupled and spheres throughout")
    a = ap.parse_args()
    bin_dir, out = (a.build / "bin").resolve(), a.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    # The tie runs past the energy check (which stops it at 5 %) to show where it goes.
    tie = ["--set", "coupling.constraint=tie", "--set", "coupling.energy_tolerance=999"]
    cases = [("0.2 m overlap, 2 cm truss", 0.2, 50, []), ("0.1 m", 0.1, 50, []), ("0.04 m (2 elements)", 0.04, 50, []),
             ("0.02 m (1 element)", 0.02, 50, []), ("0.2 m overlap, 4 cm truss", 0.2, 25, []),
             ("0.2 m, 10 cm truss", 0.2, 10, []), ("0.2 m overlap, a tie (no multipliers)", 0.2, 50, tie)]
    cubic = ["--set", "fem:bridging.shape=cubic", "--set", "dem:bridging.shape=cubic"]
    cases += [("0.2 m overlap, cubic α", 0.2, 50, cubic), ("0.02 m (1 element), cubic α", 0.02, 50, cubic)]
    rows = []
    for name, width, elements, sets in cases:
        folder = out / f"w{width}_e{elements}{'_' + sets[1].split('=')[-1] if sets else ''}"
        scene = write_case(folder, width, elements)
        t0 = time.monotonic()
        r = subprocess.run([str(bin_dir / "cosim"), "run", str(scene), "--out", str(folder / "run"), *sets],
                           capture_output=True, text=True)
        wall = time.monotonic() - t0
        s = yaml.safe_load((folder / "run/summary.yaml").read_text())
        if r.returncode != 0:
            rows.append(f"| {name} | exit {r.returncode}: {s.get('failure', {}).get('cause', '?')} | | | | |")
            continue
        res = s["results"]
        starts = np.array([p["position"][0] for p in yaml.safe_load((folder / "bridging_wave_dem.yaml").read_text())["spheres"]])
        rows.append(f"| {name} | {res['reflected_energy_fraction']:.2e} | {res['transmitted_energy_fraction']:.4f} | "
                    f"{res['energy_drift_fraction']:.1e} | {chain_error(folder / 'run/dem/dem.h5', starts):.3f} | {wall:.1f} |")
        print(rows[-1], flush=True)

    ref = out / "reference"
    subprocess.run([str(bin_dir / "fem_solver"), str(SCENES / "bridging_wave_reference.yaml"), "--out", str(ref),
                    "--quiet"], check=True)
    with h5py.File(ref / "fem.h5") as h:
        x = h["meshes/line/nodes"][:, 0]
        order = np.argsort(x)
        t, s = snapshots(h, "meshes/line/steps")[-1]
        alone = np.abs(s["point/displacement"][:, 0][order] - exact(x[order], t))[x[order] > 1.0].max() / AMPLITUDE
    table = ["| case | reflected | transmitted | energy drift | chain vs f(x − ct) | wall [s] |",
             "| --- | --- | --- | --- | --- | --- |", *rows,
             f"| the bar as one 2 cm truss (fem_solver alone) | | | | {alone:.3f} | |"]
    (out / "bridging.md").write_text("\n".join(table) + "\n")
    print("\n".join(table))
    plot(out / "w0.2_e50", ref, out / "bridging_wave.png")
    slab(bin_dir, out, a.pairs)
    return 0


NEAR, FAR = (0.105, 0.155, 0.005), (0.805, 0.155, 0.005)  # under the impact, and 0.7 m from it (slab bottom)


def sphere_history(dem_h5, point):
    """t and u_z of the sphere whose first snapshot centre is nearest `point`."""
    with h5py.File(dem_h5) as h:
        snaps = snapshots(h, "particles/spheres/steps")
        first = snaps[0][1]
        i = int(np.argmin(np.linalg.norm(first["position"][:] - np.array(point), axis=1)))
        body = int(first["body"][i])
        z0 = first["position"][i, 2]
        out = []
        for t, s in snaps:
            j = int(np.flatnonzero(s["body"][:] == body)[0])
            out.append((t, s["position"][j, 2] - z0))
        return np.array(out)


def node_history(fem_h5, point):
    with h5py.File(fem_h5) as h:
        x = h["meshes/volume/nodes"][:]
        n = int(np.argmin(np.linalg.norm(x - np.array(point), axis=1)))
        return np.array([(t, s["point/displacement"][n, 2]) for t, s in snapshots(h, "meshes/volume/steps")])


def timed(cmd):
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.monotonic() - t0


def slab_cost(bin_dir, out, length, pairs):
    """Wall times of the slab `length` m long, coupled and as spheres throughout, in turn."""
    cells = int(round(length / 0.01))
    coupled = [str(bin_dir / "cosim"), "run", str(SCENES / "bridging_slab.yaml"), "--out", str(out / f"slab_{length}"),
               "--set", f"fem:mesh.box.size=[{length - 0.15},0.3,0.06]"]
    spheres = [str(bin_dir / "dem_solver"), str(SCENES / "bridging_slab_all_dem.yaml"), "--out",
               str(out / f"slab_all_dem_{length}"), "--quiet", "--set", f"clusters[0].box.n=[{cells},30,6]",
               "--set", f"clusters[0].position=[{length / 2},0.15,0.03]"]
    walls = {"coupled": [], "all_dem": []}
    for _ in range(pairs):  # in turn: the machine's drift hits both alike
        walls["coupled"].append(timed(coupled))
        walls["all_dem"].append(timed(spheres))
    ratios = [c / a for c, a in zip(walls["coupled"], walls["all_dem"])]
    with h5py.File(out / f"slab_{length}/fem/fem.h5") as h:
        tets = h["meshes/volume/cells"].shape[0]
    bonded = yaml.safe_load((out / f"slab_{length}/dem/summary.yaml").read_text())["results"]["spheres"] - 1  # not the ball
    return (f"| {length:g} m | {cells * 180:,} | {bonded:,} spheres + {tets:,} tet4 | "
            f"{np.median(walls['coupled']):.1f} | {np.median(walls['all_dem']):.1f} | "
            f"{np.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f}) |")


def slab(bin_dir, out, pairs=1):
    for folder, extra in (("slab", []), ("slab_free", ["--set", "coupling.rotations=free"])):
        subprocess.run([str(bin_dir / "cosim"), "run", str(SCENES / "bridging_slab.yaml"), "--out", str(out / folder),
                        *extra], check=True, capture_output=True)
    subprocess.run([str(bin_dir / "dem_solver"), str(SCENES / "bridging_slab_all_dem.yaml"), "--out",
                    str(out / "slab_all_dem"), "--quiet"], check=True, capture_output=True)
    near_c = sphere_history(out / "slab/dem/dem.h5", NEAR)
    near_f = sphere_history(out / "slab_free/dem/dem.h5", NEAR)
    near_a = sphere_history(out / "slab_all_dem/dem.h5", NEAR)
    far_c = node_history(out / "slab/fem/fem.h5", FAR)
    far_f = node_history(out / "slab_free/fem/fem.h5", FAR)
    far_a = sphere_history(out / "slab_all_dem/dem.h5", FAR)
    s = yaml.safe_load((out / "slab/summary.yaml").read_text())["results"]
    sf = yaml.safe_load((out / "slab_free/summary.yaml").read_text())["results"]

    def diff(c, a):
        ta = a[:, 0]
        return float(np.abs(np.interp(ta, c[:, 0], c[:, 1]) - a[:, 1]).max() / np.abs(a[:, 1]).max())

    table = ["| | coupled (spheres x ≤ 0.25 m, tet4 x ≥ 0.15 m) | coupled, spin free | spheres throughout |",
             "| --- | --- | --- | --- |",
             f"| largest downward displacement under the impact [µm] | {-near_c[:, 1].min() * 1e6:.1f} | {-near_f[:, 1].min() * 1e6:.1f} | {-near_a[:, 1].min() * 1e6:.1f} |",
             f"| largest displacement 0.7 m from it [µm] | {np.abs(far_c[:, 1]).max() * 1e6:.2f} | {np.abs(far_f[:, 1]).max() * 1e6:.2f} | {np.abs(far_a[:, 1]).max() * 1e6:.2f} |",
             f"| largest difference from spheres throughout, under the impact | {diff(near_c, near_a):.3f} | {diff(near_f, near_a):.3f} | |",
             f"| … 0.7 m from it | {diff(far_c, far_a):.3f} | {diff(far_f, far_a):.3f} | |",
             f"| velocity mismatch in the overlap after the correction | {s['bridging_velocity_mismatch']:.1e} | {sf['bridging_velocity_mismatch']:.1e} | |",
             f"| spin mismatch after the correction | {s.get('bridging_spin_mismatch', float('nan')):.1e} | | |",
             f"| multiplier system: unknowns, non-zeros of the factor | {3 * s['bridging_nodes']}, {s['bridging_factor_nonzeros']} | {sf['bridging_nodes']}, {sf['bridging_factor_nonzeros']} | |",
             f"| multipliers' time [s] | {s['bridging_solve_time_s']:.2f} | {sf['bridging_solve_time_s']:.2f} | |"]
    cost = ["| slab | spheres throughout | coupled | wall coupled [s] | wall spheres throughout [s] | ratio, median of the pairs' |",
            "| --- | --- | --- | --- | --- | --- |", slab_cost(bin_dir, out, 1.0, pairs), slab_cost(bin_dir, out, 3.0, pairs)]
    # Where a coupled step's time goes, from each run's summary.yaml.
    where = ["| run | windows | multipliers per step [ms] | outside the solvers per pass [ms] | share outside the solvers | "
             "continuum's solver time [s] |", "| --- | --- | --- | --- | --- | --- |"]
    for name, folder in (("wave, 0.2 m overlap", out / "w0.2_e50/run"), ("slab 1 m, spin tied", out / "slab"),
                         ("slab 1 m, spin free", out / "slab_free"), ("slab 3 m, spin tied", out / "slab_3.0")):
        r = yaml.safe_load((folder / "summary.yaml").read_text())["results"]
        where.append(f"| {name} | {r['windows']} | {r['bridging_solve_time_s'] / r['windows'] * 1e3:.2g} | "
                     f"{r['outside_solvers_per_pass_s'] * 1e3:.2f} | {r['coupling_overhead_share']:.2f} | "
                     f"{r['solver_time_fem']:.1f} |")
    (out / "bridging_slab.md").write_text("\n\n".join("\n".join(t) for t in (table, cost, where)) + "\n")
    for t in (table, cost, where):
        print("\n".join(t))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, (c, a, title) in zip(axes, ((near_c, near_a, "under the impact (x = 0.1 m)"),
                                        (far_c, far_a, "0.7 m from it (x = 0.8 m)"))):
        ax.plot(a[:, 0] * 1e3, a[:, 1] * 1e6, "k-", label="spheres throughout (dem_solver)")
        ax.plot(c[:, 0] * 1e3, c[:, 1] * 1e6, "r--", label="spheres + tet4, bridged (cosim)")
        f = near_f if c is near_c else far_f
        ax.plot(f[:, 0] * 1e3, f[:, 1] * 1e6, "b:", label="bridged, spin free")
        ax.set_xlabel("t [ms]")
        ax.set_ylabel("u_z [µm]")
        ax.set_title(title, fontsize=9)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "bridging_slab.png", dpi=110)
    print(f"wrote {out / 'bridging_slab.png'}")


def plot(case, ref, png):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot")
        return
    starts = np.array([p["position"][0] for p in yaml.safe_load((case / "bridging_wave_dem.yaml").read_text())["spheres"]])
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    with h5py.File(case / "run/fem/fem.h5") as f, h5py.File(case / "run/dem/dem.h5") as d, h5py.File(ref / "fem.h5") as r:
        xf = f["meshes/line/nodes"][:, 0]
        xr = r["meshes/line/nodes"][:, 0]
        fem, dem, one = (dict(snapshots(f, "meshes/line/steps")), dict(snapshots(d, "particles/spheres/steps")),
                         dict(snapshots(r, "meshes/line/steps")))
        for ax, want in zip(axes, (2e-4, 5e-4, 9e-4)):
            near = lambda snaps: min(snaps, key=lambda t: abs(t - want))
            tf, td, tr = near(fem), near(dem), near(one)
            of, orr = np.argsort(xf), np.argsort(xr)
            xs = np.linspace(0, 2, 801)
            ax.plot(xs, exact(xs, tf) * 1e6, color="0.7", lw=3, label="d'Alembert f(x − ct)")
            ax.plot(xr[orr], one[tr]["point/displacement"][:, 0][orr] * 1e6, "k:", label="one truss, 2 cm (fem_solver)")
            ax.plot(xf[of], fem[tf]["point/displacement"][:, 0][of] * 1e6, "b.-", ms=4, label="truss (coupled)")
            s = dem[td]
            x0 = starts[s["body"][:].astype(int)]
            ax.plot(x0, (s["position"][:, 0] - x0) * 1e6, "r.", ms=3, label="chain of spheres (coupled)")
            ax.axvspan(0.8, 1.0, color="orange", alpha=0.15, label="overlap" if want == 2e-4 else None)
            ax.set_ylabel("u [µm]")
            ax.set_title(f"t = {tf * 1e3:.2f} ms", fontsize=9)
        axes[0].legend(fontsize=7, loc="upper right")
        axes[-1].set_xlabel("x [m]")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    print(f"wrote {png}")


if __name__ == "__main__":
    sys.exit(main())
