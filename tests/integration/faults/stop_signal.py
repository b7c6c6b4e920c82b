#!/usr/bin/env python3
"""SIGTERM to a participant mid-run: it ends like any failed run, with its summary.

Usage:  stop_signal.py BUILD_DIR OUT

The dynamic python_spring scene (fem_solver on the right, the Python mass-spring on the left) runs for
long enough; 1.5 s in, the fem_solver process gets SIGTERM. It used to vanish at once, sometimes before its
summary (the coupler then said only that it could not send ADVANCE). Checked: fem_solver writes
right/summary.yaml with exit code 4 and a status naming SIGTERM; cosim ends with exit 4 naming "right" and
its exit code; no process of the run is left. Exits 1 on any failure.
"""
import subprocess
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[3]


def main(argv=None):
    argv = argv if argv is not None else sys.argv[1:]
    build, out = Path(argv[0]).resolve(), Path(argv[1]).resolve()
    subprocess.run(["rm", "-rf", str(out)], check=True)
    spring = "[/usr/bin/python3, ../../coupler/python/mass_spring.py, --k, '4.0e6', --m, '1.0e3', --x, '5', '0', '0']"
    command = [str(build / "bin/cosim"), "run", str(ROOT / "configs/verification/python_spring.yaml"), "--out", str(out),
               "--quiet", "--set", "coupling.time_window=1e-3", "--set", "coupling.end_time=60", "--set",
               f"participants.left.command={spring}", "--set", "coupling.idle_cpus=sleep"]
    cosim = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.5)
    pids = subprocess.run(["pgrep", "-f", f"fem_solver.*--out {out}/right"], capture_output=True, text=True).stdout.split()
    problems = []
    if len(pids) != 1:
        problems.append(f"expected one fem_solver of this run, found {pids}")
    else:
        subprocess.run(["kill", "-TERM", pids[0]], check=True)
    code = cosim.wait(timeout=120)
    summary = yaml.safe_load((out / "summary.yaml").read_text())
    right = out / "right/summary.yaml"
    participant = yaml.safe_load(right.read_text()) if right.exists() else None
    if code != 4 or "participant \"right\" exited with code 4" not in summary.get("status", ""):
        problems.append(f"cosim: exit {code}, status {summary.get('status')!r}")
    if participant is None:
        problems.append("fem_solver wrote no summary")
    elif participant.get("exit_code") != 4 or "stopped by SIGTERM" not in participant.get("status", ""):
        problems.append(f"fem_solver: exit {participant.get('exit_code')}, status {participant.get('status')!r}")
    left = subprocess.run(["pgrep", "-f", f"--out {out}"], capture_output=True, text=True).stdout.split()
    if left:
        problems.append(f"processes of the run still alive: {left}")
    print("\n".join(problems) if problems else f"ok: {participant['status']}; cosim: {summary['status']}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
