"""Runs every ```sh block of docs/guide.md, in order, in the source tree with build/bin on the PATH and
$OUT a fresh folder: the guide's commands cannot rot. Run: python3 test_guide.py SOURCE_DIR BIN_DIR OUT"""
import os
import re
import subprocess
import sys
from pathlib import Path

source, bin_dir, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
subprocess.run(["rm", "-rf", str(out)], check=True)
out.mkdir(parents=True)
text = (source / "docs" / "guide.md").read_text()
blocks = re.findall(r"^```sh\n(.*?)^```", text, flags=re.S | re.M)
if len(blocks) < 8:
    print(f"only {len(blocks)} shell blocks in docs/guide.md")
    sys.exit(1)
# Open MPI refuses root (CI runs as root) and, in containers, its single-copy shared memory; its ranks
# spin while they wait, which on a machine shared with other tests stalls them: the guide's mpirun block
# runs here all the same, its waiting ranks yielding.
env = dict(os.environ, OUT=str(out), BUILD=str(bin_dir.resolve().parent), PATH=f"{bin_dir}:/usr/bin:/bin",
           OMP_WAIT_POLICY="passive", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_btl_vader_single_copy_mechanism="none", OMPI_MCA_mpi_yield_when_idle="1")
env["PYTHONPATH"] = ""
failures = []
for i, block in enumerate(blocks, 1):
    # python3 in the guide is Debian's (h5py, matplotlib, gmsh); /usr/bin comes first on this PATH.
    r = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=source, env=env, capture_output=True, text=True,
                       timeout=600)
    if r.returncode != 0:
        failures.append(f"block {i} exited {r.returncode}:\n{block}\n--- output ---\n{r.stdout[-1500:]}{r.stderr[-1500:]}")
if failures:
    print("\n\n".join(failures))
    sys.exit(1)
print(f"ok: {len(blocks)} blocks")
