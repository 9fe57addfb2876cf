"""Cost of ours' forward sensitivities (ours/sensitivity.py) against its plain step and MuJoCo's mjd_transitionFD.

The double pendulum released at (90°, 0°), and a chain of 8 links (its J W Jᵀ solved by banded Cholesky, where
the double pendulum's 2 × 2 is solved in closed form), dt 1e-3 s, STEPS steps, in one run:

- ours' plain step, per variant (baumgarte-rk4, projection-rk4, rattle, lagrangian-rk4; on the chain
  baumgarte-rk4 and rattle): ``ours.simulate`` of STEPS steps (one
  sample at the end), per step;
- ours' sensitivities for n directions (n = 1, 2, 4, 8: 8 is the whole state of two planar particles) by its
  tangent-linear step (``forward_sensitivities``: one run carries all n; the lagrangian method's in link
  angles), per step, and its ratio to the same
  variant's plain step beside the issue's budget of 2 + n steps' worth;
- for baumgarte-rk4 also: n = 4 physical parameters (g, m1, m2, l1: the model moves as well as the state), and
  the complex step (``complex_step_sensitivities``: one complex run per direction, the method it replaced and the
  tests' independent check) for n = 1 and 8;
- MuJoCo (hinge, Euler; its state has 2 nv = 4 entries): ``mj_step`` in a Python loop, per step, and
  ``mjd_transitionFD`` (centred, the whole 4 × 4 one-step Jacobian) followed by ``mj_step``, per step: what
  its chained derivative (engines/mujoco/gradients.py) costs, and its ratio to its own step.

Times are the minimum over REPEATS of the thread's CPU time (``time.thread_time``): the least disturbed run on
a shared machine. Ratios are within one run and one engine; across machines, compare ratios only.

    .venv/bin/python bench/bench_gradients.py [--repeats N] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import numpy as np  # noqa: E402

import ours  # noqa: E402
from bench_ours import fastest  # noqa: E402
from engines.ours.adapter import _to_system  # noqa: E402
from engines.scene import catalog  # noqa: E402
from engines.ours.gradients import directions  # noqa: E402
from ours.sensitivity import complex_step_sensitivities, forward_sensitivities  # noqa: E402

DT = 1e-3
STEPS = 2000
REPEATS = 7
DIRECTIONS = (1, 2, 4, 8)


def best_cpu(work, repeats: int) -> float:
    """s: the least thread CPU time of ``repeats`` calls of ``work()`` (one uncounted call first: compiles)."""
    work()
    return fastest(work, repeats)


VARIANTS = (("baumgarte", "rk4"), ("projection", "rk4"), ("rattle", "rattle"), ("lagrangian", "rk4"))
PHYSICAL = ["g", "m1", "m2", "l1"]


def _row(what: str, n: int, work, plain: float, repeats: int) -> dict:
    """One row: ``work``'s cost per step (µs) and in steps' worth of ``plain`` (s per step)."""
    cost = best_cpu(work, repeats) / STEPS
    return {"what": what, "n": n, "us_per_step": cost * 1e6, "steps_worth": cost / plain, "budget": 2 + n}


def ours_rows(repeats: int, name: str = "double-pendulum", parameters: dict | None = None,
              variants=VARIANTS, label: str = "ours") -> list[dict]:
    """ours' rows on one catalog scene: per variant its plain step and its sensitivities for each n; for
    baumgarte-rk4 on the double pendulum also physical parameters and the complex step."""
    scene = catalog.build(name, parameters or {})
    system, q0, v0, _ = _to_system(scene)
    rng = np.random.default_rng(0)
    rows = []
    for method, integrator in variants:
        variant = f"{label} " + (method if method == integrator else f"{method}-{integrator}")
        settings = {"method": method, "integrator": integrator}
        plain = best_cpu(lambda s=settings: ours.simulate(system, q0, v0, DT, STEPS, STEPS, **s), repeats) / STEPS
        rows.append({"what": f"{variant} step", "n": 0, "us_per_step": plain * 1e6, "steps_worth": 1.0,
                     "budget": None})
        for n in DIRECTIONS:
            dq, dv = rng.standard_normal((n, *q0.shape)), rng.standard_normal((n, *v0.shape))
            rows.append(_row(f"{variant} sensitivities, n = {n}", n,
                             lambda dq=dq, dv=dv, s=settings: forward_sensitivities(system, q0, v0, dq, dv, DT, STEPS,
                                                                                    **s), plain, repeats))
        if method != "baumgarte" or name != "double-pendulum":
            continue
        moved = directions(scene, PHYSICAL, _to_system)
        rows.append(_row(f"  the same, n = {len(PHYSICAL)} physical ({', '.join(PHYSICAL)})", len(PHYSICAL),
                         lambda m=moved, s=settings: forward_sensitivities(*m[:5], DT, STEPS, dmodel=m[5], **s),
                         plain, repeats))
        for n in (1, 8):
            dq, dv = rng.standard_normal((n, *q0.shape)), rng.standard_normal((n, *v0.shape))
            rows.append(_row(f"  by complex step (before), n = {n}", n,
                             lambda dq=dq, dv=dv, s=settings: complex_step_sensitivities(system, q0, v0, dq, dv, DT,
                                                                                         STEPS, **s), plain, repeats))
    return rows


def mujoco_rows(repeats: int) -> list[dict]:
    try:
        import mujoco
    except ImportError:
        return [{"what": "MuJoCo not installed", "n": None, "us_per_step": None, "steps_worth": None, "budget": None}]
    from engines.mujoco.adapter import hinge_velocities
    from engines.registry import resolve

    engine, variant = resolve("mujoco/hinge")
    scene = catalog.build("double-pendulum", {})
    model, _, _ = engine.build(scene, DT, engine.resolve(variant, None))
    n = 2 * model.nv + model.na
    jacobian = np.empty((n, n))

    def plain() -> None:
        data = mujoco.MjData(model)
        data.qvel[:] = hinge_velocities(scene, model)
        for _ in range(STEPS):
            mujoco.mj_step(model, data)

    def chained() -> None:
        data = mujoco.MjData(model)
        data.qvel[:] = hinge_velocities(scene, model)
        for _ in range(STEPS):
            mujoco.mjd_transitionFD(model, data, 1e-6, True, jacobian, None, None, None)
            mujoco.mj_step(model, data)

    step = best_cpu(plain, repeats) / STEPS
    fd = best_cpu(chained, repeats) / STEPS
    return [{"what": "MuJoCo hinge Euler mj_step (Python loop)", "n": 0, "us_per_step": step * 1e6,
             "steps_worth": 1.0, "budget": None},
            {"what": f"MuJoCo mjd_transitionFD + mj_step, n = {n}", "n": n, "us_per_step": fd * 1e6,
             "steps_worth": fd / step, "budget": 2 + n}]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--json", type=Path, default=ROOT / "results" / "bench" / "bench_gradients.json")
    args = parser.parse_args()
    rows = (ours_rows(args.repeats)
            + ours_rows(args.repeats, "chain", {"n": 8}, (("baumgarte", "rk4"), ("rattle", "rattle")), "chain of 8: ours")
            + mujoco_rows(args.repeats))
    print(f"double pendulum (then a chain of 8), dt {DT} s, {STEPS} steps; min of {args.repeats} repeats of thread CPU time; "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'what':58} {'µs/step':>9} {'steps worth':>12} {'budget 2+n':>11}")
    for row in rows:
        us = "–" if row["us_per_step"] is None else f"{row['us_per_step']:.3g}"
        worth = "–" if row["steps_worth"] is None else f"{row['steps_worth']:.3g}"
        budget = "" if row["budget"] is None else f"{row['budget']}"
        print(f"{row['what']:58} {us:>9} {worth:>12} {budget:>11}")
    over = [row["what"].strip() for row in rows if row["budget"] is not None and not row["what"].startswith("MuJoCo")
            and "complex step" not in row["what"] and row["steps_worth"] > row["budget"]]  # physical rows too
    print("ours' tangent-linear sensitivities within 2 + n steps' worth: "
          + ("every row" if not over else "not for " + "; ".join(over)))
    ours_full = next(r for r in rows if r["what"] == "ours baumgarte-rk4 sensitivities, n = 4")
    fd = next((r for r in rows if r["what"].startswith("MuJoCo mjd_transitionFD")), None)
    if fd is not None and fd["us_per_step"]:
        print(f"ours' sensitivities for 4 directions against MuJoCo's mjd_transitionFD (4 × 4): "
              f"{ours_full['us_per_step'] / fd['us_per_step']:.3g}× its time per step")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"rows": rows, "load_average": os.getloadavg()}, indent=1))


if __name__ == "__main__":
    main()
