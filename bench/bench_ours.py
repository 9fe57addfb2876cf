"""Speed of ours' compiled stepping loop, measured next to MuJoCo in the same run.

Prints:
1. compile time of ours' loops: cold (empty numba cache, in a fresh process)
   and warm (cache hit, in a fresh process);
2. steps per second on the default double pendulum (dt = 1e-3, 10 s):
   ours/baumgarte-rk4 and ours/rattle (stepping loop only, samples every
   10 steps as the adapter records them), MuJoCo hinge + Euler as a Python
   loop of mj_step (no recording) and through mujoco.rollout (one C call);
3. per-step cost of ours on chains of 4, 16, 64 and 256 links (should grow
   about linearly: the J W Jᵀ solve is a tridiagonal Cholesky).

Times are medians of repeats of wall time on this machine, as it is loaded
right now; compare numbers within one run, not across machines.
Run: .venv/bin/python bench/bench_ours.py [--no-cold]
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import ours  # noqa: E402
from engines import catalog  # noqa: E402
from engines.registry import resolve  # noqa: E402

REPEATS = 5
DT = 1e-3


def compile_seconds(cache_dir: str | None) -> float:
    """Seconds ``ours.compile_all()`` takes in a fresh interpreter (``cache_dir``: a fresh numba cache)."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    code = "import ours, sys; sys.stdout.write(repr(ours.compile_all()))"
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return float(out.stdout)


def median_wall(run) -> float:
    return statistics.median(run() for _ in range(REPEATS))


def ours_seconds(scene, variant: str) -> tuple[float, int]:
    engine, variant = resolve(f"ours/{variant}")
    engine.simulate(scene, DT, variant=variant)  # warm-up (loads the compiled loop)
    runs = [engine.simulate(scene, DT, variant=variant) for _ in range(REPEATS)]
    bad = [r.info.message for r in runs if r.info.status != "ok"]
    if bad:
        raise RuntimeError(f"ours/{variant} did not run cleanly: {bad[0]}")
    return statistics.median(r.info.wall_time for r in runs), runs[0].info.steps


def mujoco_rows(scene, n_steps: int) -> list[tuple[str, float]]:
    try:
        import mujoco
        from mujoco import rollout

        from engines.mujoco import ENGINE as MUJOCO, hinge_velocities
    except ImportError as exc:
        print(f"  mujoco: skipped ({exc})")
        return []
    settings = MUJOCO.resolve("hinge")
    model, _xml, _inertia = MUJOCO.build(scene, DT, settings)
    data = mujoco.MjData(model)
    data.qvel[:] = hinge_velocities(scene, model)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = [0.0] * mujoco.mj_stateSize(model, spec)
    import numpy as np

    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)

    def python_loop() -> float:
        mujoco.mj_setState(model, data, initial, spec)
        step = mujoco.mj_step
        start = time.perf_counter()
        for _ in range(n_steps):
            step(model, data)
        return time.perf_counter() - start

    def one_rollout() -> float:
        start = time.perf_counter()
        rollout.rollout(model, data, initial[None, :], nstep=n_steps)
        return time.perf_counter() - start

    python_loop()
    one_rollout()
    rows = [("mujoco hinge Euler, Python loop of mj_step", median_wall(python_loop)),
            ("mujoco hinge Euler, mujoco.rollout", median_wall(one_rollout))]
    adapter = [MUJOCO.simulate(scene, DT, variant="hinge").info.wall_time for _ in range(REPEATS)]
    rows.append(("mujoco/hinge through its adapter (loop + recording)", statistics.median(adapter)))
    return rows


def main() -> None:
    cold = "--no-cold" not in sys.argv
    print("ours: compile time of the stepping loops (fresh process each)")
    if cold:
        with tempfile.TemporaryDirectory() as empty:
            print(f"  cold, empty numba cache : {compile_seconds(empty):8.2f} s")
    print(f"  warm, from the cache    : {compile_seconds(None):8.2f} s")
    ours.compile_all()

    scene = catalog.build("double-pendulum")
    print(f"\nsteps per second, default double pendulum, dt = {DT:g} s, {scene.duration:g} s "
          f"(median of {REPEATS})")
    rows = []
    n_steps = 0
    for variant in ("baumgarte-rk4", "rattle"):
        seconds, n_steps = ours_seconds(scene, variant)
        rows.append((f"ours/{variant}", seconds))
    rows += mujoco_rows(scene, n_steps)
    for label, seconds in rows:
        print(f"  {label:<55s} {n_steps / seconds:12,.0f} steps/s  ({seconds / n_steps * 1e6:6.2f} µs/step)")

    print("\nper-step cost on chains (catalog 'chain', 1 s, dt = 1e-3; median of repeats)")
    print(f"  {'links':>5s} {'baumgarte-rk4 µs':>17s} {'per link':>9s} {'rattle µs':>10s} {'per link':>9s}")
    for n in (4, 16, 64, 256):
        chain = catalog.build("chain", {"n": n, "duration": 1.0})
        cells = []
        for variant in ("baumgarte-rk4", "rattle"):
            seconds, steps = ours_seconds(chain, variant)
            per_step = seconds / steps * 1e6
            cells += [per_step, per_step / n]
        print(f"  {n:5d} {cells[0]:17.2f} {cells[1]:9.3f} {cells[2]:10.2f} {cells[3]:9.3f}")


if __name__ == "__main__":
    main()
