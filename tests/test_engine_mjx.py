"""The MJX adapter against MuJoCo, the elliptic period and the reference, with the real MJX on JAX's CPU.

MJX is an optional extra (``pip install 'xval[mjx]'``): without it these tests
skip with that reason (tests/test_engine_drake.py checks what a machine
without the extras shows). Each model structure and precision costs one jit
compile (~2-5 s of CPU on the bead), so every test here uses the bead or the
double pendulum, and short runs. Numbers in comments were measured with
mujoco-mjx 3.17.0, jax 0.10.2, mujoco 4.0.0.

MJX runs in a spawned process (the ``mjx`` fixture), never in the test process: JAX starts threads on
import, and the test process forks later (tests/fork_guard.py fails a test that leaves JAX in it).
"""

from __future__ import annotations

import importlib.util
import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from engines.scene import catalog
from engines.reference.closed_form import pendulum_period
from engines.mujoco.adapter import ENGINE as MUJOCO
from engines.reference.reference import ENGINE as REFERENCE

HAVE_MJX = importlib.util.find_spec("jax") is not None and importlib.util.find_spec("mujoco.mjx") is not None
pytestmark = pytest.mark.skipif(not HAVE_MJX, reason="MJX is not installed: pip install 'xval[mjx]'")
G = 9.81


def _call(method, *args, **kwargs):
    """ENGINE.<method>(...) in the spawned process, where JAX may be imported."""
    from engines.mjx.adapter import ENGINE

    return getattr(ENGINE, method)(*args, **kwargs)


def _forget_compiled():
    """Empty the adapter's compiled loops in the spawned process, so the next run compiles."""
    import engines.mjx.adapter

    engines.mjx.adapter._compiled.clear()


class SpawnedMJX:
    """The MJX engine's simulate and check, run in one spawned process (results and errors come back)."""

    def __init__(self, pool: ProcessPoolExecutor):
        self.pool = pool

    def simulate(self, *args, **kwargs):
        return self.pool.submit(_call, "simulate", *args, **kwargs).result()

    def check(self, *args, **kwargs):
        return self.pool.submit(_call, "check", *args, **kwargs).result()

    def forget_compiled(self):
        self.pool.submit(_forget_compiled).result()


@pytest.fixture(scope="module")
def mjx():
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield SpawnedMJX(pool)


def test_float64_equals_mujoco_hinge(mjx):
    # Same model, same Euler step, both in float64: round-off apart (measured 4e-16 m on the bead,
    # 5e-15 m on the double pendulum, 4e-15 m on a 4-link chain, over 1-2 s). Forces are MuJoCo's at
    # MJX's state, so they agree as closely. (The bead only: each model structure costs a compile.)
    scene = catalog.build("bead", {"duration": 1})
    run = mjx.simulate(scene, 1e-3, variant="hinge")
    # The same point-mass inertia as MJX's default (mujoco/hinge's own is 1e-12 since the truth issue).
    mujoco = MUJOCO.simulate(scene, 1e-3, variant="hinge", options={"inertia_ratio": 1e-9})
    assert run.info.status == "ok", run.info.message
    assert run.info.settings["dtype"] == "float64" and run.info.steps == 1000
    assert np.abs(run.positions - mujoco.positions).max() < 1e-12
    assert np.abs(run.velocities - mujoco.velocities).max() < 1e-11
    assert np.abs(run.constraint_forces - mujoco.constraint_forces).max() < 1e-9


def test_bead_period_matches_the_elliptic_integral(mjx):
    # Euler's relative period error is below ω·dt = 3.1e-3 at dt = 1e-3 (as mujoco/hinge, whose
    # test derives the bound). Linear interpolation at a zero crossing, where x'' = 0, is exact to O(h³).
    scene = catalog.build("bead", {"theta0": 10, "duration": 4.5})  # two full periods
    run = mjx.simulate(scene, 1e-3, variant="hinge", sample_interval=2e-3)
    x, t = run.positions[:, 0, 0], run.t
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert abs(period / pendulum_period(1.0, G, math.radians(10)) - 1) < 3.2e-3


