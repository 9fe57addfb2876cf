"""Per-step cost of each engine's own stepper on the KUKA iiwa model scene, against MuJoCo's in the same run.

    .venv/bin/python bench/bench_models.py [--steps 2000] [--repeats 10]

The scene is suites/models.toml's kuka-iiwa (joint 2 at 30°, joint 4 at −45°), stepped --steps times at
dt 1e-3 s by each variant's ``Engine.simulate``: the model scenes' one loop (engines/model/stepping.py) over
the stepper of the engine's home (engines/<engine>/model.py), sampled as the suite samples. The time is what
that loop counts as stepping (thread CPU of ``advance``: no loading, building or reading of samples), per step, least
of --repeats runs taken in turns round the engines, after a warm-up. Rows pair like with like: first order
against mujoco/hinge (Euler), RK4 against mujoco/hinge-rk4; Drake's fixed-step RK2 (2nd order, two
evaluations a step) is listed against RK4 for what it is. A row is what xval runs, binding included:
PyBullet and DART's World take a Python call a step, DART's RK4 is Python around four forward-dynamics
calls; MuJoCo, Drake (its plant is C++) and ours take a sample's steps in one call. Pinocchio has no stepper
(the reference integrates its ABA with DOP853): no row. Every engine must be installed (``make
.venv/.installed-stamp``): a missing one ends the bench with an error.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from compare.suite.reader import load_suite  # noqa: E402
from engines.errors import UserError  # noqa: E402
from engines.registry import load_engine  # noqa: E402

SUITE = ROOT / "suites" / "models.toml"
SCENE = "kuka-iiwa"
DT = 1e-3
FIRST, RK4, RK2 = "1st order", "RK4", "RK2 (2nd order)"
#: Each class's MuJoCo peer, which its ratio is to.
PEERS = {FIRST: "mujoco/hinge", RK4: "mujoco/hinge-rk4", RK2: "mujoco/hinge-rk4"}
#: (class, engine variant, dynamics evaluations a step, how xval's stepper calls the engine), peers first.
ROWS = (
    (FIRST, "mujoco/hinge", 1, "mj_step(nstep) per sample, C"),
    (FIRST, "pybullet/multibody", 1, "stepSimulation, a Python call a step"),
    (FIRST, "drake/semi-explicit-euler", 1, "Simulator.AdvanceTo per sample, C++"),
    (FIRST, "dart/world", 1, "World.step, a Python call a step"),
    (FIRST, "ours/baumgarte-symplectic-euler", 1, "numba loop per sample"),
    (RK4, "mujoco/hinge-rk4", 4, "mj_step(nstep) per sample, C"),
    (RK4, "dart/rk4", 4, "RK4 in Python, 4 forward-dynamics calls a step"),
    (RK4, "ours/baumgarte-rk4", 4, "numba loop per sample"),
    (RK2, "drake/rk2", 2, "Simulator.AdvanceTo per sample, C++"),
)


def load_average() -> str:
    return f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"


def engine_of(engine_id: str):
    """(adapter, variant) of ``engine_id``; SystemExit naming it when it cannot load (every row must be measured)."""
    try:
        return load_engine(engine_id)
    except UserError as exc:
        raise SystemExit(f"bench_models: {exc}; this bench needs every engine (make .venv/.installed-stamp)") from None


def stepping(engine, variant: str | None, scene, sample_interval: float) -> tuple[float, int]:
    """(thread CPU s of the stepping, steps taken) of one run of ``scene``; SystemExit when it is not ok."""
    info = engine.simulate(scene, DT, variant=variant, sample_interval=sample_interval).info
    if info.status != "ok":
        raise SystemExit(f"bench_models: {info.variant} on {scene.name}: {info.status} ({info.message})")
    return info.cpu_time, info.steps


def least_per_step(scene, sample_interval: float, repeats: int) -> dict[str, float]:
    """s per step of each row's variant: the least of ``repeats`` runs, after one short uncounted run (numba
    loading ours' kernels, each engine's first calls). The runs go round the engines, so every engine's
    least comes from the same stretches of a shared machine's time."""
    engines = {engine_id: engine_of(engine_id) for _, engine_id, *_ in ROWS}
    for engine, variant in engines.values():
        stepping(engine, variant, scene.with_duration(sample_interval), sample_interval)
    best = dict.fromkeys(engines, math.inf)
    for _ in range(repeats):
        for engine_id, (engine, variant) in engines.items():
            seconds, steps = stepping(engine, variant, scene, sample_interval)
            best[engine_id] = min(best[engine_id], seconds / steps)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps of dt 1e-3 s a run (default 2000: 2 s)")
    parser.add_argument("--repeats", type=int, default=10,
                        help="runs per engine, taken in turns; the least is kept (default 10)")
    args = parser.parse_args()
    if args.steps < 1 or args.repeats < 1:
        parser.exit(2, "bench_models: --steps and --repeats must be at least 1\n")
    suite = load_suite(SUITE)
    spec = next(s for s in suite.scenes if s.id == SCENE)
    scene = spec.scene.with_duration(args.steps * DT)
    q0 = ", ".join(f"{joint} {angle}°" for joint, angle in spec.parameters["q0"].items())
    print(f"{SCENE} ({scene.model}, {len(scene.joint_names)} joints, q0 {q0}): {args.steps} steps of dt {DT:g} s "
          f"sampled every {suite.sample_interval:g} s; thread CPU of the stepping, least of {args.repeats} runs taken "
          f"in turns, after a warm-up; {load_average()}")
    per_step = least_per_step(scene, suite.sample_interval, args.repeats)
    print("| class | variant | evaluations a step | how it steps | µs per step | / peer | peer |")
    print("|---|---|---|---|---|---|---|")
    for kind, engine_id, evaluations, how in ROWS:
        # µs to 0.001: two costs near 2 µs rounded to 0.01 could put their printed ratio 0.01 off the one printed
        print(f"| {kind} | {engine_id} | {evaluations} | {how} | {per_step[engine_id] * 1e6:.3f} | "
              f"{per_step[engine_id] / per_step[PEERS[kind]]:.2f} | {PEERS[kind]} |")
    print(f"at the end: {load_average()}")


if __name__ == "__main__":
    main()
