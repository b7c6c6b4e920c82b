"""The adapter tests' checks: each prints `ok` or `FAIL` with its figures; finish() exits 1 if any failed
(ctest also fails a test whose output says FAIL)."""
import sys

failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name} {detail}", flush=True)
    if not ok:
        failures.append(name)


def finish():
    print("FAIL" if failures else "all passed")
    sys.exit(1 if failures else 0)
