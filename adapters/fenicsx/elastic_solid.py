#!/usr/bin/env python3
"""A linear-elastic body in FEniCSx (Debian's python3-dolfinx 0.5) as a cosim participant, Neumann side:
it reads the force on its interface nodes and writes their displacement.

Run by cosim (configs/verification/split_{bar,block}_*_fenicsx.yaml), which appends --couple, --name, --out,
--quiet:
    python3 adapters/fenicsx/elastic_solid.py (--bar L N --area A | --box LX LY LZ H --poisson NU)
        --young E --density RHO [--mode dynamic --dt DT | --mode static] [--fixed-at X0] [--interface-at X1]

The body: a bar of length L in N linear (P1) elements along x, axial stiffness E A (a truss, as
fem_solver's `truss`), fixed at x = X0, its node x = X1 the interface; or a box of linear tetrahedra,
fixed on its face x = X0, its face x = X1 the interface (by default the first and the last).
- dynamic: central differences (leapfrog) on the row-summed (lumped) mass, the first kick a half step
  from rest, as fem_solver's explicit analysis; the force read for a window acts over its steps;
- static: K u = f, solved directly (PETSc LU).
Writes OUT/fenicsx.h5 (timeseries/probes: time, interface_ux (the interface nodes' mean), interface_fx
(their summed force), as fem_solver's probes) and OUT/summary.yaml.
"""
import argparse
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent / "coupler" / "python"))
from cosim_participant import CouplingError, Participant, substeps  # noqa: E402


