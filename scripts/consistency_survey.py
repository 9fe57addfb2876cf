"""The consistency rule over stored runs: every variant it does not call consistent, with its plateau and why.

    .venv/bin/python scripts/consistency_survey.py RESULTS_DIR [RESULTS_DIR ...] [--detail]

docs/findings.md ("The consistency rule on the built-in suites") quotes what it prints for the default,
mechanisms, stiff and peers suites (`xval run suites/default.toml --output results/default`, likewise the
others). With --detail it lists only the inconsistent variants and those consistent at a precision floor
their engine declares, and counts the not-judged ones by reason; each inconsistent one is followed by its
ok runs — dt (or tolerance), max position error, constraint error, energy drift: the cause read off (a
floor, or an error that grows) — and the verdict on its siblings on that scene, the variants whose label
extends its own (mujoco/connect-rk4 -> mujoco/connect-rk4-stiff): one setting apart.
"""

from __future__ import annotations

import sys
from collections import Counter

from compare.run.results import load_results
from compare.results.sweep import VariantSweep


def _detail(sweep: VariantSweep) -> list[str]:
    rows = sorted(sweep.ok_records, key=lambda r: -(r.case.tolerance or r.case.dt))
    return [f"      {'tol' if r.case.tolerance is not None else 'dt'} {r.case.tolerance or r.case.dt:<9.3g} "
            f"error {r.metric('position_error_linf'):.3g} m  constraint error {r.metric('constraint_error'):.3g} m  "
            f"energy drift {r.metric('energy_drift'):.3g} E*" for r in rows]


def _siblings(sweep: VariantSweep, every: list[VariantSweep]) -> list[str]:
    found = [s for s in every if s.scene_id == sweep.scene_id and s.engine.startswith(sweep.engine + "-")]
    return [f"      sibling {s.engine}: consistent {s.consistency.consistent} ({s.consistency.reason})"
            for s in found if s.consistency is not None]


def survey(directory: str, detail: bool = False) -> list[str]:
    """One line per scene × variant that is not consistent (False or not judged), and a count; with ``detail``,
    the inconsistent ones only, each with its runs and siblings, and the not-judged ones counted by reason."""
    results = load_results(directory)
    lines, judged, unjudged = [], 0, Counter()
    every = results.sweeps()
    for sweep in every:
        verdict = sweep.consistency
        if verdict is None or sweep.is_reference or sweep.all_skipped:
            continue
        judged += 1
        if verdict.consistent is False or (verdict.consistent is None and not detail):
            state = "inconsistent" if verdict.consistent is False else "not judged"
            lines.append(f"  {sweep.scene_id:<18} {sweep.engine:<34} {state:<12} {verdict.reason}")
            lines.extend(_detail(sweep) + _siblings(sweep, every) if detail else [])
        elif detail and verdict.consistent and "declared precision floor" in verdict.reason:
            lines.append(f"  {sweep.scene_id:<18} {sweep.engine:<34} {'at its floor':<12} {verdict.reason}")
        elif verdict.consistent is None:
            unjudged["the reference is chaotic within the run" if "chaotic" in verdict.reason
                      else "fewer than two ok runs with an error"] += 1
    name = results.header["suite"]["name"]
    if not detail:
        return [f"{name}: {judged} variants judged, {len(lines)} not consistent", *lines]
    inconsistent = sum(1 for line in lines if " inconsistent " in line)
    head = f"{name}: {judged} variants judged, {inconsistent} inconsistent, {sum(unjudged.values())} not judged"
    return [head, *lines, *(f"  not judged, {why}: {n}" for why, n in unjudged.most_common())]


if __name__ == "__main__":
    paths = [a for a in sys.argv[1:] if a != "--detail"]
    for path in paths:
        print("\n".join(survey(path, "--detail" in sys.argv)))
