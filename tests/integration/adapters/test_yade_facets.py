"""The YADE adapter's facets inside YADE (run as `yade -n -x test_yade_facets.py ADAPTER_DIR`):

- a sphere pressed into the net off its nodes, and one on a node (where the net's eight facets make
  eight contacts at four points: YADE counts each twice), the net moving under it:
  the nodal forces sent to the coupler sum to minus the contact force YADE puts on the sphere, and their
  moment about the sphere's centre is that of the contact forces (each split at its contact point);
- a window repeated after O.loadTmp gives the same nodal forces, bit for bit;
- facets far from the sphere are never placed, and one left behind is placed again when it is near.
"""
import os
import sys

import numpy as np

sys.path.insert(0, sys.argv[1])
import cosim_yade  # noqa: E402

import yade  # noqa: E402
from yade import O, Vector3  # noqa: E402

failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name} {detail}", flush=True)
    if not ok:
        failures.append(name)


def scene(x, y):
    O.reset()
    nodes, triangles = cosim_yade.grid_mesh([0, 0, 0], [1.0, 1.0], [8, 8])
    net_material = O.materials.append(yade.FrictMat(young=5e7, poisson=0.0, density=80, frictionAngle=0.4))
    ball_material = O.materials.append(yade.FrictMat(young=1e6, poisson=0.25, density=2600, frictionAngle=0.4))
    net = cosim_yade.FacetInterface(yade, nodes, triangles, net_material, margin=0.02)
    ball = O.bodies.append(yade.utils.sphere((x, y, 0.099), 0.1, material=ball_material, mask=cosim_yade.BODIES))
    O.bodies[ball].state.vel = Vector3(0.3, -0.2, -1.0)
    O.engines = cosim_yade.engines(yade, 0.5, (0, 0, -9.81))
    O.dt = 1e-6
    return nodes, net, ball


def window(nodes, net, ball, u_end, steps=200):
    """One window of `steps` steps moving the net from rest to u_end: the nodal forces at each step."""
    rate = u_end / (steps * O.dt)
    centre = np.array(O.bodies[ball].state.pos)
    net.set_near([(centre, 0.1)], nodes, nodes + u_end)
    net.place(nodes, rate)
    out = []
    for s in range(steps):
        O.step()
        f, contacts, points = net.nodal_forces([ball])
        out.append((f, contacts, points))
    return out


for label, (x, y) in {"off the nodes": (0.43, 0.61), "on a node": (0.5, 0.5)}.items():
    nodes, net, ball = scene(x, y)
    u_end = np.zeros_like(nodes)
    u_end[:, 2] = -0.0002 * np.exp(-20 * ((nodes[:, 0] - 0.5) ** 2 + (nodes[:, 1] - 0.5) ** 2))  # a dent
    steps = window(nodes, net, ball, u_end)
    f, contacts, points = steps[-1]
    on_ball = np.array(O.forces.f(ball))
    centre = np.array(O.bodies[ball].state.pos)
    moment_nodes = sum(np.cross(p - centre, g) for p, g in zip(nodes + u_end, f))
    moment_ball = np.array(O.forces.t(ball))  # the contact forces' moment about the centre, on the ball
    check(f"{label}: in contact", contacts >= 1, f"({contacts} facet contacts)")
    if label == "off the nodes":
        check(f"{label}: one contact, one point", contacts == 1 and points == 1, f"({contacts}, {points})")
    else:  # YADE's facets: the two facets of each edge at the node make a contact at the same point
        check(f"{label}: every point counted by two facets", contacts == 2 * points, f"({contacts} contacts, {points} points)")
    check(f"{label}: nodal forces sum to minus the ball's contact force", np.abs(f.sum(axis=0) + on_ball).max() < 1e-9 * np.abs(on_ball).max(),
          f"(sum {f.sum(axis=0)}, ball {on_ball})")
    # The contact point halfway into the overlap, the facets translated rather than stretched: the moment
    # agrees to the overlap times the force.
    overlap = 0.1 - centre[2]
    check(f"{label}: their moment about the centre is the contact forces'",
          np.abs(moment_nodes + moment_ball).max() <= 2 * overlap * np.abs(on_ball).max() + 1e-9,
          f"(nodes {moment_nodes}, ball {moment_ball}, overlap {overlap:.2e} m)")
    check(f"{label}: far facets are never placed nor made", net.near.sum() < len(net.ids) / 4 and net.made() == net.near.sum(),
          f"({net.near.sum()} of {len(net.ids)} near, {net.made()} made)")

