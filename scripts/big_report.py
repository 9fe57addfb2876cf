"""A big suite's report: 25 bead scenes × 18 engine variants × 7 time steps = 3,150 cases (docs/report.md).

    .venv/bin/python scripts/big_report.py /tmp/big            # writes the suite, runs it, renders the report
    .venv/bin/python scripts/big_report.py /tmp/big --report-only

Prints the number of cases, the report's size in MB, its size per scene and the render time (reading the
results included); scripts/report_timing.py then measures how soon the page is interactive in chromium.
The scenes vary the wire radius (0.5, 1, 1.5, 2, 2.5 m) and the release angle (20, 45, 60, 90, 120 deg).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from reports.render import LAZY_CHOSEN_MUTED, LAZY_SCENES, LAZY_SERIES, write_report  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
from quoted import load_quotes, report  # noqa: E402

RADII = (0.5, 1.0, 1.5, 2.0, 2.5)
ANGLES = (20, 45, 60, 90, 120)
VARIANTS = (
    "ours/baumgarte-rk4", "ours/baumgarte-midpoint", "ours/baumgarte-symplectic-euler", "ours/plain-rk4",
    "ours/plain-euler", "ours/projection-rk4", "ours/projection-midpoint", "ours/lagrangian-rk4", "ours/rattle",
    "mujoco/hinge", "mujoco/hinge-rk4", "mujoco/connect", "mujoco/hinge-implicit",
    "pybullet/multibody", "pybullet/p2p", "pybullet/p2p-dantzig",
    "pymunk/pin", "pymunk/pin-bias0",
)


def suite_text() -> str:
    lines = [
        'name = "big"',
        'description = "25 bead scenes (radius and release angle varied) x 18 variants x 7 time steps"',
        "duration = 2.0", "sample_interval = 0.01", "repeats = 1", "timeout = 120",
        "dt = { from = 1e-1, to = 1e-4, per_decade = 2 }",
        "[reference]", "rtol = 1e-12", "atol = 1e-12",
    ]
    for radius in RADII:
        for angle in ANGLES:
            lines += ["[[scenes]]", f'id = "bead-r{radius:g}-a{angle}"', 'scene = "bead"',
                      f"parameters = {{ radius = {radius}, theta0 = {angle} }}"]
    lines += ["[[engines]]", 'id = "reference/dop853"']
    for variant in VARIANTS:
        lines += ["[[engines]]", f'id = "{variant}"']
    return "\n".join(lines) + "\n"


#: The figures that need the suite run and rendered (minutes): tests/test_docs_figures.py checks only that the
#: doc quotes them.
SLOW = {"cases", "report_mb", "mb_per_scene"}


def measure(directory: Path, report_only: bool = False) -> dict[str, float]:
    """Run the suite into DIRECTORY/results (unless ``report_only``) and render it: cases, MB, MB per scene, s."""
    results = directory / "results"
    if not report_only:
        directory.mkdir(parents=True, exist_ok=True)
        suite = directory / "big.toml"
        suite.write_text(suite_text())
        xval = Path(sys.executable).with_name("xval")
        subprocess.run([str(xval), "run", str(suite), "--output", str(results)], check=True, cwd=ROOT,
                       stdout=subprocess.DEVNULL)
    written = write_report(results, directory / "report.html")
    scenes = len(RADII) * len(ANGLES)
    return {"cases": len(list((results / "cases").glob("*.json"))), "report_mb": written.size / 1e6,
            "mb_per_scene": written.size / 1e6 / scenes, "render_s": written.seconds}


def figures(quick: bool = False, directory: Path = Path("/tmp/big"), report_only: bool = False) -> dict[str, float]:
    """The figures docs/report.md quotes: the big-suite settings of reports/render.py and, unless ``quick``, the
    measured report (see :func:`measure`)."""
    found: dict[str, float] = {"lazy_scenes": LAZY_SCENES, "lazy_points": LAZY_SERIES[0],
                               "lazy_digits": LAZY_SERIES[1], "lazy_grey_points": LAZY_SERIES[2],
                               "lazy_chosen_grey_points": LAZY_CHOSEN_MUTED}
    if not quick:
        found.update(measure(directory, report_only))
    return found


QUOTES = load_quotes(__file__)
ROWS: list = []


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path)
    parser.add_argument("--report-only", action="store_true", help="render the results already in DIRECTORY/results")
    args = parser.parse_args()
    found = figures(False, args.directory, args.report_only)
    print(f"cases {found['cases']}; report {found['report_mb']:.2f} MB, {found['mb_per_scene']:.3f} MB per scene; "
          f"rendered in {found['render_s']:.1f} s")
    report(found, QUOTES, ROWS)


if __name__ == "__main__":
    main()
