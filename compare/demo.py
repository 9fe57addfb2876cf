"""``make demo``: run ``suites/default.toml`` into ``results/default`` and print the tables.

A previous demo's results directory is replaced (only when it is one: it
holds a run.json), so the demo always shows a fresh, complete run.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from compare.run.progress import progress_for
from compare.run.runner import run_suite
from compare.suite.reader import load_suite
from compare.results.sweep import sweeps
from compare.results.table import scene_tables
from compare.results.verdict import scene_verdicts
from compare.results.verdict_format import format_verdicts

ROOT = Path(__file__).resolve().parent.parent
SUITE = ROOT / "suites" / "default.toml"
OUTPUT = ROOT / "results" / "default"


def main() -> None:
    if (OUTPUT / "run.json").exists():
        shutil.rmtree(OUTPUT)
    suite = load_suite(SUITE)
    summary = run_suite(suite, OUTPUT, progress=progress_for(sys.stderr))
    variant_sweeps = sweeps(summary.records, suite.verdict_tolerance)
    print(scene_tables(variant_sweeps))
    print(format_verdicts(scene_verdicts(variant_sweeps)))
    counts = ", ".join(f"{n} {status}" for status, n in summary.counts.items())
    print(f"{summary.ran} cases in {summary.wall_time:.1f} s ({counts})")
    print(f"results: {OUTPUT}  (xval show {OUTPUT.relative_to(ROOT)} --format csv; xval report ...)")


if __name__ == "__main__":
    main()
