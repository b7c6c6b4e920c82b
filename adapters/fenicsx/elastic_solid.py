#!/usr/bin/env python3
"""A linear-elastic body in FEniCSx (Debian's python3-dolfinx 0.5) as a cosim participant. Neumann side: it
reads the force on its interface nodes and writes their displacement; Dirichlet side (dynamic only): it
reads their displacement and writes the force the body exerts there.

Run by cosim (configs/verification/split_{bar,block}_*_fenicsx*.yaml, slab_impact_fenicsx.yaml), which appends
--couple, --name, --out, --quiet:
    python3 adapters/fenicsx/elastic_solid.py (--bar L N --area A | --box LX LY LZ H --poisson NU |
        --mesh FILE.msh --fixed-group NAME --interface-group NAME --poisson NU) --young E --density RHO
        [--mode dynamic --dt DT | --mode static] [--interface-mode neumann|dirichlet] [--fixed-at X0]
        [--interface-at X1] [--probe NAME X Y Z]

The body: a bar of length L in N linear (P1) elements along x, axial stiffness E A (a truss, as
fem_solver's `truss`), fixed at x = X0, its node x = X1 the interface; or a box of linear tetrahedra,
fixed on its face x = X0, its face x = X1 the interface (by default the first and the last); or a gmsh
mesh of linear tetrahedra, clamped on one physical surface, another its interface.
- dynamic: central differences (leapfrog) on the row-summed (lumped) mass, the first kick a half step
  from rest, as fem_solver's explicit analysis; the force read for a window acts over its steps;
- static: K u = f, solved directly (PETSc LU).
Writes OUT/fenicsx.h5 (timeseries/probes, a row a window: time, interface_ux (the interface nodes' mean),
interface_fx, _fy, _fz (their summed force) and the --probe node's displacement, named as fem_solver's
probes) and OUT/summary.yaml (with the body's kinetic and strain energy at the end).
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
    body.add_argument("--mesh", help="a gmsh mesh of linear tetrahedra (.msh) with physical groups")
    ap.add_argument("--fixed-group", default="fixed", help="--mesh: the physical surface clamped")
    ap.add_argument("--interface-group", default="interface", help="--mesh: the physical surface coupled")
    ap.add_argument("--area", type=float, default=0.0, help="the bar's cross-section [m²]")
    ap.add_argument("--poisson", type=float, default=0.0, help="the box's Poisson ratio")
    ap.add_argument("--young", type=float, required=True)
    ap.add_argument("--density", type=float, required=True)
    ap.add_argument("--mode", choices=["dynamic", "static"], default="dynamic")
    ap.add_argument("--interface-mode", choices=["neumann", "dirichlet"], default="neumann",
                    help="neumann: read the interface force, write its displacement; dirichlet: read the "
                         "displacement, write the force the body exerts there")
    ap.add_argument("--dt", type=float, default=0.0, help="time step of the dynamic mode [s]")
    ap.add_argument("--fixed-at", type=float, default=None, help="x of the fixed node or face; default: the first")
    ap.add_argument("--interface-at", type=float, default=None, help="x of the interface node or face; default: the far end")
    ap.add_argument("--probe", nargs=4, metavar=("NAME", "X", "Y", "Z"),
                    help="record the displacement of the node nearest (X, Y, Z) as NAME_ux, NAME_uy, NAME_uz")
    ap.add_argument("--origin", type=float, nargs="+", default=[0.0], help="the bar's first node x, the box's lowest corner")
    ap.add_argument("--couple", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    if args.mode == "dynamic" and not args.dt > 0:
        ap.error("--mode dynamic needs --dt > 0")
    if args.mode == "static" and args.interface_mode == "dirichlet":
        ap.error("--interface-mode dirichlet needs --mode dynamic (a static Dirichlet side is not built)")
    if args.bar and not args.area > 0:
        ap.error("--bar needs --area > 0")
    args.origin = (args.origin + [0.0, 0.0, 0.0])[:3]
    return args


class Body:
    """A body's stiffness matrix K and lumped mass (one value per dof), its fixed dofs, every node's
    position (`coordinates`, 3-D; node i's dofs are block i + c, c < block), and its interface: node
    positions, their dofs by component (−1: none) and, for a surface, triangles over them."""

    def __init__(self, K, mass, fixed, coordinates, block, nodes, dofs, triangles=()):
        from petsc4py import PETSc
        self.PETSc = PETSc
        self.K, self.mass, self.n = K, mass, len(mass)
        self.coordinates, self.block = coordinates, block
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
    return Body(K, mass, [fixed], V.tabulate_dof_coordinates(), 1, np.array([[x[interface], 0.0, 0.0]]),
                np.array([[interface, -1, -1]]))


def solid(domain, fixed_facets, interface_facets, args):
    """Isotropic linear elasticity (σ = λ tr ε I + 2 μ ε) on a mesh of linear tetrahedra, clamped on
    fixed_facets, its interface the nodes of interface_facets with those facets as its triangles."""
    import ufl
    from dolfinx import cpp, fem

    V = fem.VectorFunctionSpace(domain, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    E, nu = args.young, args.poisson
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    def eps(w):
        return ufl.sym(ufl.grad(w))

    def sigma(w):
        return 2 * mu * eps(w) + lam * ufl.tr(eps(w)) * ufl.Identity(3)

    from dolfinx.fem.petsc import assemble_matrix, assemble_vector
    K = assemble_matrix(fem.form(ufl.inner(sigma(u), eps(v)) * ufl.dx))
    K.assemble()
    ones = fem.Constant(domain, np.ones(3))
    mass = assemble_vector(fem.form(args.density * ufl.inner(ones, v) * ufl.dx)).array.copy()
    fdim = domain.topology.dim - 1
    domain.topology.create_connectivity(fdim, domain.topology.dim)
    fixed_nodes = fem.locate_dofs_topological(V, fdim, fixed_facets)
    interface_nodes = fem.locate_dofs_topological(V, fdim, interface_facets)
    coordinates = V.tabulate_dof_coordinates()
    nodes = coordinates[interface_nodes].copy()
    # The interface triangles are its facets' corners, found among the interface nodes by position: the
    # geometry's points and the P1 dofs coincide but are numbered apart.
    corners = domain.geometry.x[cpp.mesh.entities_to_geometry(domain._mesh, fdim, np.asarray(interface_facets, np.int32), False)]
    from scipy.spatial import cKDTree
    distance, triangles = cKDTree(nodes).query(corners.reshape(-1, 3))
    if distance.max() > 1e-9 * np.ptp(coordinates, axis=0).max():
        raise RuntimeError("the interface facets' corners are not all P1 nodes")
    return Body(K, mass, [int(3 * b + c) for b in fixed_nodes for c in range(3)], coordinates, 3, nodes,
                np.array([[3 * b + c for c in range(3)] for b in interface_nodes]), triangles.reshape(-1, 3))


def box(args):
    """A box of linear tetrahedra, clamped on its face x = --fixed-at (default x_min), its face
    x = --interface-at (default x_max) the interface."""
    from mpi4py import MPI
    from dolfinx import mesh

    lx, ly, lz, h = args.box
    lo = np.array(args.origin, dtype=float)
    hi = lo + [lx, ly, lz]
    cells = [max(1, round(length / h)) for length in (lx, ly, lz)]
    domain = mesh.create_box(MPI.COMM_SELF, [lo, hi], cells, mesh.CellType.tetrahedron)
    fdim = domain.topology.dim - 1

    def face(x0):
        return mesh.locate_entities_boundary(domain, fdim, lambda x: np.isclose(x[0], x0))

    return solid(domain, face(args.fixed_at if args.fixed_at is not None else lo[0]),
                 face(args.interface_at if args.interface_at is not None else hi[0]), args)


def gmsh_mesh(args):
    """A gmsh mesh of linear tetrahedra (its volume a physical group), clamped on the physical surface
    --fixed-group, its physical surface --interface-group the interface."""
    import gmsh
    from mpi4py import MPI
    from dolfinx.io import gmshio

    path, fixed_name, interface_name = pathlib.Path(args.mesh), args.fixed_group, args.interface_group
    if not path.is_file():
        raise SystemExit(f"error: --mesh {path}: no such file")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Verbosity", 1)
        # dolfinx 0.5's gmshio.read_from_msh returns an unbound name; model_to_mesh does the work.
        gmsh.merge(str(path))
        groups = {gmsh.model.getPhysicalName(d, t): t for d, t in gmsh.model.getPhysicalGroups(2)}
        for name in (fixed_name, interface_name):
            if name not in groups:
                raise SystemExit(f"error: --mesh {path}: no physical surface '{name}' (it has: {', '.join(sorted(groups))})")
        domain, _, facet_tags = gmshio.model_to_mesh(gmsh.model, MPI.COMM_SELF, 0, gdim=3)
    finally:
        gmsh.finalize()
    if domain.topology.cell_type.name != "tetrahedron":
        raise SystemExit(f"error: --mesh {path}: its cells are {domain.topology.cell_type.name}, not linear tetrahedra")
    return solid(domain, facet_tags.find(groups[fixed_name]), facet_tags.find(groups[interface_name]), args)


def advance(body, state, window, args, f_ext, target=None):
    """One window: static K u = f_ext, or central differences in whole steps of at most --dt under f_ext
    (held over the window). With `target`, the Dirichlet side: the interface dofs move to `target` at the
    window's end, linearly over its steps, as fem_solver's explicit Dirichlet interface: a prescribed dof
    reaches its place each step and the support supplies what its node's inertia and internal force need,
    m (v⁺ − v⁻)/kick + f_int. Returns the steps taken and, Dirichlet, the window mean of minus that
    support force: what the body exerts on the interface (the impulse this side received, handed on)."""
    if args.mode == "static":
        state["u"] = body.solve_static(f_ext)
        return 0, None
    count = substeps(window, args.dt)
    h = window / count
    u, v = state["u"].copy(), state["v"].copy()
    dofs = body.dofs[body.dofs >= 0]
    start, exerted = u[dofs].copy(), np.zeros(len(dofs))
    for k in range(count):
        kick = 0.5 * h if state["first"] else h
        state["first"] = False
        f_int = body.internal(u)
        v0 = v[dofs].copy()
        v += kick * ((f_ext - f_int) / body.mass)
        if target is not None:
            v[dofs] = (start + (target - start) * (k + 1) / count - u[dofs]) / h
            exerted -= (body.mass[dofs] * (v[dofs] - v0) / kick + f_int[dofs]) / count
        v[body.fixed] = 0.0
        u += h * v
        u[body.fixed] = 0.0
    state["u"], state["v"] = u, v
    return count, exerted if target is not None else None


def main():
    args = arguments()
    start = time.perf_counter()
    body = box(args) if args.box else gmsh_mesh(args) if args.mesh else bar(args)
    probe = None
    if args.probe:
        point = np.array([float(c) for c in args.probe[1:]])
        probe = int(np.argmin(np.linalg.norm(body.coordinates - point, axis=1)))
    p = Participant(args.name, args.couple)
    p.add_mesh("interface", body.nodes.ravel().tolist(), body.triangles.ravel().tolist())
    dirichlet = args.interface_mode == "dirichlet"
    p.add_read("interface", "displacement" if dirichlet else "force", 3)
    p.add_write("interface", "force" if dirichlet else "displacement", 3)
    p.initialize()
    # State: u_n, v_{n−1/2}, and whether the first step (a half kick from rest) is still to come.
    state = dict(u=np.zeros(body.n), v=np.zeros(body.n), first=True)
    on = body.dofs >= 0
    interface = body.dofs[on]
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
            data = np.array(p.read("interface", "displacement" if dirichlet else "force")).reshape(-1, 3)
            pass_start = time.perf_counter()
            f_ext = np.zeros(body.n)
            if dirichlet:
                taken, exerted = advance(body, state, w.dt, args, f_ext, target=data[on])
                force = np.zeros_like(data)
                force[on] = exerted
            else:
                force = data
                f_ext[interface] = force[on]
                taken, _ = advance(body, state, w.dt, args, f_ext)
            steps += taken
            displacement = np.where(on, state["u"][np.maximum(body.dofs, 0)], 0.0)
            trial = [w.time + w.dt, float(displacement[:, 0].mean()), *force.sum(axis=0)]
            if probe is not None:
                trial += [state["u"][body.block * probe + c] if c < body.block else 0.0 for c in range(3)]
            if dirichlet:
                p.write("interface", "force", force.ravel().tolist())
            else:
                p.write("interface", "displacement", displacement.ravel().tolist())
            # The pass's own time, which the coupler's summary splits from its waiting (solver_time_NAME).
            p.complete(solver_seconds=time.perf_counter() - pass_start)
        if trial is not None:
            rows.append(trial)
    except CouplingError as e:
        print(f"[fenicsx] error: {e}", file=sys.stderr)
        return 4
    except Exception as e:  # tell the coupler why, then fail
        p.fail(f"fenicsx {args.name}: {e}")
        raise
    # The body's energy at the end (kinetic from the last half-step velocity): what the interface did to it.
    energy = dict(kinetic_energy=float(0.5 * np.sum(body.mass * state["v"] ** 2)),
                  strain_energy=float(0.5 * state["u"] @ body.internal(state["u"])))
    write_results(pathlib.Path(args.out), rows, args.probe[0] if args.probe else None, steps,
                  time.perf_counter() - start, energy)
    return 0


def write_results(out, rows, probe, steps, seconds, energy):
    import h5py
    import yaml
    out.mkdir(parents=True, exist_ok=True)
    with h5py.File(out / "fenicsx.h5", "w") as f:
        g = f.create_group("timeseries/probes")
        columns = ["time", "interface_ux", "interface_fx", "interface_fy", "interface_fz"]
        columns += [f"{probe}_{c}" for c in ("ux", "uy", "uz")] if probe else []
        table = np.array(rows, dtype=float).reshape(-1, len(columns))
        for i, name in enumerate(columns):
            g[name] = table[:, i]
    results = dict(interface_displacement=float(rows[-1][1]) if rows else 0.0, windows=len(rows), steps=steps,
                   wall_seconds=seconds, **energy)
    (out / "summary.yaml").write_text(yaml.safe_dump(dict(scene="fenicsx elastic body", solver="fenicsx", status="ok",
                                                          exit_code=0, results=results), sort_keys=False))


if __name__ == "__main__":
    sys.exit(main())
