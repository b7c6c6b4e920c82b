"""The rockfall block in YADE, coupled to the net through cosim: dem_solver's side of configs/rockfall/cN.yaml.

Run by cosim (configs/rockfall/c1_yade.yaml, c2_yade.yaml), which appends --couple, --name, --out, --quiet:
    yade -n -x adapters/yade/rockfall_block.py SCENE.yaml --cluster FILE --position X Y Z [options]

It builds the scene from dem_solver's own block scene (SCENE.yaml: materials, the concrete–net
interaction, the block's mass and velocity, the net's grid, gravity, dt, end time), so that the two
DEM sides start from the same description:
- the block: one sphere (c1) or a YADE clump of the cluster file's spheres, with the cluster's mass and
  inertia;
- the net: YADE facets on dem_solver's grid, node for node, moved by the coupler, of the net's node
  masses (`areal_density`; see --rigid-net);
- contacts: YADE's Hertz–Mindlin (Ip2_FrictMat_FrictMat_MindlinPhys with the restitution as en and es,
  Law2_ScGeom_MindlinPhys_Mindlin), Coulomb friction, no numerical damping.

Options that remove, one at a time, the causes of differences from dem_solver (docs/validation/external_codes.md):
    --restitution E     both restitutions (normal and tangential) instead of the scene's
    --rigid-net         fixed facets: the contact dashpot sees the block's mass alone (YADE's usual wall),
                        not the net's node masses of the scene's `areal_density`
    --match-stiffness   both Young moduli × √(3/2), so that a sphere on a facet has dem_solver's Hertz
                        stiffness (YADE takes the facet's radius as twice the sphere's)
Writes OUT/dem.h5 (timeseries/body_0 and timeseries/energy, as dem_solver does) and OUT/summary.yaml.
"""
import argparse
import math
import os
import pathlib
import resource
import sys
import time
import traceback

import numpy as np
import yaml

HERE = pathlib.Path(sys.argv[0]).resolve().parent  # under `yade -x`, __file__ is yade's own
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent.parent / "coupler" / "python"))
import cosim_yade  # noqa: E402
from cosim_participant import CouplingError, Participant, substeps  # noqa: E402

import yade  # noqa: E402
from yade import O, Vector3  # noqa: E402


