"""MJX's own derivatives (engines/mjx/gradients.py): forward mode through its stepping loop, float64 and float32.

Few and cached: each (model, precision) compiles jit(jvp(fori_loop(mjx.step))) once per process
(seconds of CPU on these two scenes, or JAX's persistent cache), so one spawned process for the module. The chain
of 8 compiles for about a minute, more than a test may: scripts/mjx_chain_gradients.py measures it (its
self-consistency, error and NaN samples, quoted in docs/gradients.md). MJX runs
there, never in the test process (tests/fork_guard.py; see tests/test_engine_mjx.py).
"""

from __future__ import annotations

import importlib.util
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import pytest

HAVE_MJX = importlib.util.find_spec("jax") is not None and importlib.util.find_spec("mujoco.mjx") is not None
pytestmark = pytest.mark.skipif(not HAVE_MJX, reason="MJX is not installed: pip install 'xval[mjx]'")


def _measure(variant: str, name: str = "double-pendulum") -> dict:
    """In the spawned process: MJX's forward-mode Jacobian of scene ``name`` at dt 1e-3 over 1 s against differences of
    its own rollouts and against the reference, and the first sample whose Jacobian is not finite."""
    from engines import registry
    from engines.gradients import finite_difference_jacobian
    from engines.reference.sensitivity import reference_jacobian, relative_error
    from engines.scene.catalog import build

    scene = build(name, {"duration": 1.0})
    wrt = ["theta1", "omega2"] if name == "double-pendulum" else ["theta0", "omega0"]
    engine, _ = registry.resolve(f"mjx/{variant}")
    own, method = engine.jacobian(scene, variant, None, 1e-3, wrt)
    differences = finite_difference_jacobian(engine, scene, variant, None, 1e-3, wrt).jacobian
    from engines.mjx.gradients import transition_over_time

    _, transition = transition_over_time(engine, scene, variant, None, 1e-3)
    return {"method": method, "self": float(relative_error(own, differences)),
            "error": float(relative_error(own, reference_jacobian(scene, wrt, 1.0))),
            "first_nonfinite": transition.first_nonfinite, "samples": len(transition.times)}


@pytest.fixture(scope="module")
def spawned():
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield pool


def test_float64_rk4_forward_mode_is_accurate_and_self_consistent(spawned):
    answer = spawned.submit(_measure, "hinge-rk4").result()
    assert answer["method"] == "autodiff"
    assert answer["self"] <= 1e-6  # measured 9e-11
    assert answer["error"] <= 1e-6  # measured 8e-9
    assert answer["first_nonfinite"] is None


@pytest.mark.parametrize("name", ["double-pendulum", "bead"])
def test_float32_rk4_forward_mode_stays_finite_at_every_sample_and_within_its_floor(spawned, name):
    """No NaN appears in MJX's float32 forward-mode Jacobian on the double pendulum and the bead: each 0.01 s
    sample of d x(t) / d x(0) is finite; at T it is within the float32 floor (1e-3) of the reference (measured
    2e-6 on both), and of differences of its own float32 rollouts (step 3e-2 of each parameter's scale)."""
    answer = spawned.submit(_measure, "hinge-rk4-f32", name).result()
    assert answer["first_nonfinite"] is None and answer["samples"] == 101
    assert answer["error"] <= 1e-3
    assert answer["self"] <= 1e-3
