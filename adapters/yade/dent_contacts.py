#!/usr/bin/env python3
"""The rockfall block pressed into a dented net, in dem_solver and in YADE: the same triangles, the same
sphere, the same overlaps; how many facet contacts each code makes and the force they give.

Run with:  python3 adapters/yade/dent_contacts.py build OUT

The net is dem_solver's rockfall grid (3.9 m, 32 × 32, alternate) dented by z = −0.4 exp(−(d/0.6)²)
about the block's off-node position; the block (r = 0.2543 m, E = 1e5 Pa against the net's 5e7 Pa,
restitution 1) sits at the dent's bottom with its lowest point δ below it. One step of 1e-7 s, no
gravity: the contact forces of that geometry. Writes OUT/dent_contacts.md.
"""
import math
import pathlib
import subprocess
import sys

import numpy as np

HERE = pathlib.Path(sys.argv[0]).resolve().parent
sys.path.insert(0, str(HERE))
import cosim_yade  # noqa: E402

CENTRE = (2.03125, 1.990625)
RADIUS = 0.254343701269
DEPTH, WIDTH = 0.4, 0.6
OVERLAPS = [0.005, 0.02]


def dented_net():
    nodes, triangles = cosim_yade.grid_mesh([0, 0, 0], [3.9, 3.9], [32, 32])
    d = np.hypot(nodes[:, 0] - CENTRE[0], nodes[:, 1] - CENTRE[1])
    nodes[:, 2] = -DEPTH * np.exp(-(d / WIDTH) ** 2)
    return nodes, triangles


def centre(delta):
    return [CENTRE[0], CENTRE[1], -DEPTH + RADIUS - delta]


def write_stl(path, nodes, triangles):
    with open(path, "w") as f:
        f.write("solid dent\n")
        for t in triangles:
            a, b, c = nodes[t]
            n = np.cross(b - a, c - a)
            n /= np.linalg.norm(n)
            f.write(f" facet normal {n[0]} {n[1]} {n[2]}\n  outer loop\n")
            for p in (a, b, c):
                f.write(f"   vertex {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}\n")
            f.write("  endloop\n endfacet\n")
        f.write("endsolid dent\n")


def dem_solver_side(build, out, nodes, triangles):
    import h5py
    write_stl(out / "dent.stl", nodes, triangles)
    rows = {}
    for delta in OVERLAPS:
        scene = out / f"dent_{delta}.yaml"
        scene.write_text(f"""materials:
  concrete: {{density: 2600, young_modulus: 1.0e5, poisson_ratio: 0.25}}
  net: {{density: 81.25, young_modulus: 5.0e7, poisson_ratio: 0.0}}
interactions:
  - {{materials: [concrete, net], law: hertz_mindlin, restitution: 1.0, friction: 0.5}}
spheres:
  - {{material: concrete, radius: {RADIUS}, position: {centre(delta)}, velocity: [0, 0, 0]}}
walls:
  - {{type: mesh, name: net, material: net, file: dent.stl, sides: one}}
gravity: [0, 0, 0]
dt: 1.0e-7
end_time: 1.0e-7
output: {{interval: 1.0e-7, series_interval: 1.0e-7}}
probe: {{type: impact, body: 0}}
""")
        subprocess.run([str(build / "bin" / "dem_solver"), str(scene), "--out", str(out / f"dem_{delta}"), "--quiet"], check=True)
        with h5py.File(out / f"dem_{delta}" / "dem.h5", "r") as f:
            g = f["timeseries/body_0"]
            rows[delta] = (int(g["contacts"][-1]), float(g["fz"][-1]))
    return rows


def yade_side(out):
    import yade
    from yade import O
    nodes, triangles = np.load(out / "nodes.npy"), np.load(out / "triangles.npy")
    lines = []
    for delta in OVERLAPS:
        O.reset()
        concrete = O.materials.append(yade.FrictMat(young=1e5, poisson=0.25, density=2600, frictionAngle=math.atan(0.5)))
        net_material = O.materials.append(yade.FrictMat(young=5e7, poisson=0.0, density=81.25, frictionAngle=math.atan(0.5)))
        net = cosim_yade.FacetInterface(yade, nodes, triangles, net_material, margin=0.05)
        ball = O.bodies.append(yade.utils.sphere(tuple(centre(delta)), RADIUS, material=concrete, mask=cosim_yade.BODIES))
        O.engines = cosim_yade.engines(yade, 1.0, (0, 0, 0))
        O.dt = 1e-7
        net.set_near([(np.array(centre(delta)), RADIUS)], nodes, nodes)
        net.place(nodes, np.zeros_like(nodes))
        O.step()
        _, contacts, points = net.nodal_forces([ball])
        lines.append(f"{delta} {contacts} {points} {O.forces.f(ball)[2]}")
    (out / "yade.txt").write_text("\n".join(lines) + "\n")


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--yade-side":
        yade_side(pathlib.Path(sys.argv[2]))
        return 0
    build, out = pathlib.Path(sys.argv[1]).resolve(), pathlib.Path(sys.argv[2]).resolve()
    out.mkdir(parents=True, exist_ok=True)
    nodes, triangles = dented_net()
    np.save(out / "nodes.npy", nodes)
    np.save(out / "triangles.npy", triangles)
    ours = dem_solver_side(build, out, nodes, triangles)
    subprocess.run(["yade", "-n", "-x", str(HERE / "dent_contacts.py"), "--yade-side", str(out)], check=True,
                   capture_output=True)
    theirs = {float(a): (int(b), int(c), float(d)) for a, b, c, d in
              (line.split() for line in (out / "yade.txt").read_text().splitlines())}
    lines = ["| overlap δ [m] | dem_solver contacts | dem_solver F_z [N] | YADE contacts (distinct points) | YADE F_z [N] | YADE / dem_solver |",
             "|---|---|---|---|---|---|"]
    for delta in OVERLAPS:
        c, f = ours[delta]
        yc, yp, yf = theirs[delta]
        lines.append(f"| {delta} | {c} | {f:.1f} | {yc} ({yp}) | {yf:.1f} | {yf / f:.2f} |")
    (out / "dent_contacts.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    if "yade" in sys.modules:
        import os
        os._exit(code)
    sys.exit(code)