def arguments():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="dem_solver's block scene (its materials, interaction, cluster, grid wall, dt)")
    ap.add_argument("--cluster", required=True, help="cluster file (spheres, inertia per mass)")
    ap.add_argument("--position", type=float, nargs=3, required=True)
    ap.add_argument("--restitution", type=float, default=None)
    ap.add_argument("--match-stiffness", action="store_true")
    ap.add_argument("--rigid-net", action="store_true")
    ap.add_argument("--couple", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--threads", type=int, default=1, help="ignored: YADE takes its threads as `yade -j N`")
    return ap.parse_args()


class Scene:
    """The YADE scene built from the block scene's keys."""

    def __init__(self, args):
        path = pathlib.Path(args.scene)
        s = yaml.safe_load(path.read_text())
        self.dt = float(s["dt"])
        self.gravity = np.array(s.get("gravity", [0, 0, 0]), dtype=float)
        law = s["interactions"][0]
        if law.get("law") != "hertz_mindlin":
            raise ValueError(f"{path}: interactions[0].law: the adapter builds hertz_mindlin, the scene has {law.get('law')}")
        e = float(args.restitution if args.restitution is not None else law.get("restitution", 1.0))
        mu = float(law.get("friction", 0.0))
        block_entry, wall = s["clusters"][0], s["walls"][0]
        m_block, m_net = s["materials"][block_entry["material"]], s["materials"][wall["material"]]
        E_block, E_net = float(m_block["young_modulus"]), float(m_net["young_modulus"])
        if args.match_stiffness:
            # YADE's facet contact takes R* = (2r · r)/(2r + r) = 2r/3; dem_solver's flat wall R* = r.
            # Hertz stiffness ∝ E*√R*, E* = 1/((1−ν_b²)/E_b + (1−ν_n²)/E_n): both moduli × √(3/2) restore it
            # (the block's modulus dominates E*: the net's alone cannot).
            E_block, E_net = E_block * math.sqrt(1.5), E_net * math.sqrt(1.5)
        self.restitution, self.net_young, self.block_young = e, E_net, E_block
        concrete = O.materials.append(yade.FrictMat(young=E_block, poisson=float(m_block.get("poisson_ratio", 0.25)),
                                                    density=float(m_block["density"]), frictionAngle=math.atan(mu)))
        net = O.materials.append(yade.FrictMat(young=E_net, poisson=float(m_net.get("poisson_ratio", 0.25)),
                                               density=float(m_net["density"]), frictionAngle=math.atan(mu)))
        cluster = yaml.safe_load((path.parent / args.cluster).read_text())  # relative to the scene, as dem_solver reads it
        self.mass = float(block_entry["mass"])
        ipm = np.array(cluster["shape"]["inertia_per_mass"], dtype=float)
        centre = np.array(args.position, dtype=float)
        spheres = [yade.utils.sphere(tuple(centre + np.array(sp[:3])), sp[3], material=concrete, mask=cosim_yade.BODIES)
                   for sp in cluster["spheres"]]
        if len(spheres) == 1:
            self.block = O.bodies.append(spheres[0])
            self.spheres = [self.block]
        else:
            self.block, self.spheres = O.bodies.appendClumped(spheres)
        st = O.bodies[self.block].state
        st.mass = self.mass
        st.inertia = Vector3(*(np.diag(ipm) * self.mass))
        st.vel = Vector3(*block_entry.get("velocity", [0, 0, 0]))
        # The block's bounding sphere about its centre, for the facets near it.
        self.reach = max(np.linalg.norm(sp[:3]) + sp[3] for sp in cluster["spheres"])
        g = wall["grid"]
        self.nodes, self.triangles = cosim_yade.grid_mesh(g["origin"], g["size"], g["divisions"], g.get("pattern", "alternate"))
        # The net's node masses in the contact dashpot, as dem_solver's `areal_density` (docs/validation/external_codes.md).
        density = wall.get("areal_density")
        node_mass = None if density is None or args.rigid_net else cosim_yade.node_masses(self.nodes, self.triangles, float(density))
        self.net = cosim_yade.FacetInterface(yade, self.nodes, self.triangles, net, margin=0.05, node_mass=node_mass)
        O.engines = cosim_yade.engines(yade, e, self.gravity, calc_energy=True)
        O.dt = self.dt
        O.trackEnergy = True
        self.dissipated_base, self.saved = (0.0, 0.0), None

    def law(self):  # looked up each time: O.loadTmp replaces the engines
        return O.engines[2].lawDispatcher.functors[0]

    def sample(self):
        """The block's state and energies, as dem_solver's series names them."""
        st = O.bodies[self.block].state
        x, v, w = np.array(st.pos), np.array(st.vel), np.array(st.angVel)
        w_local = np.array(st.ori.conjugate() * st.angVel)
        kinetic = 0.5 * self.mass * v @ v + 0.5 * float(np.array(st.inertia) @ (w_local ** 2))
        law = self.law()
        damping, friction = self.dissipated()
        return dict(x=x, v=v, w=w, kinetic=kinetic, potential=-self.mass * float(self.gravity @ x),
                    elastic=float(law.normElastEnergy()) + float(law.shearEnergy), damping=damping, friction=friction)

    # The law's dissipation sums are not part of a saved scene: O.loadTmp sets them to zero. The adapter
    # keeps what they held at the window's start.
    def dissipated(self):
        law = self.law()
        return (self.dissipated_base[0] + float(law.normDampDissip + law.shearDampDissip),
                self.dissipated_base[1] + float(law.frictionDissipation))

    def save(self):
        O.saveTmp("cosim")
        self.saved = (self.net.state(), self.dissipated())

    def restore(self):
        O.loadTmp("cosim")
        O.engines[1].doSort = True  # the restored collider re-sorts its bounds before the first step
        self.net.restore(self.saved[0])
        self.dissipated_base = self.saved[1]


def main():
    args = arguments()
    scene = Scene(args)
    n_nodes = len(scene.nodes)
    p = Participant(args.name, args.couple)
    p.add_mesh("interface", scene.nodes.ravel().tolist(), scene.triangles.ravel().tolist())
    p.add_read("interface", "displacement", 3)
    p.add_write("interface", "force", 3)
    p.initialize()
    yade_time, adapter_time, checkpoint_time = cosim_yade.Stopwatch(), cosim_yade.Stopwatch(), cosim_yade.Stopwatch()
    # What a window's last iteration leaves, committed when the next window starts (as libcosim's loop).
    committed = dict(u=np.zeros((n_nodes, 3)), wall_work=0.0)
    trial, rows = None, []
    current, windows, iterations, steps = None, 0, 0, 0
    wall_start = time.perf_counter()

    def commit(t):
        nonlocal windows
        committed.update(u=t["u"], wall_work=t["wall_work"])
        rows.append(t["row"])
        windows += 1
        if not args.quiet and windows % 250 == 0:
            print(f"[yade] t = {t['row']['time']:.4f} s, {windows} windows, {iterations} iterations", flush=True)

    try:
        while (w := p.next_window()) is not None:
            if trial is not None and w.index != current:
                commit(trial)
            current = w.index
            with checkpoint_time:
                if w.restore_checkpoint:
                    scene.restore()
                if w.save_checkpoint:
                    scene.save()
            u_end = np.array(p.read("interface", "displacement")).reshape(n_nodes, 3)
            pass_start = time.perf_counter()
            u_start = committed["u"]
            n = substeps(w.dt, scene.dt)
            h = w.dt / n
            O.dt = h
            rate = (u_end - u_start) / w.dt
            with adapter_time:
                centre = np.array(O.bodies[scene.block].state.pos)
                reach = scene.reach + np.linalg.norm(np.array(O.bodies[scene.block].state.vel)) * w.dt
                if scene.net.set_near([(centre, reach)], scene.nodes + u_start, scene.nodes + u_end):
                    O.engines[1].doSort = True  # facets placed far from where the collider last saw them
            mean = np.zeros((n_nodes, 3))
            work, contacts, points = 0.0, 0, 0
            with adapter_time:
                scene.net.place(scene.nodes + u_start, rate)
            for s in range(n):
                with yade_time:
                    O.step()
                with adapter_time:
                    f, contacts, points = scene.net.nodal_forces(scene.spheres)
                mean += f / n
                # The net's nodes move rate·h under f: the work the net does on the block.
                work -= float(np.sum(f * rate)) * h
            steps += n
            iterations += 1
            state = scene.sample()
            force_on_block = -f.sum(axis=0)
            row = dict(time=w.time + w.dt, contacts=contacts, contact_points=points,
                       fx=force_on_block[0], fy=force_on_block[1], fz=force_on_block[2],
                       x=state["x"][0], y=state["x"][1], z=state["x"][2], vx=state["v"][0], vy=state["v"][1], vz=state["v"][2],
                       wx=state["w"][0], wy=state["w"][1], wz=state["w"][2], kinetic=state["kinetic"], potential=state["potential"],
                       elastic=state["elastic"], damping=state["damping"], friction=state["friction"],
                       wall_work=committed["wall_work"] + work)
            trial = dict(u=u_end, wall_work=committed["wall_work"] + work, row=row)
            p.write("interface", "force", mean.ravel().tolist())
            # The pass's own time, which the coupler's summary splits from its waiting (solver_time_dem).
            p.complete(solver_seconds=time.perf_counter() - pass_start)
        if trial is not None:
            commit(trial)
    except CouplingError as e:
        print(f"[yade] error: {e}", file=sys.stderr)
        code = 4
    except Exception as e:  # tell the coupler why, then fail
        p.fail(f"yade {args.name}: {e}")
        traceback.print_exc()
        code = 1
    else:
        code = 0
    # The committed windows are written however the run ended.
    write_results(pathlib.Path(args.out), rows, code, dict(
        windows=windows, iterations=iterations, steps=steps, wall_seconds=time.perf_counter() - wall_start,
        yade_seconds=yade_time.seconds, adapter_seconds=adapter_time.seconds, checkpoint_seconds=checkpoint_time.seconds,
        restitution=scene.restitution, block_young_modulus=scene.block_young, net_young_modulus=scene.net_young, facets=scene.net.made(),
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))
    return code


def write_results(out, rows, code, results):
    import h5py
    out.mkdir(parents=True, exist_ok=True)
    body = ["time", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz", "contacts", "contact_points"]
    with h5py.File(out / "dem.h5", "w") as f:
        g = f.create_group("timeseries/body_0")
        for k in body:
            g[k] = np.array([r[k] for r in rows], dtype=np.int64 if k.startswith("contact") else float)
        e = f.create_group("timeseries/energy")
        e["time"] = np.array([r["time"] for r in rows])
        for k in ["kinetic", "potential", "elastic", "damping", "friction", "wall_work"]:
            e[k] = np.array([r[k] for r in rows])
        for k in ["cundall", "external_work"]:
            e[k] = np.zeros(len(rows))
        first = rows[0] if rows else {}
        e["residual"] = np.array([(r["kinetic"] + r["potential"] + r["elastic"] + r["damping"] + r["friction"] - r["wall_work"])
                                  - (first["kinetic"] + first["potential"] + first["elastic"] + first["damping"] + first["friction"]
                                     - first["wall_work"]) for r in rows])
    summary = dict(scene="yade rockfall block", solver="yade", status="ok" if code == 0 else "failed", exit_code=code,
                   results={k: (float(v) if isinstance(v, (float, np.floating)) else int(v)) for k, v in results.items()})
    (out / "summary.yaml").write_text(yaml.safe_dump(summary, sort_keys=False))


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
