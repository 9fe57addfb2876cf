"""Speed of ours' rigid bodies (``ours.rigid``), measured against a peer in the same run.

1. N-scaling — chains of 4 … 256 revolute links (dt 1e-3 s): thread CPU time per step of
   baumgarte-rk4, baumgarte-symplectic-euler and projection-symplectic-euler, and the exponent p
   of cost ∝ Nᵖ fitted over the chains (least squares in log–log). Target p ≤ 1.1: the tree
   elimination makes a step O(N).
2. KUKA iiwa (7 bodies) — one step of ours against MuJoCo on the same model (pybullet_data's
   kuka_iiwa/model.urdf, read once by engines/model), MuJoCo stepping in C through ``mujoco.rollout``:
   ours' symplectic Euler against MuJoCo's Euler, ours' RK4 against MuJoCo's RK4, 0.5 s from rest at
   0.3 rad per joint. Target ≤ 5× for the default cure (baumgarte); the projection rows say what a
   factor and its iterations per step add (no target).
3. KUKA iiwa as the harness times it: suites/models.toml's kuka-iiwa scene run through each
   engine's ``Engine.simulate`` (bench/bench_models.py's ``stepping``: thread CPU of the sample-by-sample
   stepping, per step), ours/baumgarte-symplectic-euler against mujoco/hinge and ours/baumgarte-rk4
   against mujoco/hinge-rk4, the four taken in turns; a run's figure is the least of 5 such rounds, and
   5 runs give the ratio's median and spread (least–most). Target ≤ 1.0× for both.
4. A floating-base quadruped as the harness times it: pybullet_data's Unitree A1 (12 revolute joints) read with
   ``base = "floating"``, the same pairs timed the same way. ours steps the free root as a plain rigid body (no
   constraint row); MuJoCo as a free joint. Target ≤ 1.0× for both.
5. KUKA iiwa forward sensitivities (``ours.rigid.sensitivity``), per step in steps' worth of the same variant's
   real step, for baumgarte and projection with RK4 and symplectic Euler: the tangent-linear step
   (``forward_sensitivities``) carrying n = 1, 2, 4 and 8 directions, target ≤ 2 + n (the issue's budget), and one
   direction's complex run (``complex_step_sensitivities``, the tangent's check and ours' method before it).
6. The KUKA's whole one-step Jacobian (14 × 14) per step: MuJoCo's ``mjd_transitionFD`` then ``mj_step`` against
   ours' tangent-linear step carrying 14 directions, each in steps' worth of its own plain step, and their ratio.

Times are minima over repeats of thread CPU time (the least disturbed run on a shared machine);
compare ratios within a run, not across machines.

    .venv/bin/python bench/bench_rigid.py [--quick] [--json PATH]
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "bench"))

import numpy as np  # noqa: E402

from bench_ours import fastest  # noqa: E402
from ours.rigid import Stepping, initial_state  # noqa: E402
from rigid_support import chain  # noqa: E402

SCALING_TARGET = 1.1
KUKA_TARGET = 5.0
HARNESS_TARGET = 1.0
#: A real 12-joint quadruped whose URDF loads in ours and MuJoCo alike (laikago's links have no inertia).
QUADRUPED = "pybullet_data:a1/a1.urdf"
#: (ours, its MuJoCo peer) as bench/bench_models.py pairs them.
HARNESS_PAIRS = (("ours/baumgarte-symplectic-euler", "mujoco/hinge"), ("ours/baumgarte-rk4", "mujoco/hinge-rk4"))
VARIANTS = (("baumgarte", "rk4"), ("baumgarte", "symplectic-euler"), ("projection", "symplectic-euler"))


def ours_step_seconds(mech, y0, method: str, integrator: str, steps: int, repeats: int) -> float:
    """Thread CPU time of one step: the compiled loop alone (ours.rigid.Stepping, set up and compiled
    before timing), the least over ``repeats`` runs of ``steps`` steps."""
    run = Stepping(mech, y0, 1e-3, method=method, integrator=integrator)

    def once():
        run.y[:] = y0  # every repeat from the same state (a long free run of an arm could blow up)
        run.status = "ok"
        run.advance(steps)
        if run.status != "ok":
            raise RuntimeError(f"{method}-{integrator} stopped: {run.status}")

    return fastest(once, repeats) / steps


def scaling_rows(sizes, repeats: int) -> list[dict]:
    """Short runs (a few ms) and many of them: on a shared machine the least of them is a run that kept
    its CPU (and its cache) throughout; long runs of the big chains are preempted every time."""
    rows = []
    for method, integrator in VARIANTS:
        costs = []
        for n in sizes:
            mech = chain(n)
            y0 = initial_state(mech, {f"j{i}": 0.1 for i in range(n)})
            costs.append(ours_step_seconds(mech, y0, method, integrator, max(10, 2_000 // n), 3 * repeats))
        exponent = float(np.polyfit(np.log(sizes), np.log(costs), 1)[0])
        rows.append({"section": "scaling", "variant": f"{method}-{integrator}", "sizes": list(sizes),
                     "us_per_step": [c * 1e6 for c in costs], "exponent": exponent,
                     "target": SCALING_TARGET, "met": exponent <= SCALING_TARGET})
    return rows


def kuka_rows(repeats: int, steps: int = 500) -> list[dict]:
    """The KUKA from one description (engines/model): MuJoCo's import (damping, armature, limits off)
    and ours' translation of it, both from q = 0.3 rad at every joint, at rest."""
    import mujoco
    from mujoco import rollout

    from engines.mujoco import model as mujoco_model
    from engines.model.source import resolve
    from engines.model.urdf import read
    from engines.ours.model import translate

    source = resolve("pybullet_data:kuka_iiwa/model.urdf")
    description = read(source)
    peer = mujoco_model.load(source, description)
    model, data = peer.model, peer.data
    model.opt.timestep = 1e-3
    ours = translate(description)
    q0 = {j.name: 0.3 for j in description.moving_joints}
    y0 = initial_state(ours.mechanism, q0)
    rows = []
    for (method, integrator), (name, code) in (
        (("baumgarte", "symplectic-euler"), ("mujoco Euler", mujoco.mjtIntegrator.mjINT_EULER)),
        (("projection", "symplectic-euler"), ("mujoco Euler", mujoco.mjtIntegrator.mjINT_EULER)),
        (("baumgarte", "rk4"), ("mujoco RK4", mujoco.mjtIntegrator.mjINT_RK4)),
        (("projection", "rk4"), ("mujoco RK4", mujoco.mjtIntegrator.mjINT_RK4)),
    ):
        model.opt.integrator = code
        data.qpos[:] = 0.0
        data.qpos[peer.qpos] = [q0[j.name] for j in description.moving_joints]
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.zeros(mujoco.mj_stateSize(model, kind))
        mujoco.mj_getState(model, data, state, kind)
        out = np.zeros((1, steps, state.size))
        rollout.rollout(model, data, state[None], nstep=steps, state=out)  # warm
        theirs = fastest(lambda: rollout.rollout(model, data, state[None], nstep=steps, state=out), repeats) / steps  # noqa: B023 (timed here)
        mine = ours_step_seconds(ours.mechanism, y0, method, integrator, steps, repeats)
        rows.append({"section": "kuka", "variant": f"{method}-{integrator}", "peer": name,
                     "us_per_step": mine * 1e6, "peer_us_per_step": theirs * 1e6, "ratio": mine / theirs,
                     # the target is for a step of the default cure; projection adds a factor and its
                     # iterations to every step and is listed for what it costs, without a target
                     "target": KUKA_TARGET if method == "baumgarte" else None,
                     "met": mine / theirs <= KUKA_TARGET if method == "baumgarte" else True})
    return rows


