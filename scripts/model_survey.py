"""Survey pybullet_data's robot models with ``xval model survey``: the table of counts in docs/models.md.

Run: ``.venv/bin/python scripts/model_survey.py`` (about a minute on 2 cores). The set (:func:`pybullet_data_set`)
is every URDF in pybullet_data with two or more moving joints (revolute, continuous or prismatic, counted in
the text, so files that are not well-formed XML are in it too) and every MJCF file (root ``<mujoco>``). Prints
each file's row, then the counts per outcome (100 states, seed 0, 2 jobs).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Row, report  # noqa: E402

from compare.model.survey import OUTCOMES, counts, survey  # noqa: E402

DOC = "docs/models.md"
_MOVING = re.compile(r"""type\s*=\s*["'](?:revolute|continuous|prismatic)["']""")
#: Every count is slow (the whole survey): the quote test checks only that the doc has the row.
SLOW = {f"pybullet_data.{key}" for key in ("files", *OUTCOMES)}


def pybullet_data_set() -> list[str]:
    """Paths of the URDFs with at least two moving joints and of the MJCF files in pybullet_data, sorted."""
    import pybullet_data

    root = Path(pybullet_data.getDataPath())
    urdf = [p for p in root.rglob("*.urdf") if len(_MOVING.findall(p.read_text(errors="replace"))) >= 2]
    mjcf = [p for p in root.rglob("*.xml") if b"<mujoco" in p.read_bytes()]
    return sorted(str(p) for p in urdf + mjcf)


def figures(quick: bool = False) -> dict[str, float]:
    if quick:
        return {}
    import pybullet_data

    models = pybullet_data_set()
    rows = survey(models, states=100, seed=0, timeout=60.0, jobs=2)
    root = pybullet_data.getDataPath()
    for row in rows:
        print(f"{row.model.replace(root, 'pybullet_data')}: {row.outcome} {', '.join(row.engines)} {row.reason[:160]}")
    totals = counts(rows)
    print("\n| set | files | " + " | ".join(OUTCOMES) + " |\n|---|---|" + "---|" * len(OUTCOMES))
    print(f"| pybullet_data | {len(rows)} | " + " | ".join(str(totals[o]) for o in OUTCOMES) + " |")
    return {"pybullet_data.files": float(len(rows)), **{f"pybullet_data.{o}": float(n) for o, n in totals.items()}}


QUOTES: list = []
ROWS = [Row(DOC, "pybullet_data", ("pybullet_data.files", *(f"pybullet_data.{o}" for o in OUTCOMES)),
            after="## Surveying many files")]


def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