def test_float32_error_floor_is_measured_above_float64s(mjx):
    # RK4 on the bead (1 s) at dt = 2.5e-3 and 1e-3: float64 sits on the 1e-9 inertia floor
    # (~2.6e-9 m, as mujoco/hinge-rk4), while RK4's truncation error is already below it. Float32
    # stops at its round-off, accumulated over the steps: measured 1.5e-6 and 2.5e-6 m over 2 s,
    # i.e. 10-20 ε₃₂·L (ε₃₂ = 1.2e-7, L = 1 m). Bounds: above ε₃₂·L, below 100 ε₃₂·L, and at
    # least 10× float64's error.
    scene = catalog.build("bead", {"duration": 1})
    eps32 = float(np.finfo(np.float32).eps)
    for dt in (2.5e-3, 1e-3):
        reference = REFERENCE.simulate(scene, dt)
        f64 = mjx.simulate(scene, dt, variant="hinge-rk4")
        f32 = mjx.simulate(scene, dt, variant="hinge-rk4-f32")
        e64 = np.abs(f64.positions - reference.positions).max()
        e32 = np.abs(f32.positions - reference.positions).max()
        assert e64 < 1e-8
        assert eps32 < e32 < 100 * eps32
        assert e32 > 10 * e64


def test_jit_compile_time_is_recorded_apart_from_stepping(mjx):
    # A dt sweep reuses the compiled loop (dt is an array in MJX's model): the second run compiles nothing.
    # The compiled loops are emptied first, so the first run compiles (an earlier test may have compiled
    # this scene's loop already).
    mjx.forget_compiled()
    scene = catalog.build("bead", {"duration": 0.5})
    first = mjx.simulate(scene, 2e-3, variant="hinge")
    second = mjx.simulate(scene, 1e-3, variant="hinge")
    assert second.info.settings["jit_cache_hit"] is True and second.info.settings["jit_compile_time"] == 0.0
    assert first.info.settings["jit_cache_hit"] is False and first.info.settings["jit_compile_time"] > 0
    assert second.info.steps == 500 and second.info.wall_time > 0


def test_a_deep_chain_is_left_out_with_the_reason_and_the_fix(mjx):
    from engines.errors import Unsupported

    with pytest.raises(Unsupported, match="body tree is 32 deep .* set option max_depth = 32 to run it anyway"):
        mjx.check(catalog.build("chain", {"n": 32}), "hinge")
    mjx.check(catalog.build("chain", {"n": 32}), "hinge", {"max_depth": 32})  # the user may insist


_CACHED_RUN = r"""
import json, jax
events = []
jax.monitoring.register_event_listener(lambda name, **kwargs: events.append(name))
from engines.scene import catalog
from engines.mjx.adapter import ENGINE
run = ENGINE.simulate(catalog.build("bead", {"duration": 0.05}), 1e-2, variant="hinge")
print(json.dumps({"status": run.info.status, "hits": events.count("/jax/compilation_cache/cache_hits"),
                  "misses": events.count("/jax/compilation_cache/cache_misses")}))
"""


def test_a_second_process_loads_the_compiled_loop_from_xvals_cache_directory(tmp_path):
    # JAX's persistent compilation cache lives in xval's cache directory ($XVAL_CACHE_DIR/jax): the first
    # process compiles the stepping loop and stores it, the second finds every executable there.
    import json
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("JAX_COMPILATION_CACHE_DIR", "NUMBA_CACHE_DIR")}
    env["XVAL_CACHE_DIR"] = str(tmp_path / "cache")
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", _CACHED_RUN], env=env, capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        counts.append(json.loads(out.stdout.strip().splitlines()[-1]))
    first, second = counts
    assert first["status"] == second["status"] == "ok"
    assert first["misses"] >= 1 and first["hits"] == 0
    assert second["misses"] == 0 and second["hits"] >= 1
    assert any((tmp_path / "cache" / "jax").iterdir())
