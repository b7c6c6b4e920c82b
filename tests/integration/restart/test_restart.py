#!/usr/bin/env python3
"""A coupled run killed and restarted gives the uninterrupted run's results, bit for bit (issue 28).

Usage:  test_restart.py BUILD_BIN_DIR OUT [--end-time T] [--interval N] [--scene FILE]

The rockfall c2 scene (DEM block on the FEM net, implicit IQN-ILS; one thread each, so deterministic),
shortened to T with an on-disk checkpoint every N windows:
  1. run through (A);
  2. run again (B), SIGKILL the coupler as soon as its first checkpoint is on disk, and check that its
     participants end on their own (they watch the coupler) and no process of B is left;
  3. `cosim run … --out B --restart`; every summary result and every HDF5 dataset of B equals A's
     (tools/compare_runs.py --rtol 0: bit for bit; wall-clock quantities left out);
  4. a damaged checkpoint is refused with exit 2 and a message naming the file, a missing one too;
  5. the FEM–FEM split bar under explicit parallel, explicit serial and implicit Aitken, and the lattice–FEM
     prism (cracking after the checkpoint), killed after their first checkpoint: each says it restarted from
     the window of the killed run's last logged checkpoint, before its last window, and equals its
     uninterrupted run bit for bit;
  6. each solver alone (output.checkpoint_interval, the lattice's checkpoint_every; one thread, the lattice two): a DEM
     pour, two rigid clusters colliding (the neighbour list's per-body reach, built from the scene, kept
     over the restart), the Hertz impact, the membrane vibration (its step following the stable step), the FEM net (its
     static start from the cache) and a lattice tension test (cracking, the coarse space updated rod by rod),
     killed after their first checkpoint and restarted with --restart: each restarts at a step (increment)
     after the start and before the end (summary cost restarted_at_step / restarted_at_increment), and equals
     its uninterrupted run bit for bit.
"""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[3]


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (FileNotFoundError, IndexError):
        return False


def compare(a, b):
    """tools/compare_runs.py A B --rtol 0: whether they agree, its last line, all it printed."""
    r = subprocess.run([sys.executable, str(ROOT / "tools/compare_runs.py"), str(a), str(b), "--rtol", "0"],
                       capture_output=True, text=True)
    text = r.stdout.strip()
    return r.returncode == 0, (text.splitlines() or ["no comparison"])[-1], text


def kill_after_first_checkpoint(command, checkpoint, env, log=None):
    """Starts `command`, kills its process group once `checkpoint` exists; whether it was killed before its
    end (False: it ended first, and the restart would test nothing). With `log` (a coupler's cosim.log), the
    participants it started are waited for too."""
    proc = subprocess.Popen(command, env=env, start_new_session=True)
    while not checkpoint.exists() and proc.poll() is None:
        time.sleep(0.001)
    if proc.poll() is not None:
        return False
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    if log is not None:
        pids = [int(p) for p in re.findall(r"started \w+ \(pid (\d+)\)", log.read_text())]
        deadline = time.time() + 30
        while any(alive(p) for p in pids) and time.time() < deadline:
            time.sleep(0.01)
    return True


def run_and_restart(bin_dir, scene, sets, out, env):
    """cosim run SCENE with `sets` into OUT/A; again into OUT/B, killed after its first checkpoint and
    restarted. Problems found: the restart's exit, the window it says it restarted from against the last
    checkpoint the killed run logged, and compare(A, B). Also the line to print."""
    a, b = out / "A", out / "B"
    shutil.rmtree(out, ignore_errors=True)
    command = [str(bin_dir / "cosim"), "run", str(scene), "--quiet"]
    for s in sets + ["coupling.idle_cpus=sleep"]:
        command += ["--set", s]
    subprocess.run(command + ["--out", str(a)], env=env, check=True)
    if not kill_after_first_checkpoint(command + ["--out", str(b)], b / "checkpoint" / "cosim.h5", env, b / "cosim.log"):
        return [f"{scene.name}: B ended before it could be killed after its first checkpoint"], "not killed"
    # The windows whose participant checkpoints the killed run left on disk (NAME_WINDOW.h5).
    windows = sorted({int(m.group(1)) for f in (b / "checkpoint").iterdir() if (m := re.search(r"_(\d+)\.h5$", f.name))})
    code = subprocess.run(command + ["--out", str(b), "--restart"], env=env).returncode
    same, line, text = compare(a, b)
    summary = yaml.safe_load((b / "summary.yaml").read_text())
    restarted = (summary.get("cost") or {}).get("restarted_from_window")
    total = (yaml.safe_load((a / "summary.yaml").read_text()).get("results") or {}).get("windows")
    problems = []
    if code != 0:
        problems.append(f"the restart exited {code}")
    if restarted not in windows or not (isinstance(total, int) and 0 < restarted < total):
        problems.append(f"restarted from window {restarted}; the killed run left checkpoints of windows {windows}, "
                        f"of {total}")
    if not same:
        problems.append(f"the restarted run differs: {text[:400]}")
    return problems, f"killed with checkpoints of windows {windows} on disk, restarted from window {restarted} " \
                      f"of {total} (exit {code}): {line}"


