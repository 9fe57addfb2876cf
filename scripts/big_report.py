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

from reports.render import write_report  # noqa: E402

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path)
    parser.add_argument("--report-only", action="store_true", help="render the results already in DIRECTORY/results")
    args = parser.parse_args()
    results = args.directory / "results"
    if not args.report_only:
        args.directory.mkdir(parents=True, exist_ok=True)
        suite = args.directory / "big.toml"
        suite.write_text(suite_text())
        xval = Path(sys.executable).with_name("xval")
        subprocess.run([str(xval), "run", str(suite), "--output", str(results)], check=True, cwd=ROOT,
                       stdout=subprocess.DEVNULL)
    written = write_report(results, args.directory / "report.html")
    cases = len(list((results / "cases").glob("*.json")))
    scenes = len(RADII) * len(ANGLES)
    print(f"cases {cases}; report {written.size / 1e6:.2f} MB, {written.size / 1e6 / scenes:.3f} MB per scene; "
          f"rendered in {written.seconds:.1f} s")


if __name__ == "__main__":
    main()