#: The numbers of directions the tangent-linear step is timed with, each against the budget 2 + n.
DIRECTIONS = (1, 2, 4, 8)


def sensitivity_rows(repeats: int, steps: int = 500) -> list[dict]:
    """The KUKA from rest at 0.3 rad per joint: the real step (Stepping) against the tangent-linear step carrying
    n directions (forward_sensitivities) and one direction's complex run (complex_step_sensitivities), each compiled
    before timing, thread CPU per step, the least of ``repeats``; a call's setup (packing, scratch) is timed too."""
    from engines.model.source import resolve
    from engines.model.urdf import read
    from engines.ours.model import translate
    from ours.rigid.sensitivity import complex_step_sensitivities, forward_sensitivities

    description = read(resolve("pybullet_data:kuka_iiwa/model.urdf"))
    mech = translate(description).mechanism
    y0 = initial_state(mech, {j.name: 0.3 for j in description.moving_joints})
    directions = np.random.default_rng(0).normal(size=(max(DIRECTIONS), y0.size))
    rows = []
    for method, integrator in VARIANTS + (("projection", "rk4"),):
        real = ours_step_seconds(mech, y0, method, integrator, steps, repeats)

        def per_step(carry, n, method=method, integrator=integrator):
            def once():
                carry(mech, y0, directions[:n], 1e-3, steps, steps, method=method, integrator=integrator)

            once()  # compile, or load from numba's cache
            return fastest(once, repeats) / steps

        tangent = [per_step(forward_sensitivities, n) for n in DIRECTIONS]
        complex_step = per_step(complex_step_sensitivities, 1)
        worth = [t / real for t in tangent]
        rows.append({"section": "sensitivity", "variant": f"{method}-{integrator}", "us_per_step": real * 1e6,
                     "directions": list(DIRECTIONS), "tangent_us_per_step": [t * 1e6 for t in tangent],
                     "tangent_steps_worth": worth, "complex_us_per_step": complex_step * 1e6,
                     "steps_worth": complex_step / real,
                     "met": all(w <= 2 + n for w, n in zip(worth, DIRECTIONS))})
    return rows


