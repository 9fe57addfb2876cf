"""Where a step of ours' rigid bodies goes: a per-stage profile on the KUKA iiwa.

The KUKA iiwa (pybullet_data's kuka_iiwa/model.urdf, 7 moving bodies, translated by engines/ours/model.py) at
q = 0.3 rad per joint, at rest, dt 1e-3 s. Each stage of the compiled derivative (ours.rigid.kernel) is
timed as the difference between two compiled loops that run the derivative's stages up to it and up to the
one before, from the same state every time (so no stage sees another's output drift). A step of each
method is timed on a 500-step run from that state. Figures are thread CPU time, the least of the repeats,
per call; the shares are of one symplectic-Euler step, so that they compare across machines.

Allocations: the kernel is compiled without numba's runtime (``ours.banded``: ``_nrt`` off), in which
an array allocation does not compile, so a step cannot allocate; the Python side of a call
(``Stepping.advance``, once per sample) is counted with tracemalloc.

The A1 quadruped of bench/bench_rigid.py (its base floating) with ``--model a1``.

    .venv/bin/python bench/profile_rigid.py [--repeats 9] [--model kuka|a1]
"""

from __future__ import annotations

import argparse
import os
import sys
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import numpy as np  # noqa: E402

from bench_ours import fastest  # noqa: E402
from numba import njit  # noqa: E402

from ours.banded import _NO_RUNTIME  # noqa: E402
from ours.rigid import Stepping, initial_state, pack, workspace  # noqa: E402
from ours.rigid import kernel as K  # noqa: E402
from ours.rigid.method import resolve  # noqa: E402

#: Compiled afresh on each run, not cached: numba's cache of this file would not see the kernel change.
profiled = njit(cache=False, fastmath={"contract"}, error_model="numpy", **_NO_RUNTIME)
#: The derivative's stages in the order it runs them: (name, what it computes).
STAGES = (
    ("rotations", "R = R(Q) per body, the quaternion normalised on the fly"),
    ("joint rows", "Jacobian blocks J_A, J_B, the residual C and J̇u of every joint"),
    ("forces", "gravity and the gyroscopic term −ω × I_w ω"),
    ("row targets", "−J̇u − k_s C − k_d J u (Baumgarte's terms)"),
    ("mass blocks", "M per body: m 1 and I_w = R I Rᵀ"),
    ("elimination", "the tree's block Cholesky, leaves first, with the forward sweep of the right side"),
    ("back-substitution", "the backward sweep: u and λ"),
    ("rates", "ẏ: v, ½ (0, ω) ⊗ Q, u̇ and λ read out"),
)


@profiled
def _upto(y, model, work, ks, kd, ydot, stages, n):
    """Run the derivative's first ``stages`` stages n times at y (the same state each time)."""
    nb, R = model[0].shape[0], work[0]
    ok = True
    for _ in range(n):
        if stages >= 1:
            K.rotations(y, nb, R)
        if stages >= 2:
            K.joint_rows(y, model, R, work[1], work[2], work[3], work[4])
        if stages >= 3:
            K.forces(y, model, work)
        if stages >= 4:
            K.row_targets(y, model, work, ks, kd)
        if stages >= 5:
            K.assemble(model, work)
        if stages >= 6:
            ok = K.factor_and_sweep(model, work, work[7]) and ok
        if stages >= 7:
            K.sweep_up(model, work, work[7])
        if stages >= 8:
            K.rates(y, model, work, ydot)
    return ok


@profiled
def _integrate(y, nb, ydot, h, n):
    """n symplectic-Euler updates (kick, drift, quaternion exponential and renormalisation) from y."""
    for _ in range(n):
        K.kick_drift(y, nb, ydot, h)


def kuka():
    from engines.ours.model import translate
    from engines.model.source import resolve as resolve_source
    from engines.model.urdf import read

    description = read(resolve_source("pybullet_data:kuka_iiwa/model.urdf"))
    mech = translate(description).mechanism
    return mech, initial_state(mech, {j.name: 0.3 for j in description.moving_joints})


def a1():
    """bench/bench_rigid.py's floating-base quadruped (the Unitree A1, 12 revolute joints) at its first state."""
    from bench_rigid import quadruped_scene
    from engines.ours.model import OursStepper

    stepper = OursStepper(quadruped_scene(0.01), 1e-3, "baumgarte", "symplectic-euler")
    return stepper.model.mechanism, stepper.run.y.copy()


