#!/usr/bin/env python3
"""Hostile input given to the executables themselves: each ends with a located exit 2, without taking the
memory that the input claims, and leaves nothing it had written behind half-done.

Usage: hostile_input.py BUILD_DIR OUT [LIMIT_MB]   (200 MB; more under AddressSanitizer, whose shadow
                                                    memory counts in the resident set)

  - a 1 KB YAML "billion laughs" (nine levels of nine aliases: 3.9e8 values) as a DEM, FEM and lattice
    scene and to `cosim check` and `cosim run`: exit 2 naming the alias budget, under 200 MB;
  - the same through `--set`;
  - a 23 KB gmsh v4 file whose header claims 1e8 nodes, as the FEM's mesh: exit 2, under 200 MB;
  - 1e9 particles generated into a large box: exit 2 with the memory it would need, under 200 MB;
  - dt = 1e-300 s in the DEM, coupling.time_window = 1e-300 s in the coupler: exit 2 (a step count that
    overflows), not a run that never ends or "ok" after 0 steps.
The peak memory is each process's own (wait4's maximum resident set), with its children.
"""
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))


# The same in one flow map, as --set takes it.
FLOW_LAUGHS = "{a: &a [x, x, x, x, x, x, x, x, x], " + ", ".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]" for i in range(8)) + "}"


def run(cmd, cwd):
    """Exit code, peak resident memory [MB] and the output of `cmd` (30 s at most: a hang is a failure)."""
    start = time.monotonic()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT)
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() - start > 30:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.01)
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        return proc.returncode, usage.ru_maxrss / 1024.0, out.read().decode(errors="replace")


def main():
    bin_dir, out = Path(sys.argv[1]).resolve() / "bin", Path(sys.argv[2]).resolve()
    limit = float(sys.argv[3]) if len(sys.argv) > 3 else 200.0
    out.mkdir(parents=True, exist_ok=True)
    laughs = out / "laughs.yaml"
    laughs.write_text(LAUGHS)
    assert len(LAUGHS) < 1024
    header = out / "claims_1e8.msh"
    header.write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 100000000 1 100000000\n2 1 0 3\n1 2 3\n"
                      "0 0 0\n1 0 0\n0 1 0\n$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n"
                      + "%" * 23000 + "\n")
    fem_scene = out / "claims.yaml"
    fem_scene.write_text((ROOT / "configs/verification/split_bar_dynamic_monolithic.yaml").read_text()
                         .replace("mesh: {file: split_bar.msh}", f"mesh: {{file: {header}}}"))
    cases = [
        ("dem_solver, billion laughs", [bin_dir / "dem_solver", laughs, "--check"], "alias"),
        ("fem_solver, billion laughs", [bin_dir / "fem_solver", laughs, "--check"], "alias"),
        ("lattice_solver, billion laughs", [bin_dir / "lattice_solver", laughs, "--check"], "alias"),
        ("cosim check, billion laughs", [bin_dir / "cosim", "check", laughs], "alias"),
        ("cosim run, billion laughs", [bin_dir / "cosim", "run", laughs, "--out", out / "run"], "alias"),
        ("dem_solver, billion laughs in --set", [bin_dir / "dem_solver", ROOT / "configs/dem/hertz_bounce.yaml",
                                                 "--check", "--set", "gravity=" + FLOW_LAUGHS], "alias"),
        ("fem_solver, a mesh header claiming 1e8 nodes", [bin_dir / "fem_solver", fem_scene, "--check"], "claims 1e+08 nodes"),
        ("dem_solver, 1e9 particles", [bin_dir / "dem_solver", ROOT / "configs/dem/pour.yaml", "--check",
                                       "--set", "generate[0].count=1000000000",
                                       "--set", "generate[0].box.max=[2000,2000,4000]"], "GB"),
        ("dem_solver, dt = 1e-300 s", [bin_dir / "dem_solver", ROOT / "configs/dem/hertz_bounce.yaml", "--out",
                                       out / "tiny_dt", "--set", "dt=1e-300", "--set", "dt_check=warn"], "1e-300"),
        ("cosim, time_window = 1e-300 s", [bin_dir / "cosim", "run", ROOT / "configs/verification/split_bar_dynamic.yaml",
                                           "--out", out / "tiny_window", "--set", "coupling.time_window=1e-300"], "1e-300"),
    ]
    failures = []
    for name, cmd, expect in cases:
        code, peak, text = run([str(c) for c in cmd], out)
        verdict = code == 2 and peak < limit and (expect is None or expect in text)
        print(f"{'ok  ' if verdict else 'FAIL'} {name}: exit {code}, peak {peak:.0f} MB; {text.strip().splitlines()[-1][:160] if text.strip() else ''}")
        if not verdict:
            failures.append(f"{name}: exit {code} (want 2), {peak:.0f} MB (want < {limit:.0f}), "
                            f"'{expect}' {'in' if expect and expect in text else 'not in'} the message:\n{text[-600:]}")
    if failures:
        print("\n".join(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