def transition_rows(repeats: int, steps: int = 200) -> list[dict]:
    """The KUKA's whole one-step Jacobian, 2 nv × 2 nv (nv = 7), per step: MuJoCo's ``mjd_transitionFD`` (centred
    differences) then ``mj_step`` (Euler), against ours' tangent-linear step (baumgarte-symplectic-euler) carrying
    2 nv directions through its own step: both in steps' worth of their own plain step, and their ratio.
    Python loops on MuJoCo's side (its step and its derivative, as a user calls them), thread CPU."""
    import mujoco

    from engines.mujoco import model as mujoco_model
    from engines.model.source import resolve
    from engines.model.urdf import read
    from engines.ours.model import translate
    from ours.rigid.sensitivity import forward_sensitivities

    source = resolve("pybullet_data:kuka_iiwa/model.urdf")
    description = read(source)
    peer = mujoco_model.load(source, description)
    model, data = peer.model, peer.data
    model.opt.timestep = 1e-3
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    n = 2 * model.nv
    jacobian = np.empty((n, n))
    q0 = {j.name: 0.3 for j in description.moving_joints}

    def start() -> None:
        data.qpos[:] = 0.0
        data.qpos[peer.qpos] = [q0[j.name] for j in description.moving_joints]
        data.qvel[:] = 0.0

    def plain() -> None:
        start()
        for _ in range(steps):
            mujoco.mj_step(model, data)

    def chained() -> None:
        start()
        for _ in range(steps):
            mujoco.mjd_transitionFD(model, data, 1e-6, True, jacobian, None, None, None)
            mujoco.mj_step(model, data)

    plain()
    chained()
    step, fd = fastest(plain, repeats) / steps, fastest(chained, repeats) / steps
    mech = translate(description).mechanism
    y0 = initial_state(mech, q0)
    directions = np.random.default_rng(0).normal(size=(n, y0.size))
    real = ours_step_seconds(mech, y0, "baumgarte", "symplectic-euler", steps, repeats)

    def carried() -> None:
        forward_sensitivities(mech, y0, directions, 1e-3, steps, steps, method="baumgarte",
                              integrator="symplectic-euler")

    carried()
    tangent = fastest(carried, repeats) / steps
    return [{"section": "transition", "n": n, "mujoco_us_per_step": step * 1e6, "mujoco_fd_us_per_step": fd * 1e6,
             "mujoco_steps_worth": fd / step, "ours_us_per_step": real * 1e6, "ours_tangent_us_per_step": tangent * 1e6,
             "ours_steps_worth": tangent / real, "ratio": tangent / fd, "met": tangent / real <= 2 + n}]