# An explicit scheme does not iterate: the implicit keys of the scene go.
WEAK = ["coupling.max_iterations=null", "coupling.tolerance=null", "coupling.extrapolation=null", "coupling.acceleration=null"]


def schemes(bin_dir, out, env):
    """The FEM–FEM split bar under the other schemes and accelerations, restarted from its last checkpoint."""
    failures = []
    for name, sets in [("explicit_parallel", ["coupling.scheme=explicit_parallel", *WEAK]),
                       ("explicit_serial", ["coupling.scheme=explicit_serial", *WEAK]),
                       ("implicit_aitken", ["coupling.acceleration.type=aitken"])]:
        problems, line = run_and_restart(bin_dir, ROOT / "configs/verification/split_bar_dynamic.yaml",
                                         sets + ["coupling.checkpoint_interval=50"], out / name, env)
        print(f"split bar, {name}: {line}")
        failures += [f"split bar {name}: {p}" for p in problems]
    return failures


def lattice_prism(bin_dir, out, env):
    """The lattice–FEM prism (two static FEM ends, the lattice cracking, Aitken), coarsened, restarted."""
    problems, line = run_and_restart(
        bin_dir, ROOT / "configs/verification/lattice_prism.yaml",
        ["coupling.end_time=8", "coupling.checkpoint_interval=2", "lattice:specimen.rod_length=0.006",
         "lattice:aggregates.sieve.d_min=0.006"], out, env)
    print(f"lattice prism, rods breaking on: {line}")
    return [f"lattice prism: {p}" for p in problems]


