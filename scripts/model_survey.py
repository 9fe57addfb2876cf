"""Survey pybullet_data's and gymnasium's robot models with ``xval model survey``: the table of counts in
docs/models.md.

Run: ``.venv/bin/python scripts/model_survey.py`` (about a minute on 2 cores). pybullet_data's set
(:func:`pybullet_data_set`) is every URDF in it with two or more moving joints (revolute, continuous or
prismatic, counted in the text, so files that are not well-formed XML are in it too) and every MJCF file (root
``<mujoco>``); gymnasium's (:func:`gymnasium_set`) every MJCF file in its ``envs/mujoco/assets``. Prints each
file's row, then the counts per outcome and set (100 states, seed 0, 2 jobs).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Row, Tolerance, report  # noqa: E402

from compare.model.survey import OUTCOMES, counts, survey  # noqa: E402

DOC = "docs/models.md"
_MOVING = re.compile(r"""type\s*=\s*["'](?:revolute|continuous|prismatic)["']""")
SETS = ("pybullet_data", "gymnasium")
KEYS = ("files", *(o.replace(" ", "_") for o in OUTCOMES))
#: Every count is slow (the whole survey): the quote test checks only that the doc has the row.
SLOW = {f"{name}.{key}" for name in SETS for key in KEYS}


def pybullet_data_set() -> list[str]:
    """Paths of the URDFs with at least two moving joints and of the MJCF files in pybullet_data, sorted."""
    import pybullet_data

    root = Path(pybullet_data.getDataPath())
    urdf = [p for p in root.rglob("*.urdf") if len(_MOVING.findall(p.read_text(errors="replace"))) >= 2]
    mjcf = [p for p in root.rglob("*.xml") if b"<mujoco" in p.read_bytes()]
    return sorted(str(p) for p in urdf + mjcf)


def gymnasium_assets() -> Path:
    """gymnasium's folder of MuJoCo models (gymnasium is in the test extra)."""
    import gymnasium

    return Path(gymnasium.__file__).resolve().parent / "envs" / "mujoco" / "assets"


def gymnasium_set() -> list[str]:
    """Paths of the MJCF files in gymnasium's ``envs/mujoco/assets``, sorted."""
    return sorted(str(p) for p in gymnasium_assets().rglob("*.xml") if b"<mujoco" in p.read_bytes())


def model_sets() -> list[tuple[str, list[str], str]]:
    """Each set's (name, files, root folder): the root is replaced by the name when a file is printed."""
    import pybullet_data

    return [("pybullet_data", pybullet_data_set(), pybullet_data.getDataPath()),
            ("gymnasium", gymnasium_set(), str(gymnasium_assets()))]


def figures(quick: bool = False) -> dict[str, float]:
    if quick:
        return {}
    found: dict[str, float] = {}
    lines = []
    for name, models, root in model_sets():
        rows = survey(models, states=100, seed=0, timeout=60.0, jobs=2)
        for row in rows:
            print(f"{row.model.replace(root, name)}: {row.outcome} {', '.join(row.engines)} {row.reason[:160]}")
        totals = counts(rows)
        lines.append(f"| {name} | {len(rows)} | " + " | ".join(str(totals[o]) for o in OUTCOMES) + " |")
        found |= {f"{name}.files": float(len(rows)), **{f"{name}.{o.replace(' ', '_')}": float(n)
                                                         for o, n in totals.items()}}
    print("\n| set | files | " + " | ".join(OUTCOMES) + " |\n|---|---|" + "---|" * len(OUTCOMES))
    print("\n".join(lines))
    return found


#: A file whose largest difference lies near the derived tolerance could change class with another machine's
#: round-off (BLAS, CPU): one file either way per class; the number of files is exact.
_ONE_FILE = Tolerance(why="a file near the agreement tolerance may change class with another machine's round-off",
                      absolute=1.0)
QUOTES: list = []
ROWS = [Row(DOC, name, tuple(f"{name}.{key}" for key in KEYS), after="## Surveying many files",
            tolerances={f"{name}.{key}": _ONE_FILE for key in KEYS[1:]}) for name in SETS]


def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
