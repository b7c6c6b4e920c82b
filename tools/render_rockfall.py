#!/usr/bin/env python3
"""Pictures of a coupled rockfall run: the net and the block at the net's largest deflection (a side view
and a perspective, the net coloured by its displacement, like Sautter et al. 2020, Figs. 10–17), and an
animation of the whole impact.

Usage:  tools/render_rockfall.py RESULTS [--out DIR] [--no-animation]
        RESULTS is a `cosim run configs/rockfall/cN.yaml --out RESULTS` folder (fem/fem.h5 and dem/dem.h5
        with snapshots: the rockfall scenes write both every 5 ms).
Writes DIR/rockfall_max_deflection.png and DIR/rockfall_impact.gif (DIR: RESULTS/plots).
"""
import argparse
import sys
from pathlib import Path

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import animation, cm, colors  # noqa: E402


def read_steps(path, group):
    """[(time, {dataset: array})] of the snapshots under `group` (a mesh or a particle set)."""
    steps = []
    with h5py.File(path, "r") as f:
        if f"{group}/steps" not in f:
            return steps
        for name in sorted(f[f"{group}/steps"]):
            g = f[f"{group}/steps/{name}"]
            data = {}
            g.visititems(lambda k, d: data.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
            steps.append((float(g.attrs["time"]), data))
    return steps


def load(results):
    fem, dem = results / "fem" / "fem.h5", results / "dem" / "dem.h5"
    for p in (fem, dem):
        if not p.exists():
            raise SystemExit(f"render_rockfall: {p} does not exist; run a rockfall scene with --out {results} first.")
    with h5py.File(fem, "r") as f:
        mesh = next(iter(f["meshes"]))
        cells = f[f"meshes/{mesh}/cells"][()]
    net = read_steps(fem, f"meshes/{mesh}")
    spheres = read_steps(dem, "particles/spheres")
    if not net or not spheres:
        raise SystemExit(f"render_rockfall: {results} holds no snapshots (the scenes' output.interval is 0?).")
    return cells, net, spheres


def nearest(steps, t):
    return min(steps, key=lambda s: abs(s[0] - t))[1]


def draw(ax, cells, net_step, sphere_step, norm, elev, azim, title):
    x = net_step["nodes"]
    d = np.linalg.norm(net_step["point/displacement"], axis=1)
    tri = ax.plot_trisurf(x[:, 0], x[:, 1], x[:, 2], triangles=cells, cmap="viridis", norm=norm, linewidth=0.1,
                          edgecolor=(0, 0, 0, 0.15), antialiased=True, alpha=0.75)
    tri.set_array(d[cells].mean(axis=1))
    p = sphere_step["position"]
    r = sphere_step["radius"].ravel()
    # Marker area in points²: the sphere's diameter on the axes' scale (≈ 300 points across the 3.9 m net;
    # an approximation in 3-D).
    ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=(2 * r / 3.9 * 300) ** 2, c="#b5651d", depthshade=True, alpha=0.95)
    ax.set_xlim(0, 3.9), ax.set_ylim(0, 3.9), ax.set_zlim(-1.2, 1.0)
    ax.set_box_aspect((3.9, 3.9, 2.2))
    ax.view_init(elev=elev, azim=azim)
    ax.set_xlabel("x [m]"), ax.set_zlabel("z [m]")
    if elev == 0:  # side view: the depth axis is edge-on
        ax.set_yticks([])
    else:
        ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=10)
    return tri


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--no-animation", action="store_true")
    a = ap.parse_args(argv)
    out = a.out or a.results / "plots"
    out.mkdir(parents=True, exist_ok=True)
    cells, net, spheres = load(a.results)
    sags = [-(s[1]["point/displacement"][:, 2].min()) for s in net]
    k = int(np.argmax(sags))
    t_max, net_max = net[k]
    dmax = max(np.linalg.norm(s[1]["point/displacement"], axis=1).max() for s in net)
    norm = colors.Normalize(0.0, dmax)
    fig = plt.figure(figsize=(12, 5.2))
    title = f"{a.results.name}: t = {t_max * 1e3:.0f} ms, largest net deflection {sags[k]:.3f} m"
    for i, (elev, azim, view) in enumerate([(0, -90, "side view"), (22, -60, "perspective")]):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        draw(ax, cells, net_max, nearest(spheres, t_max), norm, elev, azim, f"{title} ({view})" if i == 0 else view)
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap="viridis"), ax=fig.axes, shrink=0.6,
                 label="net displacement [m]")
    png = out / "rockfall_max_deflection.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    print(f"render_rockfall: {png}")
    if a.no_animation:
        return 0
    fig = plt.figure(figsize=(6.5, 5.2))
    ax = fig.add_subplot(1, 1, 1, projection="3d")

    def frame(i):
        ax.clear()
        t, step = net[i]
        draw(ax, cells, step, nearest(spheres, t), norm, 12, -70, f"{a.results.name}: t = {t * 1e3:.0f} ms")

    anim = animation.FuncAnimation(fig, frame, frames=len(net), interval=120)
    gif = out / "rockfall_impact.gif"
    anim.save(gif, writer=animation.PillowWriter(fps=8), dpi=70)
    plt.close(fig)
    print(f"render_rockfall: {gif}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
