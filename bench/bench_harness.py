"""What the harness costs around the physics: CPU of ``xval run suites/default.toml --jobs 1``
against the summed stepping time of its cases (issue 20's target: at most 1.4×).

Runs the suite into a temporary directory in a child process (numba's cache warm:
a first run fills it) and reports the CPU time of that whole process tree (user +
system, from the kernel's accounting of waited-for children), the sum over cases of
the engines' stepping times (``wall_times`` in the records), and their ratio.

The stepping times are wall clock: on a machine loaded by other jobs they grow
while CPU time does not, which flatters the ratio. The load average is printed
with the result; compare runs made at similar load.

    .venv/bin/python bench/bench_harness.py [--runs N]
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
XVAL = [sys.executable, "-c", "from compare.cli import main; main()"]


def one_run() -> tuple[float, float]:
    """(CPU seconds of the run's process tree, summed stepping seconds of its cases)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "default"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([*XVAL, "run", "suites/default.toml", "--jobs", "1", "--output", str(out)], cwd=ROOT,
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        stepping = sum(sum(json.loads(f.read_text())["wall_times"]) for f in (out / "cases").glob("*.json"))
    return cpu, stepping


def main(argv: list[str]) -> int:
    runs = int(argv[argv.index("--runs") + 1]) if "--runs" in argv else 2
    one_run()  # fills numba's cache if it is empty; not counted
    print(f"{'run':>3} {'CPU s':>7} {'stepping s':>11} {'CPU / stepping':>15} {'load':>5}")
    for k in range(runs):
        cpu, stepping = one_run()
        print(f"{k + 1:>3} {cpu:7.2f} {stepping:11.2f} {cpu / stepping:15.2f} {os.getloadavg()[0]:5.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
