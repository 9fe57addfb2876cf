"""Wall time of ``xval run suites/default.toml`` and where it goes.

Runs the default suite into a temporary directory with the default job count
(all cores) and reports: total wall time; the sum over cases of the stepping
loops alone (what the engines cost), of whole cases in their workers (adds
model building, forking the case's child process and sending the trajectory
back), per engine; and the parent's share (reference solves, metrics,
writing records). Target: under 60 s on 2 cores.
"""

from __future__ import annotations

import collections
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from compare.run.results import load_results  # noqa: E402
from compare.run.runner import default_jobs  # noqa: E402


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        output = Path(tmp) / "default"
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-c", "from compare.cli import main; main()", "run", "suites/default.toml",
             "--output", str(output)],
            cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - start
        records = load_results(output).records
        size = sum(f.stat().st_size for f in output.rglob("*") if f.is_file())
    stepping: collections.Counter = collections.Counter()
    whole: collections.Counter = collections.Counter()
    cases: collections.Counter = collections.Counter()
    for record in records:
        engine = record["case"]["engine"].split("/")[0]
        stepping[engine] += sum(record["wall_times"])
        whole[engine] += record["elapsed"]
        cases[engine] += 1
    jobs = default_jobs()
    print(f"xval run suites/default.toml: {wall:.1f} s wall on {jobs} cores, {len(records)} cases, "
          f"results {size / 1e6:.1f} MB (target: under 60 s on 2 cores)")
    print(f"{'engine':<10} {'cases':>6} {'stepping s':>11} {'whole cases s':>14} {'overhead/case ms':>17}")
    for engine in sorted(whole, key=whole.get, reverse=True):
        overhead = (whole[engine] - stepping[engine]) / cases[engine] * 1e3
        print(f"{engine:<10} {cases[engine]:>6} {stepping[engine]:>11.1f} {whole[engine]:>14.1f} {overhead:>17.0f}")
    total_whole = sum(whole.values())
    print(f"{'all':<10} {len(records):>6} {sum(stepping.values()):>11.1f} {total_whole:>14.1f}")
    print(f"worker time / cores = {total_whole / jobs:.1f} s of the {wall:.1f} s wall; the rest is start-up "
          f"(imports, environment, reference solves before the first cases finish), the parent's metrics and "
          f"writing, and the tail of the longest cases")


if __name__ == "__main__":
    main()
