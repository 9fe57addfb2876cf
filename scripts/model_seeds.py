"""Whether any ``xval model check`` verdict changes with ``--seed``: the survey's two sets at seeds 0 to 4.

Run: ``.venv/bin/python scripts/model_seeds.py`` (five surveys of both sets at ``xval model check``'s default
100 states, 2 jobs: 4.5 to 6 min on 2 shared cores, 2.6 min at 20 states; most of it is the engines' imports, one
child process per engine and file, not the states). The sets are scripts/model_survey.py's
(``model_sets``). A file's verdict at a seed is its survey row's outcome
and the engines it names (those that disagree, crashed): the same at every seed, or the file is listed with
its verdict per seed. Prints per set the files and how many have one verdict at every seed.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_survey import model_sets  # noqa: E402
from quoted import Row, report  # noqa: E402

from compare.model.survey import SurveyRow, survey  # noqa: E402

DOC = "docs/models.md"
SEEDS = range(5)
#: States per check, ``xval model check``'s default (the verdicts users see): the sample's scales (S_M, S_b, S_a)
#: and the amplification come from these.
STATES = 100
SETS = ("pybullet_data", "gymnasium")
#: Every figure is slow (five surveys): the quote test checks only that the doc has the rows.
SLOW = {f"{name}.{key}" for name in SETS for key in ("files", "identical")}


def verdict(row: SurveyRow) -> str:
    """A file's verdict: its outcome and the engines it names."""
    return f"{row.outcome} ({', '.join(row.engines)})" if row.engines else row.outcome


def differing(models: list[str]) -> list[tuple[str, list[str]]]:
    """Each file of ``models`` whose verdict is not the same at every seed, with its verdict per seed."""
    verdicts = [[verdict(row) for row in survey(models, states=STATES, seed=seed, timeout=60.0, jobs=2)]
                for seed in SEEDS]
    return [(model, [v[k] for v in verdicts]) for k, model in enumerate(models) if len({v[k] for v in verdicts}) > 1]


def figures(quick: bool = False) -> dict[str, float]:
    found: dict[str, float] = {}
    table = [f"| set | files | same verdict at seeds {SEEDS[0]}–{SEEDS[-1]} |", "|---|---|---|"]
    for name, models, root in [] if quick else model_sets():
        start = time.perf_counter()
        changed = differing(models)
        print(f"{name}: {len(SEEDS)} surveys of {len(models)} files in {time.perf_counter() - start:.0f} s")
        for model, seen in changed:
            print(f"  differs: {model.replace(root, name)}: " + "; ".join(f"seed {s}: {v}" for s, v in zip(SEEDS, seen)))
        table.append(f"| {name} | {len(models)} | {len(models) - len(changed)} |")
        found |= {f"{name}.files": float(len(models)), f"{name}.identical": float(len(models) - len(changed))}
    if found:
        print("\n" + "\n".join(table))
    return found


QUOTES: list = []
ROWS = [Row(DOC, name, (f"{name}.files", f"{name}.identical"), after="same verdict at seeds") for name in SETS]


def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
