"""Size and render time of the HTML report of the default suite's results (target: under 10 MB, a few seconds).

Uses the results in results/default (or $XVAL_BENCH_RESULTS), running
suites/default.toml into it first when they are missing or unfinished (that
run takes minutes; the report itself takes about a second). Renders the
report a few times and prints its size and the median render time (reading
the results included). Exits 1 when the report is over the 10 MB limit.

    .venv/bin/python bench/bench_report.py
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from reports.render import write_report

ROOT = Path(__file__).resolve().parent.parent
SUITE = ROOT / "suites" / "default.toml"
RESULTS = Path(os.environ.get("XVAL_BENCH_RESULTS", ROOT / "results" / "default"))
#: The limit on the report's size, bytes.
SIZE_LIMIT = 10_000_000
REPEATS = 3


def ensure_results() -> None:
    """Run the default suite into RESULTS unless a finished run is already there."""
    header = RESULTS / "run.json"
    if header.exists() and json.loads(header.read_text()).get("finished"):
        return
    xval = Path(sys.executable).with_name("xval")
    command = [str(xval), "run", str(SUITE), "--output", str(RESULTS)] + (["--resume"] if header.exists() else [])
    print(f"running the default suite first: {' '.join(command)}", flush=True)
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)


def main() -> int:
    ensure_results()
    n_cases = len(list((RESULTS / "cases").glob("*.json")))
    with tempfile.TemporaryDirectory() as scratch:
        runs = [write_report(RESULTS, Path(scratch) / "report.html") for _ in range(REPEATS)]
    size = runs[0].size
    seconds = statistics.median(r.seconds for r in runs)
    print(f"report of {RESULTS} ({n_cases} cases): {size / 1e6:.2f} MB, "
          f"render {seconds:.2f} s (median of {REPEATS}, reading the results included)")
    if size > SIZE_LIMIT:
        print(f"FAIL: the report is over the {SIZE_LIMIT / 1e6:.0f} MB limit")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
