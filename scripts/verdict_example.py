"""The worked example of docs/report.md ("How the verdict is reached"): a cost model, a cost to reach with
its interval, a ratio or a tie, and the consistency rule, on CPU times recorded from a real run of the
default suite (tests/fixtures/cost_samples.json, run 1, written by scripts/cost_samples.py).

    .venv/bin/python scripts/verdict_example.py
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from compare.results.consistency import DEFAULT_TOLERANCE  # noqa: E402
from compare.results.cost import RESOLUTION, case_cost  # noqa: E402
from compare.results.sweep import sweeps  # noqa: E402
from compare.results.verdict import scene_verdicts  # noqa: E402
from test_verdict_stability import RUNS, record  # noqa: E402


def main() -> None:
    rows = RUNS[0]
    found = sweeps([record(row, row["cpu_times"]) for row in rows])
    by_key = {(s.scene_id, s.engine): s for s in found}

    hinge = by_key[("bead", "mujoco/hinge-rk4")]
    print("1. cost model of mujoco/hinge-rk4 on the bead (CPU time of each run, 3 repeats)")
    print("   dt/s       steps  least CPU/s  spread")
    for r in sorted(hinge.ok_records, key=lambda r: -r.case.dt):
        c = case_cost(r)
        print(f"   {r.case.dt:<9.3g} {c.steps:>6}  {c.cpu_min:11.3e}  {c.spread:6.0%}")
    model = hinge.cost
    print(f"   Theil-Sen fit T = a + c·steps: c = {model.describe()}, a = {model.overhead:.2g} s")
    print(f"   (interval: {RESOLUTION:g}× either side of c, or the fits leaving out one case each where wider)")
    per_step: dict[tuple[str, str], list[float]] = {}
    for run in RUNS:
        for sweep in sweeps([record(row, row["cpu_times"]) for row in run]):
            if sweep.cost is not None:
                per_step.setdefault((sweep.scene_id, sweep.engine), []).append(sweep.cost.per_step)
    spread = {key: max(v) / min(v) for key, v in per_step.items()}
    worst = max(spread, key=spread.__getitem__)
    print(f"   one variant's c across the fixture's {len(RUNS)} runs: up to {spread[worst]:.2f}× apart "
          f"({worst[1]} on the {worst[0]}) < {RESOLUTION:g}² = {RESOLUTION ** 2:.2g}")
    print(f"   cost per simulated s at dt 1e-3 s = c / dt = {model.per_step / 1e-3:.3g} s/s "
          f"[{model.low / 1e-3:.3g}, {model.high / 1e-3:.3g}]")

    verdict = {v.scene_id: v for v in scene_verdicts(found, focus="ours")}["bead"]
    print("\n2. cost to reach 1e-6·L = 1e-06 m on the bead, cheapest first (steps per simulated s at the crossing)")
    for reach in sorted((r for r in verdict.reaches if r.reached), key=lambda r: r.cost):
        print(f"   {reach.engine:<25} {reach.steps:5.0f} steps/s  {reach.describe()}")
    named = verdict.comparison.focus
    print(f"   ours' tie (intervals linked to the cheapest's): {', '.join(sorted([named.engine, *verdict.comparison.focus_ties]))}; "
          f"named by the fewest steps: {named.engine}")
    comparison = verdict.comparison
    print(f"   ratio = {comparison.ratio:.3g} [{comparison.ratio_low:.3g}, {comparison.ratio_high:.3g}]; "
          f"tie: {comparison.tie}")
    print(f"   {comparison.describe()}")

    p2p = by_key[("double-pendulum", "pybullet/p2p-dantzig")]
    print("\n3. consistency of pybullet/p2p-dantzig on the double pendulum (L = 2 m)")
    points = sorted((r.case.dt, r.metric("position_error_linf")) for r in p2p.ok_records)
    print("   dt/s       error/m    local order to the next coarser dt")
    for (dt, e), (dt2, e2) in zip(points, points[1:] + [(math.nan, math.nan)]):
        order = math.log(e2 / e) / math.log(dt2 / dt) if not math.isnan(dt2) else math.nan
        print(f"   {dt:<9.3g}  {e:.3e}  {'' if math.isnan(order) else f'{order:.2f}'}")
    bar = p2p.ok_records[0].reference["reference_error"]
    print(f"   explained by: 10 × the reference's error bar = {10 * bar:.2g} m? no; the tolerance "
          f"{DEFAULT_TOLERANCE:g}·L = {DEFAULT_TOLERANCE * 2:.2g} m? no; a declared floor? none")
    print(f"   consistent = {p2p.consistency.consistent}: {p2p.consistency.reason}")


if __name__ == "__main__":
    main()