def arguments():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    body = ap.add_mutually_exclusive_group(required=True)
    body.add_argument("--bar", nargs=2, metavar=("L", "N"), help="a bar: length [m] and number of elements")
    body.add_argument("--box", nargs=4, type=float, metavar=("LX", "LY", "LZ", "H"),
                      help="a box of linear tetrahedra, element size about H [m], from --origin")
    ap.add_argument("--area", type=float, default=0.0, help="the bar's cross-section [m²]")
    ap.add_argument("--poisson", type=float, default=0.0, help="the box's Poisson ratio")
    ap.add_argument("--young", type=float, required=True)
    ap.add_argument("--density", type=float, required=True)
    ap.add_argument("--mode", choices=["dynamic", "static"], default="dynamic")
    ap.add_argument("--dt", type=float, default=0.0, help="time step of the dynamic mode [s]")
    ap.add_argument("--fixed-at", type=float, default=None, help="x of the fixed node or face; default: the first")
    ap.add_argument("--interface-at", type=float, default=None, help="x of the interface node or face; default: the far end")
    ap.add_argument("--origin", type=float, nargs="+", default=[0.0], help="the bar's first node x, the box's lowest corner")
    ap.add_argument("--couple", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    if args.mode == "dynamic" and not args.dt > 0:
        ap.error("--mode dynamic needs --dt > 0")
    if args.bar and not args.area > 0:
        ap.error("--bar needs --area > 0")
    args.origin = (args.origin + [0.0, 0.0, 0.0])[:3]
    return args


class Body:
    """A body's stiffness matrix K and lumped mass (one value per dof), its fixed dofs, and its interface:
    node positions (3-D), their dofs by component (−1: none) and, for a surface, triangles over them."""

    def __init__(self, K, mass, fixed, nodes, dofs, triangles=()):
        from petsc4py import PETSc
        self.PETSc = PETSc
        self.K, self.mass, self.n = K, mass, len(mass)
        self.fixed, self.nodes, self.dofs = fixed, nodes, dofs
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self._u, self._f = K.createVecRight(), K.createVecLeft()
        self._ksp = None

    def internal(self, u):
        self._u.array[:] = u
        self.K.mult(self._u, self._f)
        return self._f.array.copy()

    def solve_static(self, f):
        """K u = f with the fixed dofs held at zero; K factored once (LU), on the first solve."""
        if self._ksp is None:
            K = self.K.copy()
            K.zeroRowsColumns(self.fixed, 1.0)
            self._ksp = self.PETSc.KSP().create(self.PETSc.COMM_SELF)
            self._ksp.setOperators(K)
            self._ksp.setType("preonly")
            self._ksp.getPC().setType("lu")
        rhs = self.K.createVecLeft()
        rhs.array[:] = f
        rhs.array[self.fixed] = 0.0
        u = self.K.createVecRight()
        self._ksp.solve(rhs, u)
        return u.array.copy()


def bar(args):
    """A bar along x of P1 elements, axial stiffness E A, fixed at --fixed-at (default its first node),
    its interface the node at --interface-at (default its far end), moving along x only."""
    from mpi4py import MPI
    import ufl
    from dolfinx import fem, mesh
    from dolfinx.fem.petsc import assemble_matrix, assemble_vector

    length, n = float(args.bar[0]), int(args.bar[1])
    x0 = args.origin[0]
    domain = mesh.create_interval(MPI.COMM_SELF, n, [x0, x0 + length])
    V = fem.FunctionSpace(domain, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    EA, rhoA = args.young * args.area, args.density * args.area
    K = assemble_matrix(fem.form(EA * ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
    K.assemble()
    # Row sums of the consistent mass: ∫ ρA v dx, the lumped mass of P1 elements.
    mass = assemble_vector(fem.form(rhoA * v * ufl.dx)).array.copy()
    x = V.tabulate_dof_coordinates()[:, 0].copy()
    fixed = int(np.argmin(np.abs(x - (args.fixed_at if args.fixed_at is not None else x0))))
    interface = int(np.argmin(np.abs(x - (args.interface_at if args.interface_at is not None else x0 + length))))
    return Body(K, mass, [fixed], np.array([[x[interface], 0.0, 0.0]]), np.array([[interface, -1, -1]]))


def box(args):
    """A box of linear tetrahedra, isotropic linear elasticity (σ = λ tr ε I + 2 μ ε), fixed on its face
    x = --fixed-at (default x_min), its face x = --interface-at (default x_max) the interface."""
    from mpi4py import MPI
    import ufl
    from dolfinx import fem, mesh
    from dolfinx.fem.petsc import assemble_matrix, assemble_vector

    lx, ly, lz, h = args.box
    lo = np.array(args.origin, dtype=float)
    hi = lo + [lx, ly, lz]
    cells = [max(1, round(length / h)) for length in (lx, ly, lz)]
    domain = mesh.create_box(MPI.COMM_SELF, [lo, hi], cells, mesh.CellType.tetrahedron)
    V = fem.VectorFunctionSpace(domain, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    E, nu = args.young, args.poisson
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    def eps(w):
        return ufl.sym(ufl.grad(w))

    def sigma(w):
        return 2 * mu * eps(w) + lam * ufl.tr(eps(w)) * ufl.Identity(3)

    K = assemble_matrix(fem.form(ufl.inner(sigma(u), eps(v)) * ufl.dx))
    K.assemble()
    ones = fem.Constant(domain, np.ones(3))
    mass = assemble_vector(fem.form(args.density * ufl.inner(ones, v) * ufl.dx)).array.copy()
    fdim = domain.topology.dim - 1

    def face(x0):
        facets = mesh.locate_entities_boundary(domain, fdim, lambda x: np.isclose(x[0], x0))
        return fem.locate_dofs_topological(V, fdim, facets)

    fixed_nodes = face(args.fixed_at if args.fixed_at is not None else lo[0])
    interface_nodes = face(args.interface_at if args.interface_at is not None else hi[0])
    nodes = V.tabulate_dof_coordinates()[interface_nodes].copy()
    # The interface face's triangles over these nodes: the box's face is a grid of (ny + 1) × (nz + 1)
    # nodes, two triangles a square (the coupler maps through any triangulation of the same points).
    ny, nz = cells[1], cells[2]
    at = {(int(round((y - lo[1]) / ly * ny)), int(round((z - lo[2]) / lz * nz))): i for i, (_, y, z) in enumerate(nodes)}
    triangles = [t for j in range(ny) for k in range(nz) for t in
                 ((at[j, k], at[j + 1, k], at[j + 1, k + 1]), (at[j, k], at[j + 1, k + 1], at[j, k + 1]))]
    return Body(K, mass, [int(3 * b + c) for b in fixed_nodes for c in range(3)], nodes,
                np.array([[3 * b + c for c in range(3)] for b in interface_nodes]), triangles)


def main():
    args = arguments()
    start = time.perf_counter()
    body = box(args) if args.box else bar(args)
    p = Participant(args.name, args.couple)
    p.add_mesh("interface", body.nodes.ravel().tolist(), body.triangles.ravel().tolist())
    p.add_read("interface", "force", 3)
    p.add_write("interface", "displacement", 3)
    p.initialize()
    # State: u_n, v_{n−1/2}, and whether the first step (a half kick from rest) is still to come.
    state = dict(u=np.zeros(body.n), v=np.zeros(body.n), first=True)
    saved = None
    trial = None
    current, rows, steps = None, [], 0
    try:
        while (w := p.next_window()) is not None:
            if trial is not None and w.index != current:
                rows.append(trial)
            current = w.index
            if w.restore_checkpoint:
                state = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in saved.items()}
            if w.save_checkpoint:
                saved = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in state.items()}
            force = np.array(p.read("interface", "force")).reshape(-1, 3)
            f_ext = np.zeros(body.n)
            on = body.dofs >= 0
            f_ext[body.dofs[on]] = force[on]
            if args.mode == "static":
                state["u"] = body.solve_static(f_ext)
            else:
                count = substeps(w.dt, args.dt)
                h = w.dt / count
                u, v = state["u"].copy(), state["v"].copy()
                for _ in range(count):
                    a = (f_ext - body.internal(u)) / body.mass
                    v += (0.5 * h if state["first"] else h) * a
                    state["first"] = False
                    v[body.fixed] = 0.0
                    u += h * v
                    u[body.fixed] = 0.0
                steps += count
                state["u"], state["v"] = u, v
            displacement = np.where(on, state["u"][np.maximum(body.dofs, 0)], 0.0)
            ux = float(displacement[:, 0].mean())
            trial = (w.time + w.dt, ux, float(force[:, 0].sum()))
            p.write("interface", "displacement", displacement.ravel().tolist())
            p.complete()
        if trial is not None:
            rows.append(trial)
    except CouplingError as e:
        print(f"[fenicsx] error: {e}", file=sys.stderr)
        return 4
    except Exception as e:  # tell the coupler why, then fail
        p.fail(f"fenicsx {args.name}: {e}")
        raise
    write_results(pathlib.Path(args.out), rows, steps, time.perf_counter() - start)
    return 0


def write_results(out, rows, steps, seconds):
    import h5py
    import yaml
    out.mkdir(parents=True, exist_ok=True)
    with h5py.File(out / "fenicsx.h5", "w") as f:
        g = f.create_group("timeseries/probes")
        g["time"] = np.array([r[0] for r in rows])
        g["interface_ux"] = np.array([r[1] for r in rows])
        g["interface_fx"] = np.array([r[2] for r in rows])
    results = dict(interface_displacement=float(rows[-1][1]) if rows else 0.0, windows=len(rows), steps=steps,
                   wall_seconds=seconds)
    (out / "summary.yaml").write_text(yaml.safe_dump(dict(scene="fenicsx elastic body", solver="fenicsx", status="ok",
                                                          exit_code=0, results=results), sort_keys=False))


if __name__ == "__main__":
    sys.exit(main())