def quadruped_scene(duration: float):
    """pybullet_data's Unitree A1 (12 revolute joints, full inertias) with its base floating, from the suite's
    reading of a URDF with ``base = "floating"``: legs crouched and swinging, the base moving and turning, gravity
    on (no contacts: it falls freely, which costs a step what standing would)."""
    from engines.model.scene import model_scene

    legs = ("FR", "FL", "RR", "RL")
    q0 = {f"{leg}_{part}_joint": angle for leg in legs for part, angle in (("hip", 5), ("upper", 40), ("lower", -80))}
    v0 = {f"{leg}_{part}_joint": rate * (1 + 0.2 * k) for k, leg in enumerate(legs)
          for part, rate in (("hip", 1.0), ("upper", 2.0), ("lower", -3.0))}
    return model_scene("a1", QUADRUPED, q0=q0, v0={**v0, "__floating_base__": [0.1, 0.0, 0.0, 0.2, 0.5, 0.1]},
                       duration=duration, root_joint="floating")


def harness_scenes(steps: int):
    """(label, scene, sample interval) of each model the harness section times: the KUKA iiwa from
    suites/models.toml and the floating-base quadruped, ``steps`` steps of dt 1e-3 s each."""
    from bench_models import DT, SCENE, SUITE
    from compare.suite.reader import load_suite

    suite = load_suite(SUITE)
    kuka = next(s for s in suite.scenes if s.id == SCENE).scene.with_duration(steps * DT)
    return (("KUKA iiwa", kuka, suite.sample_interval),
            ("A1 quadruped (floating base)", quadruped_scene(steps * DT), suite.sample_interval))


def harness_rows(model: str, scene, sample_interval: float, runs: int = 5, rounds: int = 5) -> list[dict]:
    """Per step as the harness times it: each run the least of ``rounds`` rounds taken in turns round the four
    variants (the whole of ``scene`` each), then the ratio's median and spread over ``runs`` runs."""
    import math

    from bench_models import engine_of, stepping

    ids = [i for pair in HARNESS_PAIRS for i in pair]
    engines = {i: engine_of(i) for i in ids}
    for engine, variant in engines.values():  # numba loading ours' kernels, each engine's first calls
        stepping(engine, variant, scene.with_duration(sample_interval), sample_interval)
    ratios: dict[str, list[float]] = {ours: [] for ours, _ in HARNESS_PAIRS}
    last: dict[str, float] = {}
    for _ in range(runs):
        best = dict.fromkeys(ids, math.inf)
        for _ in range(rounds):
            for i, (engine, variant) in engines.items():
                seconds, taken = stepping(engine, variant, scene, sample_interval)
                best[i] = min(best[i], seconds / taken)
        for ours, peer in HARNESS_PAIRS:
            ratios[ours].append(best[ours] / best[peer])
        last = best
    rows = []
    for ours, peer in HARNESS_PAIRS:
        r = sorted(ratios[ours])
        rows.append({"section": "harness", "model": model, "variant": ours, "peer": peer, "ratios": r,
                     "median": float(np.median(r)), "us_per_step": last[ours] * 1e6,
                     "peer_us_per_step": last[peer] * 1e6, "target": HARNESS_TARGET,
                     "met": float(np.median(r)) <= HARNESS_TARGET})
    return rows


