#!/usr/bin/env python3
"""tools/stability_suite.py's selection: `--label long` (what CI runs after `make test`) and `--skip-label long`
(what `make test` runs) split the suite's cases between them, none left out and none run twice; the cases
labelled `long` are the ones whose headers say so, and there are some.
Run: python3 test_suite_selection.py SOURCE_DIR BUILD_DIR"""
import subprocess
import sys
from pathlib import Path

source, build = Path(sys.argv[1]), sys.argv[2]
suite = [sys.executable, str(source / "tools" / "stability_suite.py"), build, "unused", "--list"]


def listed(*flags):
    r = subprocess.run(suite + list(flags), capture_output=True, text=True, check=True)
    return [line.split()[0] for line in r.stdout.splitlines() if line.strip()]


everything, long, rest = listed(), listed("--label", "long"), listed("--skip-label", "long")
sys.path.insert(0, str(source / "tools"))
from stability_suite import load_cases  # noqa: E402
headers = [case["name"] for _, _, case in load_cases(source / "configs" / "stability") if case.get("label") == "long"]
failures = []
if sorted(long) != sorted(headers) or not long:
    failures.append(f"--label long lists {long}, the headers label {headers}")
if set(long) & set(rest):
    failures.append(f"both selections list {sorted(set(long) & set(rest))}")
if sorted(long + rest) != sorted(everything):
    failures.append(f"{len(long)} + {len(rest)} cases selected, {len(everything)} in the suite")
print("\n".join(failures) or f"ok: {len(long)} long + {len(rest)} others = {len(everything)} cases")
sys.exit(1 if failures else 0)
