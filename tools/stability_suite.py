#!/usr/bin/env python3
"""Run the stability suite: every case of configs/stability/*.yaml, each checked against its stated outcome.

Usage:  tools/stability_suite.py BUILD_DIR OUT [--only SUBSTRING ...] [--skip-label long] [--label long] [--list]

Each scene file of configs/stability/ says in its header what it stresses and the outcome it must have,
and carries machine-readable lines starting with "#!" (YAML once the prefix is stripped):

    #! run: dem_solver                   # an executable of BUILD_DIR/bin (cosim for coupled scenes)
    #! cases:
    #!   - name: dem_impact_50ms          # unique across the suite
    #!     set: ["spheres[0].velocity=[0,0,-50]"]   # --set overrides (optional)
    #!     label: long                    # optional: --skip-label long leaves it out, --label long runs only such
    #!     expect:
    #!       exit: 0                      # the exit code it must end with (0 or 3)
    #!       energy_error: 0.02           # exit 0: the largest energy balance error allowed
    #!       energy: summary              # where the energy error comes from: `summary` (results.
    #!                                    #   energy_balance_error, default) or `rockfall` (the coupled
    #!                                    #   block + net balance of tools/rockfall_report.py)
    #!       cause: energy growth         # exit 3: failure.cause must equal this (or one of a list)
    #!       results: {key: [lo, hi]}     # summary results that must lie in [lo, hi]
    #!       no_fix_settings: why         # exit 3: no setting is the fix (a finer mesh, another law), and why
    #!       timeout: 600                 # seconds before the case counts as a hang (default 600)

For every case the driver also checks, whatever the expectation: a summary.yaml exists; exit 3 comes with
a non-empty failure.cause and failure.fix; status is "ok" exactly when the exit code is 0; no HDF5 file
the run wrote holds a non-finite value. An exit 3 must come with failure.fix_settings (the fix as `--set`
values, as the run printed them), unless the case says `no_fix_settings:` and why; the driver then reruns
the case with those settings appended, verbatim, into OUT/<case>/fix/, and the rerun must end with exit 0
and status ok (a rerun that meets another cause applies that fix in turn, up to three runs; a fix asked
again for a key already fixed did not work): a fix that does not work fails the case. It writes OUT/stability.csv (case, exit_code, status, cause,
fix, energy_error, interface_error, nonfinite_in_output, wall_s, expected, verdict, problems) and
OUT/stability.md, the same as a Markdown table (docs/stability.md shows one), and OUT/<case>/ with each run's
files, prints a table, and exits 1 if any case missed its outcome (0 otherwise).
"""
import argparse
import csv
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent


def load_cases(folder):
    """(scene path, executable, case dict) for every case of every scene in `folder`."""
    cases = []
    for scene in sorted(folder.glob("*.yaml")):
        header = [line[2:].rstrip("\n")[1:] if line.startswith("#! ") else line[2:].rstrip("\n")
                  for line in scene.read_text().splitlines(True) if line.startswith("#!")]
        if not header:
            raise SystemExit(f"{scene}: no '#!' header (run: and cases:); every stability scene states its cases.")
        try:
            spec = yaml.safe_load("\n".join(header))
        except yaml.YAMLError as e:
            raise SystemExit(f"{scene}: the '#!' header is not valid YAML: {e}")
        if not isinstance(spec, dict) or "run" not in spec or not spec.get("cases"):
            raise SystemExit(f"{scene}: the '#!' header needs `run:` and a non-empty `cases:` list.")
        for case in spec["cases"]:
            expect = case.get("expect", {})
            if "name" not in case or expect.get("exit") not in (0, 3):
                raise SystemExit(f"{scene}: case {case.get('name', '?')}: needs a name and expect.exit 0 or 3.")
            cases.append((scene, spec["run"], case))
    names = [c[2]["name"] for c in cases]
    duplicates = {n for n in names if names.count(n) > 1}
    if duplicates:
        raise SystemExit(f"case names used twice: {', '.join(sorted(duplicates))}")
    return cases


def nonfinite_values(folder):
    """Number of non-finite floating values in every HDF5 file under `folder`."""
    count = 0
    for path in folder.rglob("*.h5"):
        try:
            with h5py.File(path, "r") as f:
                def visit(_, obj):
                    nonlocal count
                    if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and obj.size:
                        count += int(np.size(obj[()]) - np.count_nonzero(np.isfinite(obj[()])))
                f.visititems(visit)
        except OSError as e:  # an unreadable file is a failure of its own
            print(f"  {path}: unreadable ({e})", file=sys.stderr)
            count += 1
    return count


