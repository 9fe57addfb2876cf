"""Size of a report and how soon it is interactive in headless chromium (the figures docs/report.md quotes).

    .venv/bin/python scripts/report_timing.py results/default/report.html results/stiff/report.html [--repeats 5]

For each report: its size in MB, and over ``--repeats`` fresh browser
profiles (network off, 1300 × 1000 px), the median and worst time from
navigation start until the page says it is interactive (its status
element's ``data-ready-ms``: parsed, every table sortable and filterable,
the verdict drawn), then how long opening the first scene's plots takes
(unpacking plotly.js and drawing them). The machine's load average is
printed beside, since a busy machine stretches every browser timing.
Needs chromium (``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from browser_support import CHROMIUM, Page  # noqa: E402


def measure(report: Path, repeats: int) -> dict[str, float]:
    ready, plots = [], []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as profile, Page(report, Path(profile) / "p") as page:
            if page.evaluate('document.getElementById("xval-render-status").getAttribute("data-state")') != "ready":
                raise SystemExit(f"{report}: the page did not become ready: {page.errors()}")
            ready.append(page.ready_ms / 1000)
            started = time.perf_counter()
            page.evaluate('document.getElementById("plots-0").open = true')  # as a click on its summary does
            page.wait('document.querySelectorAll("#plots-0 div.xval-plot[data-drawn-traces]").length === '
                      'document.querySelectorAll("#plots-0 div.xval-plot").length', 120)
            plots.append(time.perf_counter() - started)
            if page.errors():
                raise SystemExit(f"{report}: console errors: {page.errors()}")
    return {"size_mb": report.stat().st_size / 1e6, "ready_median": statistics.median(ready),
            "ready_max": max(ready), "plots_median": statistics.median(plots)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", nargs="+", type=Path)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    if CHROMIUM is None:
        raise SystemExit("no chromium: apt-get install -y chromium")
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
    print(f"{'report':<44} {'size/MB':>8} {'interactive/s (median, max)':>28} {'first scene plots/s':>20}")
    for report in args.reports:
        m = measure(report, args.repeats)
        print(f"{str(report):<44} {m['size_mb']:>8.2f} {m['ready_median']:>18.2f}, {m['ready_max']:<8.2f} "
              f"{m['plots_median']:>20.2f}")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
