#!/usr/bin/env python3
"""Reference participant: a lumped mass m on a linear spring k, on one interface node, in pure Python.

Run with (cosim appends the last four arguments):
    python3 coupler/python/mass_spring.py --k 4e6 [--m 0] [--x 5 0 0] --couple ENDPOINT --name NAME --out DIR

It reads the force F on its interface node and writes the node's displacement: statically (m = 0)
u = F/k; dynamically m ü + k u = F(t), integrated exactly over each window for the window's constant
force (checkpoints saved and restored as the protocol asks). Only the x component moves.

--diverge-above DT makes it a participant that fails on windows longer than DT s, to test the coupler's
adaptive windows: with --diverge-as residual its answer is off by a factor 10^(3(k+1)) at iteration k,
as an unstable interface would be; with --diverge-as solver its own solver reports a divergence (a RESULT
flagged diverged: it offers retries).
"""
import argparse
import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from cosim_participant import CouplingError, Participant  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=float, required=True, help="spring stiffness [N/m]")
    ap.add_argument("--m", type=float, default=0.0, help="mass [kg] (0: static)")
    ap.add_argument("--x", type=float, nargs=3, default=[0.0, 0.0, 0.0], help="interface node position [m]")
    ap.add_argument("--diverge-above", type=float, default=math.inf, help="windows longer than this diverge [s]")
    ap.add_argument("--diverge-as", choices=["residual", "solver"], default="residual")
    ap.add_argument("--couple", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()

    p = Participant(args.name, args.couple)
    p.add_mesh("interface", args.x)
    p.add_read("interface", "force", 3)
    p.add_write("interface", "displacement", 3)
    p.initialize(retries=args.diverge_as == "solver")
    u, v = 0.0, 0.0
    saved = (u, v)
    history = []
    diverged = False
    try:
        while (w := p.next_window()) is not None:
            if diverged and not w.restore_checkpoint:
                raise RuntimeError("after a diverged RESULT the coupler must repeat the window from its start")
            diverged = False
            if w.restore_checkpoint:
                u, v = saved
            if w.save_checkpoint:
                saved = (u, v)
            f = p.read("interface", "force")[0]
            if args.m <= 0:
                u = f / args.k
            else:  # exact solution of m ü + k u = f over dt from (u, v)
                omega = math.sqrt(args.k / args.m)
                ue = f / args.k
                c, s = math.cos(omega * w.dt), math.sin(omega * w.dt)
                u, v = ue + (u - ue) * c + v / omega * s, -(u - ue) * omega * s + v * c
            history.append((w.time + w.dt, u, f))
            too_long = w.dt > args.diverge_above * (1 + 1e-12)
            if too_long and args.diverge_as == "solver":
                if not p.retries:
                    raise RuntimeError(f"the spring diverged in a window of {w.dt} s")
                p.diverged(f"the spring diverged in a window of {w.dt} s (longer than {args.diverge_above} s)")
                diverged = True
                continue
            answer = u * 10.0 ** (3 * (w.iteration + 1)) if too_long else u
            p.write("interface", "displacement", [answer, 0.0, 0.0])
            p.complete()
    except CouplingError as e:  # the coupler stopped the run or is gone: exit 4, like every participant
        print(f"[mass_spring] error: {e}", file=sys.stderr)
        return 4
    except Exception as e:  # tell the coupler why, then fail
        p.fail(f"mass_spring {args.name}: {e}")
        raise
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.yaml").write_text(f"scene: mass_spring\nstatus: ok\nexit_code: 0\nresults:\n  displacement: {u!r}\n"
                                      f"  force: {history[-1][2] if history else 0.0!r}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