#: --model: (the mechanism and its state, its name in the table's title).
MODELS = {"kuka": (kuka, "KUKA iiwa"), "a1": (a1, "A1 quadruped (floating base)")}


def stage_seconds(mech, y0, repeats: int, n: int = 20_000) -> dict[str, float]:
    """s per call of each stage of the derivative (baumgarte gains), by differences of prefix loops."""
    model, work = pack(mech), workspace(mech, 1)
    ydot = np.zeros_like(y0)
    ks, kd = 100.0, 20.0
    _upto(y0, model, work, ks, kd, ydot, len(STAGES), 1)  # compile
    prefix = [0.0]
    for stages in range(1, len(STAGES) + 1):
        prefix.append(fastest(lambda: _upto(y0, model, work, ks, kd, ydot, stages, n), repeats) / n)  # noqa: B023
    out = {name: max(prefix[i + 1] - prefix[i], 0.0) for i, (name, _) in enumerate(STAGES)}
    y = y0.copy()
    _integrate(y, len(mech.bodies), ydot, 1e-3, 1)
    out["integration"] = fastest(lambda: _integrate(y.copy(), len(mech.bodies), ydot, 1e-3, n), repeats) / n
    out["derivative"] = prefix[-1]
    return out


def step_seconds(mech, y0, method: str, integrator: str, repeats: int, steps: int = 500) -> float:
    """s per step of a ``steps``-step run from y0 (the compiled loop alone)."""
    run = Stepping(mech, y0, 1e-3, method=method, integrator=integrator)

    def once():
        run.y[:] = y0
        run.status = "ok"
        run.advance(steps)

    return fastest(once, repeats) / steps


def python_allocations(mech, y0, calls: int = 200) -> float:
    """Blocks tracemalloc sees allocated and kept per ``Stepping.advance`` call of 10 steps (the harness's sample)."""
    run = Stepping(mech, y0, 1e-3, method="baumgarte", integrator="symplectic-euler")
    run.advance(10)
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    for _ in range(calls):
        run.advance(10)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    kept = sum(s.count_diff for s in after.compare_to(before, "filename") if s.count_diff > 0)
    return kept / calls


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9, help="timed runs per figure; the least is kept")
    parser.add_argument("--model", choices=tuple(MODELS), default="kuka", help="the model profiled (default kuka)")
    args = parser.parse_args(argv)
    build, title = MODELS[args.model]
    mech, y0 = build()
    resolve("baumgarte", "symplectic-euler")
    steps = {f"{m}-{i}": step_seconds(mech, y0, m, i, args.repeats)
             for m, i in (("baumgarte", "symplectic-euler"), ("plain", "symplectic-euler"),
                          ("projection", "symplectic-euler"), ("baumgarte", "rk4"), ("projection", "rk4"))}
    stages = stage_seconds(mech, y0, args.repeats)
    euler = steps["baumgarte-symplectic-euler"]
    print(f"{title} ({len(mech.bodies)} bodies, {len(mech.joints)} joints), dt 1e-3 s: thread CPU per call, "
          f"least of {args.repeats}; share = of one baumgarte-symplectic-euler step ({euler * 1e6:.2f} µs)")
    print("| stage | µs | share of a step |")
    print("|---|---|---|")
    for name, _ in STAGES:
        print(f"| {name} | {stages[name] * 1e6:.3f} | {stages[name] / euler:.1%} |")
    print(f"| integration (kick, drift, quaternion exp and renormalisation) | {stages['integration'] * 1e6:.3f} | "
          f"{stages['integration'] / euler:.1%} |")
    print(f"| derivative, all stages | {stages['derivative'] * 1e6:.3f} | {stages['derivative'] / euler:.1%} |")
    print(f"| projection (factor and iterations), per step: projection − plain | "
          f"{(steps['projection-symplectic-euler'] - steps['plain-symplectic-euler']) * 1e6:.3f} | "
          f"{(steps['projection-symplectic-euler'] - steps['plain-symplectic-euler']) / euler:.1%} |")
    print("\n| step | µs | / baumgarte-symplectic-euler |")
    print("|---|---|---|")
    for name, seconds in steps.items():
        print(f"| {name} | {seconds * 1e6:.2f} | {seconds / euler:.2f} |")
    print(f"\nallocations: none in a compiled step (compiled without numba's runtime); "
          f"{python_allocations(mech, y0):.2f} Python blocks kept per Stepping.advance call")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
