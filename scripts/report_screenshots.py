"""The screenshots docs/report.md shows: a report's first screen at 1400 × 900, as a new user opens it.

    .venv/bin/python scripts/report_screenshots.py results/default/report.html=default results/models/report.html=models

Each REPORT=NAME writes docs/images/report-NAME.png: headless chromium (tests/browser_support.py, network off),
1400 × 900 px, the page from its top. A NAME ending in ``@SELECTOR`` (``models@#verdict-0``) starts the shot at
that element instead. Needs chromium (``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from browser_support import CHROMIUM, Page  # noqa: E402

#: The screen of issue 44: what must hold the summary.
WIDTH, HEIGHT = 1400, 900
IMAGES = ROOT / "docs" / "images"


def shoot(report: Path, name: str, selector: str | None) -> Path:
    target = IMAGES / f"report-{name}.png"
    with tempfile.TemporaryDirectory() as profile, Page(report, Path(profile) / "p", WIDTH, HEIGHT) as page:
        top = 0.0
        if selector:
            top = float(page.evaluate(f"document.querySelector({selector!r}).getBoundingClientRect().top + scrollY"))
        page.screenshot(target, HEIGHT, top)
        if page.errors():
            raise SystemExit(f"{report}: console errors: {page.errors()}")
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("shots", nargs="+", help="REPORT=NAME or REPORT=NAME@SELECTOR")
    args = parser.parse_args()
    if CHROMIUM is None:
        raise SystemExit("no chromium: apt-get install -y chromium")
    for shot in args.shots:
        report, _, name = shot.partition("=")
        name, _, selector = name.partition("@")
        if not report or not name:
            raise SystemExit(f"{shot!r}: expected REPORT=NAME or REPORT=NAME@SELECTOR")
        print(shoot(Path(report), name, selector or None).relative_to(ROOT))


if __name__ == "__main__":
    main()
