"""The consistency rule (compare/results/consistency.py) on real engines: a quiet model error is caught, a
declared precision floor and the reference's own floor are not called errors.

The quiet error is tests/gravity_program.py, a double-pendulum solver speaking the process protocol whose
only bug is g = 9.8 m/s² where the scene says 9.81: RK4, so its error falls at fourth order — towards the
wrong motion. The same program given the scene's 9.81 is the control: the rule must not simply reject it.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from compare.results.consistency import judge
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from engines.mjx.adapter import precision_floor

HERE = Path(__file__).parent

SUITE = """
name = "consistency"
duration = 2.0
sample_interval = 0.01
dt = [1e-2, 3.16227766017e-3, 1e-3, 3.16227766017e-4]

[[scenes]]
id = "double-pendulum"
scene = "double-pendulum"

[[engines]]
command = ["{python}", "{program}"]
label = "g-9.8"
version = "1"

[[engines]]
command = ["{python}", "{program}", "9.81"]
label = "g-9.81"
version = "1"
"""


def run(tmp_path: Path, text: str) -> dict[str, object]:
    """Run the suite ``text`` (its commands given absolute paths); the sweeps by variant label."""
    text = text.replace("{python}", sys.executable).replace("{program}", str(HERE / "gravity_program.py"))
    suite = parse_suite(text, str(HERE / "consistency_suite.toml"))
    run_suite(suite, tmp_path / "out", jobs=2)
    return {s.engine: s for s in load_results(tmp_path / "out").sweeps()}


def pendulum_suite(duration: float, *engines: str) -> str:
    """The double pendulum over ``duration`` s at dt 1e-3, 3.16e-4 and 1e-4 s, for the built-in ``engines``."""
    # A generous case timeout: MJX compiles its step (minutes of CPU on a loaded 2-core machine) before stepping.
    return (f'name = "floor"\nduration = {duration}\nsample_interval = 0.01\ntimeout = 900\n'
            'dt = [1e-3, 3.16227766017e-4, 1e-4]\n[[scenes]]\nid = "double-pendulum"\nscene = "double-pendulum"\n'
            + "".join(f'[[engines]]\nid = "{engine}"\n' for engine in engines))


def test_a_solver_with_gravity_9_8_converges_to_something_else_and_is_inconsistent(tmp_path):
    found = run(tmp_path, SUITE)
    wrong, right = found["command/g-9.8"], found["command/g-9.81"]
    # Every case ran and is ok: `ok` cannot see the bug.
    assert {r.status.value for r in wrong.records} == {"ok"}
    errors = [r.metric("position_error_linf") for r in sorted(wrong.ok_records, key=lambda r: -r.case.dt)]
    # Fourth order at first, then flat: the g error (0.1 %) dominates; the plateau is millimetres.
    assert 1e-3 < errors[-1] < 2e-2 and errors[-1] / errors[-2] > 0.9
    verdict = wrong.consistency
    assert verdict.consistent is False
    assert verdict.plateau == pytest.approx(errors[-1])
    assert verdict.reason.startswith(f"converges to something {errors[-1]:.2g} m from the reference: error stops "
                                     f"falling at {errors[-1]:.2g} m from dt ")
    assert "above the tolerance 2e-06 m, the reference's error bar" in verdict.reason
    # Its cost is the program's own CPU time (not the host's thread's): a Python RK4 step costs microseconds.
    assert wrong.cost is not None and wrong.cost.per_step > 2e-6
    # The control: with the scene's own g the same program keeps converging (or reaches the reference's floor).
    assert right.consistency.consistent is True
    assert right.consistency.reason.startswith("error still falls (local order ")
    assert float(right.consistency.reason.split("local order ")[1].split()[0]) > 2


def test_ours_and_mujoco_hinge_rk4_stop_at_the_references_floor_and_are_consistent(tmp_path):
    text = pendulum_suite(2.0, "ours/lagrangian-rk4", "mujoco/hinge-rk4")
    found = run(tmp_path, text)
    for label in ("ours/lagrangian-rk4", "mujoco/hinge-rk4"):
        sweep = found[label]
        bar = sweep.finest_ok.reference["reference_error"]  # m, the reference's own error bar
        assert 1e-13 < bar < 1e-10
        assert sweep.consistency.consistent is True, sweep.consistency.reason
        # Both stop falling at the reference's floor (MuJoCo's a little above: its 1e-12 point-mass inertia).
        assert sweep.consistency.plateau is not None and sweep.consistency.plateau <= 10 * bar
        assert sweep.consistency.reason.endswith(f"the reference's own floor ({bar:.2g} m)")


def test_mjx_float32_stops_at_its_declared_and_measured_floor_and_is_consistent(tmp_path):
    # An extra of xval; CI installs it. find_spec, not importorskip: importing it would load JAX here.
    if importlib.util.find_spec("jax") is None or importlib.util.find_spec("mujoco.mjx") is None:
        pytest.skip("MJX is not installed: pip install 'xval[mjx]'")
    text = pendulum_suite(1.0, "mjx/hinge-rk4-f32")
    sweep = run(tmp_path, text)["mjx/hinge-rk4-f32"]
    finest = sweep.finest_ok
    floor = finest.run_info["settings"]["precision_floor"]
    assert floor == pytest.approx(precision_floor("float32", 10_000, 2.0))  # eps32 · √steps · L
    errors = [r.metric("position_error_linf") for r in sorted(sweep.ok_records, key=lambda r: -r.case.dt)]
    # Measured: round-off, not truncation, sets the finest errors (they no longer fall with dt) ...
    assert errors[-1] / errors[-2] > 0.5
    # ... and they lie under the declared floor, yet within 30× of it: the floor says what float32 costs.
    assert floor / 30 < errors[-1] <= floor
    # Far above 1e-6·L and the reference's bar, so only the declared floor explains the plateau.
    assert errors[-1] > 2e-6
    assert sweep.consistency.consistent is True, sweep.consistency.reason
    assert "within the engine's declared precision floor" in sweep.consistency.reason


def test_the_plateau_rule_on_exact_numbers():
    # Falls at second order to the finest dt: consistent whatever the level.
    assert judge([1e-2, 1e-3], [1e-2, 1e-4], tolerance=1e-9).consistent is True
    # Flat over the last two points at 5e-3 m, nothing explains it.
    verdict = judge([1e-2, 1e-3, 1e-4], [1e-1, 5e-3, 5e-3], tolerance=1e-6, reference_error=1e-11)
    assert (verdict.consistent, verdict.plateau) == (False, 5e-3)
    assert verdict.reason == ("converges to something 0.005 m from the reference: error stops falling at 0.005 m "
                              "from dt 0.001 to 0.0001 s (local order 0.00), above the tolerance 1e-06 m, "
                              "the reference's error bar 1e-11 m")
    # The same plateau under a declared floor, under the tolerance, or at the reference's floor: consistent.
    assert judge([1e-3, 1e-4], [5e-3, 5e-3], tolerance=1e-6, floor=6e-3).consistent is True
    assert judge([1e-3, 1e-4], [5e-7, 5e-7], tolerance=1e-6).consistent is True
    assert judge([1e-3, 1e-4], [4e-11, 4e-11], tolerance=1e-12, reference_error=1e-11).consistent is True
    # A chaotic reference: an unexplained plateau is not judged.
    assert judge([1e-3, 1e-4], [5e-3, 5e-3], tolerance=1e-6, horizon_limited=True).consistent is None
    assert judge([1e-3], [5e-3], tolerance=1e-6).consistent is None