def run(build, scene, exe, sets, folder, timeout):
    """Exit code of one run into `folder` (None when it outlived `timeout`)."""
    if folder.exists():
        subprocess.run(["rm", "-rf", str(folder)], check=True)
    folder.mkdir(parents=True)
    cmd = [str(build / "bin" / exe), str(scene), "--out", str(folder), "--quiet"]
    for s in sets:
        cmd += ["--set", s]
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    with open(folder / "console.txt", "w") as console:
        # Its own process group: a case that hangs is killed with every process it started.
        proc = subprocess.Popen(cmd, stdout=console, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return None


def apply_fixes(build, scene, exe, case, folder, fix, row, rounds=3):
    """Rerun with the printed fix appended, verbatim: the rerun must end ok. A rerun that ends with exit 3
    and a fix for other keys has passed the first cause and met another (a weak scheme's lag fixed, the
    contact beneath it now too soft): that fix is applied in turn, as a user would, up to `rounds` runs.
    A fix proposed again for a key already fixed did not work."""
    settings, fixed_keys, steps = list(case.get("set", [])), set(), []
    for i in range(1, rounds + 1):
        keys = {v.split("=", 1)[0] for v in fix}
        if keys & fixed_keys:
            return [f"the printed fix did not work: after {' '.join(steps)} the run asks again for {sorted(keys & fixed_keys)}"]
        fixed_keys |= keys
        settings += fix
        steps.append(" ".join(f"--set {v}" for v in fix))
        where = folder / ("fix" if i == 1 else f"fix{i}")
        code = run(build, scene, exe, settings, where, case.get("expect", {}).get("timeout", 600))
        summary = (yaml.safe_load((where / "summary.yaml").read_text()) or {}) if (where / "summary.yaml").exists() else {}
        row["fix"] = " then ".join(steps) + f" → exit {code}"
        if code == 0 and summary.get("status") == "ok":
            return ["the printed fix's run wrote non-finite values"] if nonfinite_values(where) else []
        fix = (summary.get("failure") or {}).get("fix_settings") or []
        if code != 3 or not fix:
            break
    return [f"the printed fix ({' then '.join(steps)}) ends with exit {code}, not ok (see {where})"]


def run_case(build, out, scene, exe, case):
    folder = out / case["name"]
    expect = case.get("expect", {})
    start = time.monotonic()
    code = run(build, scene, exe, case.get("set", []), folder, expect.get("timeout", 600))
    wall = time.monotonic() - start
    row = {"case": case["name"], "exit_code": code if code is not None else "timeout", "status": "", "cause": "",
           "fix": "", "energy_error": "", "interface_error": "", "nonfinite_in_output": 0, "wall_s": f"{wall:.2f}",
           "expected": f"exit {expect['exit']}" + (f", {expect['cause']}" if "cause" in expect else "")
                       + (f", energy ≤ {expect['energy_error']}" if "energy_error" in expect else "")}
    problems = []
    summary_file = folder / "summary.yaml"
    summary = yaml.safe_load(summary_file.read_text()) if summary_file.exists() else None
    if code is None:
        problems.append("hang: no end within the timeout")
    if summary is None:
        problems.append("no summary.yaml")
        summary = {}
    results = summary.get("results") or {}
    failure = summary.get("failure") or {}
    row["status"] = "ok" if summary.get("status") == "ok" else ("error" if summary else "")
    row["cause"] = failure.get("cause", "")
    if expect.get("energy") == "rockfall" and code == 0:
        report = subprocess.run([sys.executable, str(ROOT / "tools" / "rockfall_report.py"), str(folder)],
                                capture_output=True, text=True)
        if report.returncode != 0:
            problems.append(f"rockfall_report.py failed: {report.stderr.strip()[-200:]}")
        summary = yaml.safe_load(summary_file.read_text())
        results = summary.get("results") or {}
    energy = results.get("energy_balance_error")
    if energy is not None:
        row["energy_error"] = f"{energy:.3g}"
    interface = [v for k, v in results.items() if k.startswith("interface_energy_error") and isinstance(v, (int, float))]
    row["interface_error"] = f"{max(interface):.2g}" if interface else ""
    row["nonfinite_in_output"] = nonfinite_values(folder)

    if code is not None and code != expect["exit"]:
        problems.append(f"exit {code}, expected {expect['exit']}")
    if code == 0 and summary.get("status") != "ok":
        problems.append("exit 0 without status: ok")
    if code not in (0, None) and summary.get("status") == "ok":
        problems.append(f"exit {code} with status: ok")
    if code == 3:
        if not failure.get("cause") or not failure.get("fix"):
            problems.append("exit 3 without failure.cause and failure.fix")
        causes = expect.get("cause", [])
        causes = [causes] if isinstance(causes, str) else causes
        if causes and failure.get("cause") not in causes:
            problems.append(f"cause {failure.get('cause')!r}, expected {' or '.join(repr(c) for c in causes)}")
        fix = failure.get("fix_settings") or []
        if not fix and "no_fix_settings" in expect:
            row["fix"] = f"no setting fixes it: {expect['no_fix_settings']}"
        if fix and "no_fix_settings" in expect:
            problems.append(f"fix_settings {fix} where the case says none exist ({expect['no_fix_settings']})")
        elif not fix and "no_fix_settings" not in expect:
            problems.append("exit 3 without failure.fix_settings (or no_fix_settings: why, in the case)")
        elif fix:
            problems += apply_fixes(build, scene, exe, case, folder, fix, row)
    if code == 0 and "energy_error" in expect:
        if energy is None:
            problems.append("no energy_balance_error in the summary")
        elif not energy <= float(expect["energy_error"]):
            problems.append(f"energy error {energy:.3g} above {expect['energy_error']}")
    if code == expect["exit"]:
        for key, (lo, hi) in (expect.get("results") or {}).items():
            lo, hi = float(lo), float(hi)  # YAML 1.1 reads 8.0e4 (no exponent sign) as a string
            value = results.get(key)
            if not isinstance(value, (int, float)) or not (lo <= value <= hi) or not math.isfinite(value):
                problems.append(f"{key} = {value}, expected in [{lo}, {hi}]")
    if row["nonfinite_in_output"]:
        problems.append(f"{row['nonfinite_in_output']} non-finite values in the HDF5 output")
    row["verdict"] = "pass" if not problems else "FAIL"
    row["problems"] = "; ".join(problems)
    return row


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("build", type=Path, help="build folder (its bin/ holds the executables)")
    parser.add_argument("out", type=Path, help="results folder (OUT/stability.csv, OUT/<case>/)")
    parser.add_argument("--only", nargs="+", default=[], help="run only cases whose name contains one of these")
    parser.add_argument("--skip-label", nargs="+", default=[], help="leave out cases with these labels")
    parser.add_argument("--label", nargs="+", default=[], help="run only cases with one of these labels")
    parser.add_argument("--list", action="store_true", help="list the cases and exit")
    parser.add_argument("--configs", type=Path, default=ROOT / "configs" / "stability")
    args = parser.parse_args(argv)

    cases = load_cases(args.configs)
    if args.only:
        cases = [c for c in cases if any(s in c[2]["name"] for s in args.only)]
    cases = [c for c in cases if c[2].get("label") not in args.skip_label]
    if args.label:
        cases = [c for c in cases if c[2].get("label") in args.label]
    if args.list:
        for scene, exe, case in cases:
            print(f"{case['name']:48s} {exe:15s} {scene.name}")
        return 0
    if not cases:
        raise SystemExit("no case selected")
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for i, (scene, exe, case) in enumerate(cases, 1):
        print(f"[{i}/{len(cases)}] {case['name']} ...", end=" ", flush=True)
        row = run_case(args.build.resolve(), args.out.resolve(), scene, exe, case)
        rows.append(row)
        print(f"exit {row['exit_code']} in {row['wall_s']} s: {row['verdict']}"
              + (f" ({row['problems']})" if row["problems"] else ""), flush=True)
    columns = ["case", "exit_code", "status", "cause", "fix", "energy_error", "interface_error", "nonfinite_in_output", "wall_s", "expected",
               "verdict", "problems"]
    with open(args.out / "stability.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    with open(args.out / "stability.md", "w") as f:
        f.write("| case | expected | exit | energy | outcome; the printed fix applied | wall [s] |\n| --- | --- | --- | --- | --- | --- |\n")
        for r in rows:
            energy = " / ".join(v or "—" for v in (r["energy_error"], r["interface_error"])) if r["interface_error"] else (r["energy_error"] or "—")
            outcome = "ok" if r["exit_code"] == 0 else f"**{r['cause']}**" + (f"; {r['fix']}" if r["fix"] else "")
            if r["verdict"] != "pass":
                outcome += f" — FAIL: {r['problems']}"
            f.write(f"| `{r['case']}` | {r['expected']} | {r['exit_code']} | {energy} | {outcome} | {r['wall_s']} |\n")
    failed = [r for r in rows if r["verdict"] != "pass"]
    print(f"\n{len(rows) - len(failed)} of {len(rows)} cases met their stated outcome; table: {args.out / 'stability.csv'}")
    for r in failed:
        print(f"  FAIL {r['case']}: {r['problems']}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
