"""YADE as a cosim participant: a triangle-mesh interface held as YADE facets.

The coupler sends the interface's node displacement at each window end; the facets follow it over the
window, as dem_solver's own mesh walls do: placed at the window's start, each moving as the rigid body
nearest to its corners' velocities (translation and spin). The facet contact forces go back as nodal
forces, each contact's force split to its facet's three nodes by the barycentric weights of the contact
point: the split keeps the force and, for a point in the facet's plane, its moment. The coupler receives
their mean over the window.

Window repeats restore YADE's state with `O.saveTmp`/`O.loadTmp` (the whole scene, serialised in
memory), and the adapter's own accumulators alongside.

`split_forces`, `grid_mesh` and `node_masses` need no YADE and are tested on their own (tests/unit/adapters). The rest
runs inside `yade`: see rockfall_block.py for a scene that uses it.
"""
import time

import numpy as np

FACETS, BODIES = 2, 3  # collision masks: bodies meet facets (3 & 2) and each other, facets meet no facet


def barycentric(a, b, c, p):
    """Weights (wa, wb, wc), summing to 1, of the projection of p onto the plane of triangle a b c; each
    argument a point (3) or rows of points (m × 3)."""
    a, b, c, p = (np.asarray(x, dtype=float) for x in (a, b, c, p))
    e0, e1, d = b - a, c - a, p - a
    d00, d01, d11 = (e0 * e0).sum(-1), (e0 * e1).sum(-1), (e1 * e1).sum(-1)
    d20, d21 = (d * e0).sum(-1), (d * e1).sum(-1)
    det = d00 * d11 - d01 * d01
    wb = (d11 * d20 - d01 * d21) / det
    wc = (d00 * d21 - d01 * d20) / det
    return 1.0 - wb - wc, wb, wc


def split_forces(corners, points, forces):
    """Forces (m × 3) acting at points (m × 3) of triangles (corners: m × 3 × 3) as nodal forces
    (m × 3 nodes × 3). Each triangle's three sum to its force; their moment about any point equals the
    force's at the point's projection onto the plane. A contact point just off the facet (YADE puts it
    halfway into the overlap) moves along the normal: the moment changes by that offset times the force's
    in-plane part, as in dem_solver. A point a rounding error beyond an edge takes the nearest weights."""
    w = np.clip(np.stack(barycentric(corners[:, 0], corners[:, 1], corners[:, 2], points), axis=-1), 0.0, None)
    w /= w.sum(axis=-1, keepdims=True)
    return w[:, :, None] * np.asarray(forces, dtype=float)[:, None, :]


def split_force(a, b, c, p, f):
    """split_forces for one force: a 3 × 3 array, one row per node."""
    return split_forces(np.array([[a, b, c]], dtype=float), np.array([p], dtype=float), np.array([f], dtype=float))[0]


def node_masses(nodes, triangles, areal_density):
    """A sheet's mass lumped to its nodes, a third of each triangle's to each corner, as dem_solver lumps
    a mesh wall's `areal_density`."""
    x = np.asarray(nodes, dtype=float)[np.asarray(triangles)]
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    mass = np.zeros(len(nodes))
    np.add.at(mass, np.asarray(triangles).ravel(), np.repeat(areal_density * area / 3, 3))
    return mass


def grid_mesh(origin, size, divisions, pattern="alternate"):
    """dem_solver's `walls[i].grid` (pattern right or alternate), node for node and triangle for triangle:
    nodes row by row from the origin, two triangles per cell."""
    nx, ny = divisions
    hx, hy = size[0] / nx, size[1] / ny
    nodes = np.array([[origin[0] + i * hx, origin[1] + j * hy, origin[2]] for j in range(ny + 1) for i in range(nx + 1)])

    def node(i, j):
        return j * (nx + 1) + i

    triangles = []
    for j in range(ny):
        for i in range(nx):
            if pattern == "alternate" and (i + j) % 2 == 1:
                triangles += [(node(i, j), node(i + 1, j), node(i, j + 1)), (node(i + 1, j), node(i + 1, j + 1), node(i, j + 1))]
            else:
                triangles += [(node(i, j), node(i + 1, j), node(i + 1, j + 1)), (node(i, j), node(i + 1, j + 1), node(i, j + 1))]
    return nodes, np.array(triangles, dtype=np.int64)


