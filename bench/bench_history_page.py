"""Size of the history's trend page and how soon it is interactive in headless chromium.

    .venv/bin/python bench/bench_history_page.py [RESULTS_DIR] [--runs 20] [--repeats 3] [--output PAGE.html]

RESULTS_DIR is one finished run (e.g. ``xval run suites/default.toml --output
results/default``); without it the script runs suites/default.toml first. The script makes a history of ``--runs`` runs from it (each
started an hour after the last, under a made-up commit, every case's timings
moved by a seeded ±10 % as a machine's noise would), writes its trend page
(``xval history report``'s code) and prints the page's size, the time to write
it, and over ``--repeats`` fresh browser profiles (network off, 1300 × 1000 px)
the time until the page says it is interactive (its status element's
``data-ready-ms``), and from scrolling to the first plot until it is drawn. The load
average is printed beside: a busy machine stretches every browser timing.
Needs chromium (``apt-get install chromium``) for the browser part.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402

from browser_support import CHROMIUM, Page  # noqa: E402
from compare.history.origin import Origin  # noqa: E402
from compare.history.store import History  # noqa: E402
from compare.run.results import load_results  # noqa: E402
from reports.history import write_history_report  # noqa: E402

T0 = _dt.datetime(2026, 11, 1, 12, 0, tzinfo=_dt.timezone.utc)
TIMINGS = ("wall_time", "cost_per_simulated_second")


def history_of(results_dir: Path, runs: int, target: Path) -> None:
    """``runs`` copies of the run at ``results_dir`` in a new history at ``target``, timings jittered."""
    base = load_results(results_dir)
    noise = np.random.default_rng(7).uniform(0.9, 1.1, size=(runs, len(base.records)))
    with History.open(target, create=True) as history:
        for index in range(runs):
            records = []
            for k, record in enumerate(base.records):
                metrics = dict(record.metrics)
                for name in TIMINGS:
                    if metrics.get(name) is not None:
                        metrics[name] *= float(noise[index, k])
                records.append(dataclasses.replace(record, metrics=metrics,
                                                   wall_times=tuple(w * float(noise[index, k]) for w in record.wall_times)))
            started = (T0 + _dt.timedelta(hours=index)).isoformat()
            run = dataclasses.replace(base, header={**base.header, "started": started}, records=records)
            history.add(run, Origin(f"{index + 1:040x}", False, started))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, nargs="?", default=None)
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        if args.results is None:
            args.results = Path(scratch) / "default"
            subprocess.run([str(Path(sys.executable).with_name("xval")), "run", str(ROOT / "suites" / "default.toml"),
                            "--output", str(args.results), "--jobs", "2", "--quiet"], check=True)
        history = Path(scratch) / "history.sqlite"
        history_of(args.results, args.runs, history)
        page = args.output or Path(scratch) / "trend.html"
        written = write_history_report(str(history), page)
        print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
        print(f"trend page of {written.runs} runs of {args.results}: {written.size / 1e6:.2f} MB, written in "
              f"{written.seconds:.2f} s, {written.steps} step changes")
        if CHROMIUM is None:
            print("no chromium: the browser timings are left out (apt-get install -y chromium)")
            return
        ready, first = [], []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory() as profile, Page(page, Path(profile) / "p") as browser:
                ready.append(browser.ready_ms / 1000)
                started = time.perf_counter()
                # Scrolled to the first plot: plotly.js is unpacked and the plots near it are drawn.
                browser.evaluate('document.querySelector("div.xval-plot").scrollIntoView()')
                browser.wait('Number(document.getElementById("xval-render-status").getAttribute("data-drawn")) >= 1', 120)
                first.append(time.perf_counter() - started)
                if browser.errors():
                    raise SystemExit(f"console errors: {browser.errors()}")
        print(f"interactive after {statistics.median(ready):.2f} s (median of {args.repeats}; worst {max(ready):.2f} s); "
              f"the first plot drawn {statistics.median(first):.2f} s after it is scrolled to")
        print(f"load average after {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
