#!/usr/bin/env python3
"""The fault-injection suite: every protocol phase × every fault, each run checked for how it ends.

Usage:  fault_suite.py BUILD_DIR OUT [--quick] [--timeout T] [--markdown FILE]

Each case is the dynamic python_spring scene (configs/verification/python_spring.yaml: fem_solver on the
right, a mass-spring on the left, 10 windows, implicit IQN-ILS) with its left participant replaced by
tests/integration/faults/fault_participant.py injecting one fault at one phase, and coupling.timeout =
coupling.first_answer_timeout = T (default 3 s). Checked for every case:

  - the exit code: 0 for `none` and `stranger` (a stranger must not stop the run) and then the result
    equal, bit for bit, to the fault-free run's; 4 for every other fault (the coupler's own death for
    `coupler_killed`, where the participants' ends are checked instead);
  - the time from the fault to the end of the run (or, coupler killed, of its participants) ≤ T + 15 s;
  - the message: a failed run's summary.yaml status names the participant ("left");
  - no process of the run left alive afterwards;
  - every HDF5 file of the run opens and reads.

Writes OUT/faults.csv and, with --markdown, the table for docs/reliability.md; exits 1 if any case failed.
--quick runs the cases of the issue's bar and one per fault class (make test); the full matrix is
`make faults`.
"""
import argparse
import csv
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
sys.path.insert(0, str(HERE))
from fault_participant import FAULTS, PHASES  # noqa: E402

GRACE = 15.0
QUICK = [("mid_iteration", f) for f in ("ignore_sigterm", "sigstop", "heartbeat_only", "coupler_killed", "stranger",
                                       "garbage", "nan", "bad_utf8", "kill9")] + [("start", "wrong_version"), ("start", "stranger"),
                                                                      ("finalize", "linger")]


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # A zombie has ended; only its parent has yet to collect it.
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (FileNotFoundError, IndexError):
        return False


def readable(path):
    try:
        with h5py.File(path, "r") as f:
            f.visititems(lambda name, obj: obj[()] if isinstance(obj, h5py.Dataset) else None)
        return True
    except Exception:  # noqa: BLE001 - any failure to read is the finding
        return False