def standalone(bin_dir, out, env):
    failures = []
    CUBE = ROOT / "configs/dem/clusters/cube_c3.yaml"
    cases = [("dem_solver", "pour", ROOT / "configs/dem/pour.yaml",
              ["generate[0].count=200", "end_time=0.3", "output.checkpoint_interval=0.1"]),
             # Two rigid clusters, the second falling onto the first: what the scene builds and the
             # checkpoint does not hold (each body's reach, for the neighbour list) must survive a restart.
             ("dem_solver", "clusters", ROOT / "configs/dem/cluster_drop.yaml",
              [f"clusters=[{{file: {CUBE}, material: concrete, mass: 180, position: [0, 0, 0.2732]}}, "
               f"{{file: {CUBE}, material: concrete, mass: 180, position: [0.1, 0.05, 1.0], "
               "orientation: [0.9, 0.1, 0.3, 0.2]}]",
               "interactions=[{materials: [concrete, floor], law: hertz_mindlin, restitution: 0.5, friction: 0.5}, "
               "{materials: [concrete, concrete], law: hertz_mindlin, restitution: 0.5, friction: 0.5}]",
               "end_time=0.4", "output.checkpoint_interval=0.1"]),
             ("dem_solver", "hertz_bounce", ROOT / "configs/dem/hertz_bounce.yaml",
              ["end_time=3e-3", "output.checkpoint_interval=2e-4"]),
             ("fem_solver", "membrane_vibration", ROOT / "configs/fem/membrane_vibration.yaml",
              ["explicit.end_time=1.5", "output.checkpoint_interval=0.15"]),
             ("fem_solver", "net", ROOT / "configs/rockfall/net.yaml",
              ["explicit.end_time=0.05", "output.checkpoint_interval=0.02"]),
             ("lattice_solver", "tension", ROOT / "configs/lattice/tension_5cm.yaml",
              ["specimen.size=[0.025,0.025,0.025]", "output.checkpoint_every=10"])]
    checkpoint_file = {"dem_solver": "dem.h5", "fem_solver": "fem.h5", "lattice_solver": "lattice.h5"}
    for program, name, scene, sets in cases:
        a, b = out / name / "A", out / name / "B"
        shutil.rmtree(out / name, ignore_errors=True)

        # The lattice on two threads: its K x splits the rod records between them, so a restart must
        # rebuild the records exactly where they were (removed rods' included) to keep the rounding.
        threads = "2" if program == "lattice_solver" else "1"

        def command(folder, *extra):
            c = [str(bin_dir / program), str(scene), "--out", str(folder), "--quiet", "--threads", threads]
            for s in sets:
                c += ["--set", s]
            return c + list(extra)

        subprocess.run(command(a), env=env, check=True)
        if "static_reused: 0" in (a / "summary.yaml").read_text():
            # This build's first run of the net filled the static cache; B will start from the cache.
            subprocess.run(command(a), env=env, check=True)
        if not kill_after_first_checkpoint(command(b), b / "checkpoint" / checkpoint_file[program], env):
            failures.append(f"{program} {name}: B ended before it could be killed after its first checkpoint")
            continue
        code = subprocess.run(command(b, "--restart"), env=env).returncode
        same, line, text = compare(a, b)
        # Where it restarted: after the killed run's first checkpoint, before the end (a restart that ran
        # nothing would have no steps left to match A with).
        cost = yaml.safe_load((b / "summary.yaml").read_text()).get("cost") or {}
        at = cost.get("restarted_at_step", cost.get("restarted_at_increment"))
        end = yaml.safe_load((a / "summary.yaml").read_text())
        total = end.get("steps") if program != "lattice_solver" else (end.get("results") or {}).get("increments")
        print(f"{program} {name}: killed after its first checkpoint, restarted at {at} of {total} (exit {code}): {line}")
        if code != 0 or not same:
            failures.append(f"{program} {name}: the restart exited {code}; {text[:400]}")
        if not (isinstance(at, int) and isinstance(total, int) and 0 < at < total):
            failures.append(f"{program} {name}: restarted at {at} of {total}")

    # The lattice's checkpoint under another specimen: refused (exit 2) before its results are touched.
    b = out / "tension" / "B"
    before = (b / "lattice.h5").read_bytes()
    other = subprocess.run([str(bin_dir / "lattice_solver"), str(ROOT / "configs/lattice/tension_5cm.yaml"), "--out", str(b),
                            "--quiet", "--set", "specimen.size=[0.02,0.02,0.02]", "--restart"],
                           env=env, capture_output=True, text=True)
    print(f"lattice_solver tension: another specimen's --restart exit {other.returncode}")
    if other.returncode != 2 or "nodes" not in other.stderr or (b / "lattice.h5").read_bytes() != before:
        failures.append(f"lattice: another specimen's checkpoint: exit {other.returncode}, {other.stderr[-300:]}")
    return failures


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("bin", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--end-time", default="0.05")
    parser.add_argument("--interval", default="100")
    parser.add_argument("--scene", default=str(ROOT / "configs/rockfall/c2.yaml"))
    args = parser.parse_args()
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)
    env = dict(os.environ, PATH=f"{args.bin}:{os.environ['PATH']}")
    sets = [f"coupling.end_time={args.end_time}", f"coupling.checkpoint_interval={args.interval}",
            "coupling.idle_cpus=sleep"]

    def command(out, *extra):
        c = [str(args.bin / "cosim"), "run", args.scene, "--out", str(out), "--quiet"]
        for s in sets:
            c += ["--set", s]
        return c + list(extra)

    failures = []
    a, b = args.out / "A", args.out / "B"
    t0 = time.time()
    subprocess.run(command(a), env=env, check=True)
    print(f"A: ran through in {time.time() - t0:.1f} s")

    proc = subprocess.Popen(command(b), env=env, start_new_session=True)
    checkpoint = b / "checkpoint" / "cosim.h5"
    while not checkpoint.exists() and proc.poll() is None:
        time.sleep(0.005)
    if proc.poll() is not None:
        print(f"FAIL: B ended (exit {proc.returncode}) before its first checkpoint")
        return 1
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed_at = time.time()
    log = (b / "cosim.log").read_text()
    pids = [int(p) for p in re.findall(r"started \w+ \(pid (\d+)\)", log)]
    windows = re.findall(r"checkpoint at window (\d+)", log)
    print(f"B: coupler killed after its checkpoint(s) at window(s) {', '.join(windows) or '?'}; participants {pids}")
    while any(alive(p) for p in pids) and time.time() < killed_at + 30:
        time.sleep(0.05)
    left = [p for p in pids if alive(p)]
    print(f"B: its participants ended {time.time() - killed_at:.2f} s after the kill")
    if left:
        failures.append(f"processes of the killed run left alive 30 s after the kill: {left}")
        for p in left:
            os.kill(p, signal.SIGKILL)

    t0 = time.time()
    restarted = subprocess.run(command(b, "--restart"), env=env)
    print(f"B: restarted, exit {restarted.returncode}, {time.time() - t0:.1f} s")
    if restarted.returncode != 0:
        failures.append(f"the restart exited {restarted.returncode}")
    same, _, text = compare(a, b)
    print(text)
    if not same:
        failures.append("the restarted run differs from the uninterrupted one")

    # A damaged participant checkpoint: refused, naming the file; nothing of B's results is lost.
    c = args.out / "C"
    shutil.copytree(b, c, ignore=shutil.ignore_patterns(".cosim-*"))  # the killed coupler's socket
    dem = sorted((c / "checkpoint").glob("dem_*.h5"))[-1]
    data = dem.read_bytes()
    dem.write_bytes(data[: len(data) // 2])
    before = (c / "dem" / "dem.h5").read_bytes()
    damaged = subprocess.run(command(c, "--restart"), env=env, capture_output=True, text=True)
    status = (c / "summary.yaml").read_text()
    print(f"C (damaged {dem.name}): exit {damaged.returncode}")
    if damaged.returncode not in (2, 4) or dem.name not in status + damaged.stderr:
        failures.append(f"a damaged checkpoint gave exit {damaged.returncode}, message: {status.strip()[:300]}")
    dem_log = (c / "dem" / "summary.yaml").read_text() if (c / "dem" / "summary.yaml").exists() else ""
    if damaged.returncode == 4 and "exit_code: 2" not in dem_log:
        failures.append(f"the participant did not refuse its damaged checkpoint with exit 2: {dem_log[:300]}")
    if (c / "dem" / "dem.h5").read_bytes() != before:
        failures.append("a refused restart changed the results it would have appended to")

    # A checkpoint of another scene (the c3 block has other spheres): the DEM refuses it (exit 2) before it
    # touches its results.
    e = args.out / "E"
    shutil.copytree(b, e, ignore=shutil.ignore_patterns(".cosim-*"))
    before_e = (e / "dem" / "dem.h5").read_bytes()
    other = subprocess.run(command(e, "--restart") + ["--set", "dem:clusters[0].file=../dem/clusters/cube_c3.yaml"],
                           env=env, capture_output=True, text=True)
    print(f"E (c2's checkpoint, c3's block): exit {other.returncode}")
    dem_summary = (e / "dem" / "summary.yaml").read_text() if (e / "dem" / "summary.yaml").exists() else ""
    if other.returncode == 0 or "exit_code: 2" not in dem_summary or "another scene" not in dem_summary:
        failures.append(f"another scene's checkpoint was not refused: exit {other.returncode}, {dem_summary[:300]}")
    if (e / "dem" / "dem.h5").read_bytes() != before_e:
        failures.append("a refused restart (another scene) changed the results it would have appended to")

    # A fresh run in the same folder leaves no checkpoint of the earlier one behind to restart from.
    fresh = subprocess.run([str(args.bin / "cosim"), "run", args.scene, "--out", str(c), "--quiet", "--set",
                            "coupling.end_time=0.001", "--set", "coupling.idle_cpus=sleep"],
                           env=env, capture_output=True, text=True)
    stale = subprocess.run(command(c, "--restart"), env=env, capture_output=True, text=True)
    print(f"C after a fresh run without checkpoints: --restart exit {stale.returncode}")
    if fresh.returncode != 0 or stale.returncode != 2:
        failures.append(f"a stale checkpoint: fresh run exit {fresh.returncode}, then --restart exit {stale.returncode}")

    # No checkpoint at all.
    d = args.out / "D"
    missing = subprocess.run(command(d, "--restart"), env=env, capture_output=True, text=True)
    print(f"D (no checkpoint): exit {missing.returncode}")
    if missing.returncode != 2:
        failures.append(f"a restart without a checkpoint gave exit {missing.returncode}")

    failures += schemes(args.bin, args.out / "schemes", env)
    failures += lattice_prism(args.bin, args.out / "lattice_prism", env)
    failures += standalone(args.bin, args.out / "standalone", env)
    for f in failures:
        print(f"FAIL: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
