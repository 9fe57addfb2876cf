"""Do reruns give the same verdict? Per scene, what each run's `xval verdict --format json` names, and whether it agrees.

    .venv/bin/python scripts/verdict_reruns.py RESULTS_DIR RESULTS_DIR [...]

Runs `xval verdict DIR --format json --front` on each directory (the document users get, with the front) and prints, per scene:
the focus family's winner with its ties against the best other engine with its ties, and the cost ratio with
its interval, per run; then whether every family's winner and ties, the comparison's two sides and the
equal-cost best are the same in every run, and whether every pair of ratio intervals overlaps. Last, the
largest run-to-run ratio of one variant's per-step CPU cost (what compare.results.cost.RESOLUTION covers),
and the verdict over all scenes: winners, ties and comparisons; the equal-cost best apart (a statement at
one measured budget, so a run within noise of it can fall either side). Then whether the Pareto front (each
point's variant and case, in order) is the same, listing each point on it in only some runs with its margin
where it is on it (the front is decided by measured costs: docs/metrics.md), and whether every other entry
of the JSON that names a variant, family or case is identical (text with its numbers masked), listing the
first that differ.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

XVAL = [sys.executable, "-c", "from compare.cli import main; main()"]


def document(directory: str) -> dict[str, Any]:
    out = subprocess.run([*XVAL, "verdict", directory, "--format", "json", "--front"], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def named(scene: dict[str, Any]) -> dict[str, Any]:
    """What one run's verdict names on one scene: winners with ties, the comparison's sides, the equal-cost best."""
    c = scene["comparison"]
    return {
        "winners": [(w["family"], w["engine"], tuple(w["ties"])) for w in scene["winners"]],
        "comparison": None if c is None else (c["focus"], tuple(c["focus_ties"]), c["other"], tuple(c["other_ties"])),
        "equal-cost best": [(b["family"], b["engine"], tuple(b["ties"])) for b in scene["equal_cost"]["best"]],
    }


def name_bearing(node: Any, names: set[str], path: str = "") -> dict[str, Any]:
    """Every entry of a verdict document that names a variant, family or case, by its path: values that are a
    name as they are, text that mentions one with its numbers masked (measured figures may move, names not)."""
    found: dict[str, Any] = {}
    if isinstance(node, dict):
        for key, value in node.items():
            found.update(name_bearing(value, names, f"{path}.{key}"))
    elif isinstance(node, list):
        for k, value in enumerate(node):
            found.update(name_bearing(value, names, f"{path}[{k}]"))
    elif isinstance(node, str) and (node in names or any(n in node for n in names)):
        found[path] = node if node in names else re.sub(r"[-+]?\d[\d.eE+-]*", "#", node)
    return found


def names_in(documents: list[dict[str, Any]]) -> set[str]:
    """The variant labels, families and case ids any of ``documents`` mentions."""
    found: set[str] = set()
    for doc in documents:
        for scene in doc["scenes"]:
            for model in scene["cost_models"] + scene["reach"]:
                found.update((model["engine"], model["engine"].split("/", 1)[0]))
            found.update(p["case"] for p in scene["front"])
    return found


def line(name: str, scene: dict[str, Any]) -> str:
    c = scene["comparison"]
    if c is None:  # no second family on this scene to compare with
        return f"  {name}: no comparison"
    # No ratio when one side never reaches the accuracy (a plateau, or no ok points).
    ratio = "none" if c["ratio"] is None else \
        f"{c['ratio']:.3g} [{c['ratio_interval'][0]:.3g}, {c['ratio_interval'][1]:.3g}]"
    return (f"  {name}: {c['focus']} (ties: {', '.join(c['focus_ties']) or 'none'}) vs "
            f"{c['other']} (ties: {', '.join(c['other_ties']) or 'none'}); ratio {ratio}{' tie' if c['tie'] else ''}")


def overlapping(intervals: list[list[float]]) -> bool:
    return all(a[0] <= b[1] and b[0] <= a[1] for a in intervals for b in intervals)


def main(directories: list[str]) -> None:
    documents = [document(d) for d in directories]
    names = [Path(d).name for d in directories]
    agreed, moved = True, []
    for k, scene in enumerate(documents[0]["scenes"]):
        print(f"{scene['scene']}:")
        runs = [doc["scenes"][k] for doc in documents]
        for name, run in zip(names, runs):
            print(line(name, run))
        views = [named(run) for run in runs]
        same = {key: all(v[key] == views[0][key] for v in views) for key in views[0]}
        intervals = [run["comparison"]["ratio_interval"] for run in runs
                     if run["comparison"] is not None and run["comparison"]["ratio_interval"] is not None]
        agreed = agreed and same["winners"] and same["comparison"] and overlapping(intervals)
        if not same["equal-cost best"]:
            moved.append(scene["scene"])
            for name, run in zip(names, runs):
                budget = run["equal_cost"]["budget"]
                changed = [b for j, b in enumerate(run["equal_cost"]["best"])
                           if any(v["equal-cost best"][j] != named(run)["equal-cost best"][j] for v in views)]
                print(f"  {name}: budget {budget:.3g} s/s; " + "; ".join(
                    f"{b['engine']} error {b['error']:.3g} m [{b['error_interval'][0]:.3g}, {b['error_interval'][1]:.3g}]"
                    + (f" (ties: {', '.join(b['ties'])})" if b["ties"] else "")
                    for b in changed if b["engine"] is not None))
        print("  same in every run: " + "; ".join(f"{key} {value}" for key, value in same.items())
              + f"; ratio intervals overlap: {overlapping(intervals)}")
    per_step: dict[tuple[str, str], list[float]] = {}
    for doc in documents:
        for scene in doc["scenes"]:
            for model in scene["cost_models"]:
                if model["how"] != "metric":
                    per_step.setdefault((scene["scene"], model["engine"]), []).append(model["per_step"])
    spread = {key: max(v) / min(v) for key, v in per_step.items() if len(v) == len(documents)}
    if spread:
        worst = max(spread, key=spread.__getitem__)
        print(f"largest run-to-run ratio of a per-step cost: {spread[worst]:.2f} ({worst[1]} on {worst[0]}, "
              f"{len(spread)} variants timed in every run)")
    fronts = [[[(p["engine"], p["case"]) for p in scene["front"]] for scene in doc["scenes"]] for doc in documents]
    jumped = [scene["scene"] for k, scene in enumerate(documents[0]["scenes"]) if any(f[k] != fronts[0][k] for f in fronts)]
    print(f"Pareto front the same in every run: {not jumped}" + (f" (not on {', '.join(jumped)})" if jumped else ""))
    for k in range(len(fronts[0])):
        cases = [{case for _, case in f[k]} for f in fronts]
        margins = [{p["case"]: p.get("margin") for p in doc["scenes"][k]["front"]} for doc in documents]
        for case in sorted(set().union(*cases) - set.intersection(*cases)):
            where = ", ".join("none" if m.get(case) is None else f"{m[case]:.2f}" for m in margins if case in m)
            print(f"  on the front in {sum(case in c for c in cases)} of {len(cases)} runs: {case} (margin {where})")
    names = names_in(documents)
    # The front apart (above): one point more shifts every later index.
    entries = [{path: v for path, v in name_bearing(doc, names).items() if ".front[" not in path} for doc in documents]
    differing = sorted(path for path in set().union(*entries) if any(e.get(path) != entries[0].get(path) for e in entries))
    for path in differing[:20]:
        print(f"  differs: {path}: " + " | ".join(str(e.get(path)) for e in entries))
    print(f"name-bearing entries besides the front identical in every run: {len(entries[0]) - len(differing)} of "
          f"{len(entries[0])}"
          f" -> {'yes' if not differing else 'no'}")
    print(f"winners, ties and comparisons the same in every run, ratio intervals overlapping: {agreed}")
    print(f"equal-cost best the same in every run: {not moved}" + (f" (not on {', '.join(moved)})" if moved else ""))


if __name__ == "__main__":
    main(sys.argv[1:])