def run_case(bin_dir, out, phase, fault, timeout):
    case = out / f"{phase}-{fault}"
    subprocess.run(["rm", "-rf", str(case)], check=True)
    case.mkdir(parents=True)
    marker = case / "fault_time"
    command = (f"[/usr/bin/python3, {HERE / 'fault_participant.py'}, --fault, {fault}, --phase, {phase}, "
               f"--marker, {marker}, --coupler-timeout, '{timeout}']")
    sets = ["coupling.time_window=1e-3", "coupling.end_time=0.01", f"coupling.timeout={timeout}",
            f"coupling.first_answer_timeout={timeout}", f"participants.left.command={command}"]
    args = [str(bin_dir / "cosim"), "run", str(ROOT / "configs/verification/python_spring.yaml"), "--out",
            str(case / "run"), "--quiet"]
    for s in sets:
        args += ["--set", s]
    start = time.time()
    proc = subprocess.Popen(args, stdout=open(case / "console.log", "w"), stderr=subprocess.STDOUT,
                            start_new_session=True)
    hard_cap = timeout + GRACE + 60
    try:
        code = proc.wait(timeout=hard_cap)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        code = "hang"
    end = time.time()
    raw_log = (case / "run" / "cosim.log").read_bytes() if (case / "run" / "cosim.log").exists() else b""
    log = raw_log.decode("utf-8", errors="replace")
    pids = [int(p) for p in re.findall(r"started \w+ \(pid (\d+)\)", log)]
    fault_time = float(marker.read_text()) if marker.exists() else start
    problems = []
    # Participants of a killed coupler end on their own: wait for them up to the bound.
    while any(alive(p) for p in pids) and time.time() < fault_time + timeout + GRACE:
        time.sleep(0.1)
    if fault == "coupler_killed":
        end = time.time()
    left_alive = [p for p in pids if alive(p)]
    for p in left_alive:
        os.kill(p, signal.SIGKILL)
    stop_s = end - fault_time
    summary = {}
    problems_reading = []
    for path in (case / "run").rglob("summary.yaml"):  # every summary valid UTF-8 and YAML, whatever a peer sent
        try:
            loaded = yaml.safe_load(path.read_bytes().decode("utf-8")) or {}
        except (UnicodeDecodeError, yaml.YAMLError) as e:
            problems_reading.append(f"{path.relative_to(case)} is not valid UTF-8 YAML: {e}")
            continue
        if path == case / "run" / "summary.yaml":
            summary = loaded
    status = str(summary.get("status", ""))
    problems += problems_reading
    if log.encode("utf-8") != raw_log:
        problems.append("cosim.log is not valid UTF-8 (a peer's bytes quoted raw)")
    expected = 0 if fault in ("none", "stranger") else (-signal.SIGKILL if fault == "coupler_killed" else 4)
    if code != expected:
        problems.append(f"exit {code}, expected {expected}")
    if stop_s > timeout + GRACE:
        problems.append(f"took {stop_s:.1f} s to stop after the fault (allowed {timeout + GRACE:.0f})")
    if expected == 4 and "left" not in status:
        problems.append(f"the status does not name the participant: {status!r}")
    if left_alive:
        problems.append(f"processes left alive: {left_alive}")
    unreadable = [str(p.relative_to(case)) for p in (case / "run").rglob("*.h5") if not readable(p)]
    if unreadable:
        problems.append(f"unreadable HDF5: {unreadable}")
    result = None
    left_summary = case / "run" / "left" / "summary.yaml"
    if expected == 0 and left_summary.exists():
        result = (yaml.safe_load(left_summary.read_text()) or {}).get("results", {}).get("displacement")
    return {"phase": phase, "fault": fault, "exit_code": code, "stop_s": round(stop_s, 2), "status": status,
            "left_alive": len(left_alive), "unreadable_h5": len(unreadable), "result": result,
            "refused": (summary.get("results") or {}).get("refused_connections", ""), "problems": problems}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build")
    ap.add_argument("out")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--timeout", type=float, default=3.0)
    ap.add_argument("--markdown")
    a = ap.parse_args()
    bin_dir = Path(a.build).resolve() / "bin"
    out = Path(a.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    cases = QUICK if a.quick else [(p, f) for p in PHASES for f in FAULTS if f != "none"]
    reference = run_case(bin_dir, out, "mid_iteration", "none", a.timeout)
    rows = []
    for phase, fault in cases:
        r = run_case(bin_dir, out, phase, fault, a.timeout)
        if r["exit_code"] == 0 and r["result"] != reference["result"]:
            r["problems"].append(f"result {r['result']!r} differs from the fault-free run's {reference['result']!r}")
        r["verdict"] = "ok" if not r["problems"] else "FAILED"
        rows.append(r)
        print(f"{phase:14s} {fault:15s} exit {str(r['exit_code']):5s} stop {r['stop_s']:6.2f} s  {r['verdict']}"
              + (f"  {'; '.join(r['problems'])}" if r["problems"] else ""), flush=True)
    keys = ["phase", "fault", "exit_code", "stop_s", "left_alive", "unreadable_h5", "refused", "verdict", "status"]
    with open(out / "faults.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys + ["problems"])
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in keys} | {"problems": "; ".join(r["problems"])})
    if a.markdown:
        lines = ["| phase | fault | exit | stop after fault [s] | processes left | unreadable HDF5 | refused | "
                 "verdict | message (summary.yaml status) |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in rows:
            msg = r["status"].replace("|", "\\|")
            if len(msg) > 160:
                msg = msg[:157] + "…"
            lines.append(f"| {r['phase']} | {r['fault']} | {r['exit_code']} | {r['stop_s']} | {r['left_alive']} | "
                         f"{r['unreadable_h5']} | {r['refused']} | {r['verdict']} | {msg} |")
        Path(a.markdown).write_text("\n".join(lines) + "\n")
    failed = [r for r in rows if r["problems"]]
    print(f"{len(rows) - len(failed)} of {len(rows)} cases ended as they must")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