def main(argv: list[str]) -> int:
    quick = "--quick" in argv
    path = Path(argv[argv.index("--json") + 1]) if "--json" in argv else ROOT / "results" / "bench" / "bench_rigid.json"
    repeats = 3 if quick else 7
    sizes = (4, 16, 64) if quick else (4, 8, 16, 32, 64, 128, 256)
    rows = scaling_rows(sizes, repeats)
    print(f"ours.rigid: chains of revolute links, µs per step (thread CPU, least of {repeats})")
    print(f"{'variant':<30}" + "".join(f"{n:>9}" for n in sizes) + f"{'exponent':>10}  target ≤ {SCALING_TARGET}")
    for row in rows:
        print(f"{row['variant']:<30}" + "".join(f"{c:9.1f}" for c in row["us_per_step"])
              + f"{row['exponent']:10.3f}  {'met' if row['met'] else 'MISSED'}")
    kuka = kuka_rows(repeats)
    print("\nKUKA iiwa (7 bodies, dt 1e-3 s): µs per step, ours against MuJoCo (rollout, in C) in this run")
    print(f"{'variant':<34}{'ours':>8}  {'peer':<14}{'peer µs':>8}{'ratio':>8}  target ≤ {KUKA_TARGET:g}×")
    for row in kuka:
        print(f"{row['variant']:<34}{row['us_per_step']:8.2f}  {row['peer']:<14}{row['peer_us_per_step']:8.2f}"
              f"{row['ratio']:7.2f}×  {('met' if row['met'] else 'MISSED') if row['target'] else '(no target)'}")
    harness = []
    for model, scene, sample_interval in harness_scenes(steps=2000):
        rows_of_model = harness_rows(model, scene, sample_interval, runs=3 if quick else 5)
        harness += rows_of_model
        print(f"\n{model} as the harness times it ({scene.model}, {len(scene.joint_names)} joints; Engine.simulate, "
              f"2 s at dt 1e-3 s): each run the least of 5 rounds in turns; ratio over "
              f"{len(rows_of_model[0]['ratios'])} runs")
        print(f"{'variant':<34}{'µs':>7}  {'peer':<18}{'µs':>7}{'median':>8}  {'spread':<13}  "
              f"target ≤ {HARNESS_TARGET:g}×")
        for row in rows_of_model:
            print(f"{row['variant']:<34}{row['us_per_step']:7.2f}  {row['peer']:<18}{row['peer_us_per_step']:7.2f}"
                  f"{row['median']:7.2f}×  {row['ratios'][0]:.2f}–{row['ratios'][-1]:.2f}×    "
                  f"{'met' if row['met'] else 'MISSED'}")
    sensitivity = sensitivity_rows(repeats)
    print("\nKUKA iiwa forward sensitivities (dt 1e-3 s), per step in steps' worth of the real step: the tangent-linear "
          "step carrying n directions (target ≤ 2 + n), and one direction's complex run")
    print(f"{'variant':<34}{'real µs':>8}" + "".join(f"{f'n = {n}':>8}" for n in DIRECTIONS) + f"{'complex':>9}")
    print(f"{'budget 2 + n':<42}" + "".join(f"{2 + n:8d}" for n in DIRECTIONS))
    for r in sensitivity:
        print(f"{r['variant']:<34}{r['us_per_step']:8.2f}" + "".join(f"{w:8.2f}" for w in r["tangent_steps_worth"])
              + f"{r['steps_worth']:9.2f}  {'met' if r['met'] else 'MISSED'}")
    transition = transition_rows(repeats)
    for r in transition:
        print(f"\nKUKA iiwa whole one-step Jacobian ({r['n']} × {r['n']}) per step, each in steps' worth of its own "
              f"plain step: MuJoCo mjd_transitionFD + mj_step {r['mujoco_fd_us_per_step']:.1f} µs "
              f"({r['mujoco_steps_worth']:.1f}); ours' tangent-linear step, {r['n']} directions, baumgarte-symplectic-euler "
              f"{r['ours_tangent_us_per_step']:.1f} µs ({r['ours_steps_worth']:.1f}, budget {2 + r['n']}); "
              f"ours / MuJoCo {r['ratio']:.2f}×  {'met' if r['met'] else 'MISSED'}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nload average {load:.1f} on {os.cpu_count()} CPUs")
    path.parent.mkdir(parents=True, exist_ok=True)
    everything = rows + kuka + harness + sensitivity + transition
    path.write_text(json.dumps({"rows": everything, "load_average": load}, indent=1))
    return 0 if all(r["met"] for r in everything) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