def engines(yade, restitution, gravity, calc_energy=False):
    """YADE's engine list for spheres against FacetInterface's facets: Hertz–Mindlin with the restitution
    as en and es, no numerical damping. The adapter reaches the collider as O.engines[1] and the contact
    law as O.engines[2].lawDispatcher.functors[0]."""
    return [yade.ForceResetter(),
            yade.InsertionSortCollider([yade.Bo1_Sphere_Aabb(), yade.Bo1_Facet_Aabb()], avoidSelfInteractionMask=FACETS),
            yade.InteractionLoop([yade.Ig2_Facet_Sphere_ScGeom()], [yade.Ip2_FrictMat_FrictMat_MindlinPhys(en=restitution, es=restitution)],
                                 [yade.Law2_ScGeom_MindlinPhys_Mindlin(calcEnergy=calc_energy)]),
            yade.NewtonIntegrator(gravity=yade.Vector3(*gravity), damping=0.0)]


class FacetInterface:
    """The interface mesh as fixed YADE facets, moved by the adapter.

    Only the facets near the bodies are placed (set_near): each placement is a Python call of about ten
    microseconds, and a net of thousands of facets would cost more than the DEM itself. A facet
    is near when its true position or the position it was last given is within `margin` of a body's
    bounding sphere, so a facet left behind can never touch a body where the mesh no longer is.

    A facet becomes a YADE body the first time it is near: far ones carry no force, and every body is
    serialised at each window's checkpoint (O.saveTmp), the adapter's largest cost."""

    def __init__(self, yade, nodes, triangles, material, margin, node_mass=None):
        """node_mass: the sheet's mass at each node. Given, each facet is a dynamic body of its corners'
        mean node mass with its degrees of freedom blocked (YADE's integrator still moves it at its
        velocity): YADE's contact dashpot then sees m* = m m_f/(m + m_f), as dem_solver's `areal_density`
        gives its mesh walls. Without, the facets are fixed and the dashpot sees the sphere's mass alone."""
        self.y = yade
        self.facet_mass = None if node_mass is None else np.asarray(node_mass, dtype=float)[np.asarray(triangles)].mean(axis=1)
        self.reference = np.asarray(nodes, dtype=float)
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.margin = margin
        self.material = material
        self.ids = np.full(len(self.triangles), -1, dtype=np.int64)  # the YADE body of each facet, once made
        self.at = self.reference[self.triangles].copy()  # the corners each facet was last given
        self.centre = self.at.mean(axis=1)
        self.near = np.zeros(len(self.triangles), dtype=bool)
        self.moving = np.zeros(len(self.triangles), dtype=bool)  # given a velocity at the last placement
        self.index = {}  # facet body id → facet
        # Contact points closer than this are one point: the facets of a shared edge, each moving rigidly,
        # part by up to their corners' velocity difference times a window.
        self.point_tolerance = 1e-4
        self.near_ids = []  # the YADE bodies of the near facets, as last placed

    def set_near(self, bodies, start, end):
        """Marks the facets to be moved in this window: near a body's bounding sphere (centre, radius) at
        the window's start or end positions (node arrays), or where they were last placed."""
        corners = [start[self.triangles], end[self.triangles], self.at]
        lo = np.minimum.reduce([c.min(axis=1) for c in corners]) - self.margin
        hi = np.maximum.reduce([c.max(axis=1) for c in corners]) + self.margin
        near = np.zeros(len(self.triangles), dtype=bool)
        for centre, radius in bodies:
            near |= np.all((lo - radius <= centre) & (centre <= hi + radius), axis=1)
        newly = near & ~self.near
        self.near = near
        return bool(newly.any())

    def place(self, nodes, velocity):
        """Puts the near facets at the given node positions, each moving as the rigid body nearest to its
        corners' velocities (translation and spin, least squares): YADE's integrator then carries it
        through the window, so a window needs one placement, at its start. Within the window a facet
        follows the net's tilting, not its stretching. Once per window also because each assignment of a
        facet's vertices keeps about 0.4 kB in YADE 2023 (measured over 3,000 assignments). A facet that
        is no longer near is put where the mesh is and stopped: it would go on moving."""
        stopped = np.flatnonzero(self.moving & ~self.near)
        self._put(np.flatnonzero(self.near), nodes, velocity)
        self._put(stopped, nodes, np.zeros_like(nodes))
        self.moving = self.near.copy()
        self.near_ids = self.ids[self.near].tolist()

    def _put(self, facets, nodes, velocity):
        y = self.y
        V = y.Vector3
        bodies = y.O.bodies
        x = nodes[self.triangles[facets]]  # facets × 3 corners × 3
        c = x.mean(axis=1)
        self.at[facets] = x
        self.centre[facets] = c
        v = velocity[self.triangles[facets]]
        vc = v.mean(axis=1)
        # The spin ω minimising Σ |ω × r_i − (v_i − v_c)|²: (Σ |r_i|² I − r_i r_iᵀ) ω = Σ r_i × (v_i − v_c).
        r, d = x - c[:, None, :], v - vc[:, None, :]
        A = np.einsum("fi,jk->fjk", (r * r).sum(axis=2), np.eye(3)) - np.einsum("fij,fik->fjk", r, r)
        spin = np.linalg.solve(A, np.cross(r, d).sum(axis=1)[..., None])[..., 0] if len(facets) else vc
        # Plain floats: building Vector3 from numpy scalars costs several times more.
        for k, xk, centre, corners, vk, wk in zip(facets.tolist(), x.tolist(), c.tolist(), r.tolist(), vc.tolist(),
                                                  spin.tolist()):
            if self.ids[k] < 0:
                self.ids[k] = self.make(k, xk)
                self.index[int(self.ids[k])] = k
            b = bodies[int(self.ids[k])]
            b.state.pos = V(*centre)
            b.state.ori = y.Quaternion.Identity
            b.shape.vertices = [V(*corners[0]), V(*corners[1]), V(*corners[2])]
            b.state.vel = V(*vk)
            b.state.angVel = V(*wk)

    def make(self, k, corners):
        sheet = self.facet_mass is not None
        # Mask FACETS, with the collider's avoidSelfInteractionMask = FACETS (engines()): facets never pair with
        # each other (adjacent facets' bounds overlap: 2,000 facets would give the contact loop 90,000 idle pairs).
        b = self.y.utils.facet([tuple(p) for p in corners], fixed=not sheet, mask=FACETS, material=self.material, wire=False)
        if sheet:
            # YADE takes a body with all six degrees of freedom blocked as not dynamic, and its dashpot then
            # ignores the body's mass: the spin about z stays free, held by an inertia no torque can move.
            b.state.blockedDOFs = "xyzXY"
            b.state.mass = float(self.facet_mass[k])
            b.state.inertia = self.y.Vector3(1e30, 1e30, 1e30)
        return self.y.O.bodies.append(b)

    def nodal_forces(self, spheres):
        """The contact forces on the facets from the given spheres as nodal forces (nodes × 3), the number of
        contacts, and the number of distinct (sphere, contact point) pairs among them (points within
        point_tolerance are one): YADE's facets that share the node or edge a sphere touches each make a
        contact there, at the same point. Read from the interactions of the spheres or of the near facets,
        whichever are fewer (one sphere for c1, 1,331 for c5 against about a hundred facets)."""
        f = np.zeros_like(self.reference)
        points = {}
        bodies, interactions = self.y.O.bodies, self.y.O.interactions
        facet = self.index
        owners = spheres if len(spheres) <= len(self.near_ids) else self.near_ids
        rows = []  # (facet, contact point, force on the facet)
        for owner in owners:
            for i in interactions.withBody(owner):
                if not i.isReal:
                    continue
                fid = i.id1 if i.id1 in facet else i.id2
                k = facet.get(fid)
                if k is None:
                    continue
                sphere = i.id2 if fid == i.id1 else i.id1
                force = i.phys.normalForce + i.phys.shearForce  # on id2; the facet is id1 (Ig2_Facet_Sphere)
                if i.id1 == fid:
                    force = -force
                p = i.geom.contactPoint
                # The contact point in the frame the facet was placed in: undo its motion since.
                st = bodies[fid].state
                local = tuple(st.ori.conjugate() * (p - st.pos))
                rows.append((k, fid, local, tuple(force)))
                points.setdefault(sphere, []).append(tuple(p))
        if rows:
            k = np.array([r[0] for r in rows])
            nodal = split_forces(self.at[k], self.centre[k] + np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
            np.add.at(f, self.triangles[k].ravel(), nodal.reshape(-1, 3))
        contacts = len(rows)
        return f, contacts, sum(distinct(ps, self.point_tolerance) for ps in points.values())

    def state(self):
        """What a window repeat restores besides YADE's scene."""
        return self.at.copy(), self.centre.copy(), self.near.copy(), self.ids.copy(), self.moving.copy()

    def restore(self, state):
        self.at, self.centre, self.near, self.ids, self.moving = (a.copy() for a in state)
        self.index = {int(fid): k for k, fid in enumerate(self.ids) if fid >= 0}
        self.near_ids = self.ids[self.near].tolist()

    def made(self):
        """How many facets are YADE bodies."""
        return int((self.ids >= 0).sum())


def distinct(points, tolerance):
    """How many of the points stand apart by more than tolerance from every one counted before them."""
    kept = []
    for p in points:
        if all(max(abs(a - b) for a, b in zip(p, q)) > tolerance for q in kept):
            kept.append(p)
    return len(kept)


class Stopwatch:
    def __init__(self):
        self.seconds = 0.0

    def __enter__(self):
        self.start = time.perf_counter()

    def __exit__(self, *args):
        self.seconds += time.perf_counter() - self.start