# A repeated window: O.saveTmp before, O.loadTmp after, the same forces.
nodes, net, ball = scene(0.43, 0.61)
u_end = np.zeros_like(nodes)
u_end[:, 2] = -0.0002
O.saveTmp("w")
saved = net.state()
first = window(nodes, net, ball, u_end)
O.loadTmp("w")
O.engines[1].doSort = True
net.restore(saved)
second = window(nodes, net, ball, u_end)
check("repeat after O.loadTmp: the same nodal forces, bit for bit",
      all(np.array_equal(a[0], b[0]) and a[1] == b[1] for a, b in zip(first, second)) and first[-1][1] > 0)

# A facet left behind (near once, then far) is placed again when it is near.
nodes, net, ball = scene(0.43, 0.61)
k = int(np.argmin(np.linalg.norm(nodes[net.triangles].mean(axis=1) - [0.43, 0.61, 0], axis=1)))
net.set_near([(np.array([0.43, 0.61, 0.1]), 0.1)], nodes, nodes)
net.place(nodes, np.zeros_like(nodes))
net.set_near([(np.array([5.0, 5.0, 5.0]), 0.1)], nodes, nodes)
check("a facet far from every body is not near", not net.near[k])
moved = nodes + [0, 0, -0.5]
net.set_near([(np.array([0.43, 0.61, 0.1]), 0.1)], moved, moved)
check("a facet whose last place is near a body is near even when the mesh has moved away", bool(net.near[k]))
# Moving, then no longer near: stopped where the mesh is, not drifting on at its last velocity.
net.place(moved, np.full_like(nodes, -3.0))
fid = int(net.ids[k])
net.set_near([(np.array([5.0, 5.0, 5.0]), 0.1)], moved, moved)
net.place(moved, np.full_like(nodes, -3.0))
for _ in range(100):
    O.step()
check("a facet that leaves the near ones stops where the mesh is", not net.near[k] and
      np.allclose(np.array(O.bodies[fid].state.pos), moved[net.triangles[k]].mean(axis=0), atol=1e-12)
      and np.array(O.bodies[fid].state.vel).max() == 0, f"({O.bodies[fid].state.pos})")

# The net's node masses in the dashpot: off a fixed facet the dashpot takes the ball's mass (YADE 2023's
# Hertz–Mindlin with en = 0.5 rebounds at 0.35 there); off the facets of a light sheet (m_f ≪ m, so
# m* ≈ m_f) it is weaker by √(m_f/m) and the ball rebounds nearly whole.
def bounce(node_mass):
    O.reset()
    nodes, triangles = cosim_yade.grid_mesh([0, 0, 0], [1.0, 1.0], [8, 8])
    net_material = O.materials.append(yade.FrictMat(young=5e7, poisson=0.0, density=80, frictionAngle=0.0))
    ball_material = O.materials.append(yade.FrictMat(young=1e6, poisson=0.25, density=2600, frictionAngle=0.0))
    net = cosim_yade.FacetInterface(yade, nodes, triangles, net_material, margin=0.02,
                                    node_mass=None if node_mass is None else np.full(len(nodes), node_mass))
    ball = O.bodies.append(yade.utils.sphere((0.43, 0.61, 0.1001), 0.1, material=ball_material, mask=cosim_yade.BODIES))
    O.bodies[ball].state.vel = Vector3(0, 0, -1.0)
    O.engines = cosim_yade.engines(yade, 0.5, (0, 0, 0))
    O.dt = 2e-6
    net.set_near([(np.array(O.bodies[ball].state.pos), 0.1)], nodes, nodes)
    net.place(nodes, np.zeros_like(nodes))
    for _ in range(20000):
        O.step()
        if O.bodies[ball].state.vel[2] > 0 and O.interactions.countReal() == 0:
            break
    moved = max(np.linalg.norm(np.array(O.bodies[int(i)].state.pos) - net.centre[k]) for k, i in enumerate(net.ids) if i >= 0)
    return O.bodies[ball].state.vel[2], moved


e_fixed, _ = bounce(None)
e_sheet, moved = bounce(1e-3)
check("fixed facets: the dashpot takes the ball's mass (rebound 0.35 for en = 0.5)", 0.33 < e_fixed < 0.37, f"({e_fixed:.3f})")
check("sheet facets: the dashpot takes m* of the node mass (rebound near 1)", e_sheet > 0.95, f"({e_sheet:.4f})")
check("sheet facets: blocked, they stay where they are placed", moved < 1e-12, f"({moved:.1e} m)")
sys.stdout.flush()
os._exit(1 if failures else 0)
