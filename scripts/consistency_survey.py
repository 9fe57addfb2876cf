"""The consistency rule over stored runs: every variant it does not call consistent, with its plateau and why.

    .venv/bin/python scripts/consistency_survey.py RESULTS_DIR [RESULTS_DIR ...]

docs/findings.md ("The consistency rule on the built-in suites") quotes what it prints for the default and
mechanisms suites (`xval run suites/default.toml --output results/default`, likewise mechanisms).
"""

from __future__ import annotations

import sys

from compare.results.store import load_results


def survey(directory: str) -> list[str]:
    """One line per scene × variant that is not consistent (False or not judged), and a count."""
    results = load_results(directory)
    lines, judged = [], 0
    for sweep in results.sweeps():
        verdict = sweep.consistency
        if verdict is None or sweep.is_reference or sweep.all_skipped:
            continue
        judged += 1
        if verdict.consistent is not True:
            state = "inconsistent" if verdict.consistent is False else "not judged"
            lines.append(f"  {sweep.scene_id:<18} {sweep.engine:<34} {state:<12} {verdict.reason}")
    name = results.header["suite"]["name"]
    return [f"{name}: {judged} variants judged, {len(lines)} not consistent", *lines]


if __name__ == "__main__":
    for path in sys.argv[1:]:
        print("\n".join(survey(path)))
