"""The Drake adapter against closed forms, the reference and MuJoCo, with the real engine.

Drake is an optional extra (``pip install 'xval[drake]'``): without it these
tests skip with that reason, except the last ones, which check that a
missing Drake is "not installed" with the pip line and that a suite naming it
records its cases as skipped. Numbers in comments were measured with drake
1.51.1 (`.venv/bin/python -m pytest tests/test_engine_drake.py -q -p no:xdist`).
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from engines.scene import catalog
from engines.reference.closed_form import pendulum_period
from engines.errors import UserError
from engines.reference.reference import ENGINE as REFERENCE

HAVE_DRAKE = importlib.util.find_spec("pydrake") is not None
needs_drake = pytest.mark.skipif(not HAVE_DRAKE, reason="Drake is not installed: pip install 'xval[drake]'")
G = 9.81


def drake():
    from engines.drake.adapter import ENGINE

    return ENGINE


def crossing_times(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Upward zero crossings of x(t), linearly interpolated between samples."""
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


# -- the bead's period -------------------------------------------------------------------


@needs_drake
@pytest.mark.parametrize("variant, dt, options, bound", [
    # Error control at accuracy 1e-9: the period is right to far better than 1e-6 (measured 2e-9 RK3).
    ("rk3", 1e-2, {"accuracy": 1e-9}, 1e-6),
    ("rk5", 1e-2, {"accuracy": 1e-9}, 1e-6),
    ("radau3", 1e-2, {"accuracy": 1e-9}, 1e-6),
    # Fixed steps: a method of order p has a relative period error below (ω·dt)^p (ω ≈ 3.1 rad/s):
    # 1e-5 for RK2 at dt = 1e-3; symplectic Euler's period error is second order too (it is a
    # first-order method whose error is a phase, not an amplitude, error), bounded by ω·dt = 3.1e-3.
    ("rk2", 1e-3, {}, 1e-5),
    ("semi-explicit-euler", 1e-3, {}, 3.2e-3),
    ("discrete", 1e-3, {}, 3.2e-3),
])
def test_bead_period_matches_the_elliptic_integral(variant, dt, options, bound):
    scene = catalog.build("bead", {"theta0": 10, "duration": 6.5})  # three full periods
    run = drake().simulate(scene, dt, variant=variant, options=options, sample_interval=1e-3)
    assert run.info.status == "ok", run.info.message
    crossings = crossing_times(run.t, run.positions[:, 0, 0])
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert abs(period / pendulum_period(1.0, G, math.radians(10)) - 1) < bound


# -- agreement with the reference ------------------------------------------------------------


@needs_drake
@pytest.mark.parametrize("scene_name", ["double-pendulum", "spherical-pendulum"])
def test_rk3_error_follows_its_accuracy(scene_name):
    # Drake's accuracy targets a weighted norm of the *local* error, not the global one; for RK3
    # the 2 s global error still stays under the accuracy and falls tenfold per decade
    # (measured 1.7e-7, 1.8e-8, 1.6e-9 m on the double pendulum at 1e-6, 1e-7, 1e-8).
    # Forces follow the errors through the accelerations: under 1e-4 N at 1e-6 (measured 1.0e-5 N).
    scene = catalog.build(scene_name, {"duration": 2})
    reference = REFERENCE.simulate(scene, 1e-2)
    errors = []
    for accuracy in (1e-6, 1e-7, 1e-8):
        run = drake().simulate(scene, 1e-2, variant="rk3", options={"accuracy": accuracy})
        assert run.info.status == "ok", run.info.message
        assert run.info.settings["target_accuracy"] == accuracy and run.info.settings["fixed_step_mode"] is False
        errors.append(np.abs(run.positions - reference.positions).max())
        if accuracy == 1e-6:
            assert np.abs(run.constraint_forces - reference.constraint_forces).max() < 1e-4
    assert errors[0] < 1e-6
    assert errors[0] / errors[1] > 5 and errors[1] / errors[2] > 5


@needs_drake
@pytest.mark.parametrize("scene_name", ["double-pendulum", "spherical-pendulum"])
@pytest.mark.parametrize("variant", ["rk5", "bs3", "radau3"])
def test_other_error_controlled_variants_agree_with_the_reference(scene_name, variant):
    # At accuracy 1e-8 each stays under 2e-6 m over 2 s (measured worst: RK5 on the double
    # pendulum, 9.5e-7 m; the spherical pendulum's ball joint has the 1e-9 inertia floor, ~2e-9 m).
    scene = catalog.build(scene_name, {"duration": 2})
    reference = REFERENCE.simulate(scene, 1e-2)
    run = drake().simulate(scene, 1e-2, variant=variant, options={"accuracy": 1e-8})
    assert run.info.status == "ok", run.info.message
    assert np.abs(run.positions - reference.positions).max() < 2e-6


@needs_drake
def test_rk5_is_not_monotone_in_its_accuracy():
    # A finding docs/engines.md quotes, pinned so a Drake upgrade that changes it is noticed: on the
    # double pendulum RK5 at accuracy 1e-5 is 3.6e-8 m off the reference, at 1e-6 4.5e-5 m (measured).
    scene = catalog.build("double-pendulum", {"duration": 2})
    reference = REFERENCE.simulate(scene, 1e-2)
    loose, tight = (drake().simulate(scene, 1e-2, variant="rk5", options={"accuracy": a}) for a in (1e-5, 1e-6))
    error = [np.abs(run.positions - reference.positions).max() for run in (loose, tight)]
    assert error[1] > 100 * error[0]


@needs_drake
def test_zero_inertia_point_masses_have_no_error_floor():
    # With zero rotational inertia (the default for hinges) Drake's RK5 at fixed dt = 1e-3 reaches
    # round-off on the double pendulum (ENGINE_NOTES: 1e-12 m): far below the 1.5e-8 m floor that an
    # inertia ratio of 1e-9 gives every other rigid-body engine (MuJoCo hinge-rk4).
    scene = catalog.build("double-pendulum", {"duration": 1})
    reference = REFERENCE.simulate(scene, 1e-3)
    engine = drake()
    exact = engine.simulate(scene, 1e-3, variant="rk5", options={"error_control": False})
    assert exact.info.settings["point_mass_inertia"] == [0.0, 0.0]
    assert np.abs(exact.positions - reference.positions).max() < 1e-10


@needs_drake
@pytest.mark.parametrize("variant, order", [("rk2", 2), ("semi-explicit-euler", 1), ("discrete", 1)])
def test_fixed_step_variants_have_their_order(variant, order):
    scene = catalog.build("bead", {"theta0": 60, "duration": 1})
    steps = np.array([5e-3, 2.5e-3, 1.25e-3])
    errors = []
    for dt in steps:
        run = drake().simulate(scene, dt, variant=variant)
        assert run.info.steps == round(1 / dt)  # whole steps to every sample, no sliver steps
        errors.append(np.abs(run.positions - REFERENCE.simulate(scene, dt).positions).max())
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.2


# -- the discrete plant is MuJoCo's scheme ------------------------------------------------------


@needs_drake
@pytest.mark.parametrize("scene_name, params", [("double-pendulum", {}), ("chain", {"n": 8})])
def test_discrete_plant_equals_mujoco_hinge(scene_name, params):
    # Without contact, Drake's discrete plant is symplectic Euler in joint coordinates, MuJoCo's
    # Euler: given MuJoCo's point-mass inertia they agree to round-off (measured 5e-15 m, 2e-12 N).
    from engines.mujoco.adapter import ENGINE as MUJOCO

    scene = catalog.build(scene_name, {"duration": 2, **params})
    mujoco = MUJOCO.simulate(scene, 1e-3, variant="hinge", options={"inertia_ratio": 1e-9})
    discrete = drake().simulate(scene, 1e-3, variant="discrete", options={"inertia_ratio": 1e-9})
    assert discrete.info.steps == 2000 and discrete.info.settings["discrete_contact_approximation"] == "kSap"
    assert np.abs(discrete.positions - mujoco.positions).max() < 1e-12
    assert np.abs(discrete.velocities - mujoco.velocities).max() < 1e-11
    assert np.abs(discrete.constraint_forces - mujoco.constraint_forces).max() < 1e-9


# -- bad input ----------------------------------------------------------------------------------


@needs_drake
def test_bad_options_name_the_option_and_the_fix():
    scene = catalog.build("bead")
    with pytest.raises(UserError, match="drake: option accuracy must be positive, got -1.0"):
        drake().simulate(scene, 1e-2, variant="rk3", options={"accuracy": -1})
    with pytest.raises(UserError, match="integrator rk2 has no error estimate; set error_control = false"):
        drake().simulate(scene, 1e-2, options={"integrator": "rk2"})


# -- without Drake ------------------------------------------------------------------------------

#: Run the CLI with Drake's and JAX's packages hidden, as on a machine without the extras.
WITHOUT_EXTRAS = """
import sys
class Hide:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('pydrake', 'jax') or name.startswith('mujoco.mjx'):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, Hide())
from compare.cli import main
main()
"""


def xval_without_extras(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", WITHOUT_EXTRAS, *argv], capture_output=True, text=True,
                          timeout=120)


def test_without_the_extras_engines_lists_the_pip_line():
    listing = xval_without_extras("engines")
    assert listing.returncode == 0, listing.stderr
    assert "pip install 'xval[drake]'" in listing.stdout and "pip install 'xval[mjx]'" in listing.stdout


def test_without_the_extras_a_suite_records_their_cases_skipped(tmp_path):
    suite = tmp_path / "peers.toml"
    suite.write_text('duration = 0.2\ndt = [1e-2]\n[[scenes]]\nscene = "bead"\n'
                     '[[engines]]\nid = "drake/rk3"\n[[engines]]\nid = "mjx/hinge"\n'
                     '[[engines]]\nid = "mujoco/hinge"\n')
    run = xval_without_extras("run", str(suite), "--output", str(tmp_path / "r"), "--jobs", "1")
    assert run.returncode == 0, run.stdout + run.stderr
    shown = xval_without_extras("show", str(tmp_path / "r"), "--format", "json")
    assert shown.returncode == 0, shown.stderr
    records = {row["engine"]: row for row in json.loads(shown.stdout)}
    assert records["mujoco/hinge"]["status"] == "ok"
    for engine, extra in (("drake/rk3", "drake"), ("mjx/hinge", "mjx")):
        assert records[engine]["status"] == "skipped"
        assert f"pip install 'xval[{extra}]'" in records[engine]["message"]


@needs_drake
@pytest.mark.parametrize("scene_name, words", [
    ("slider-pendulum", "drake models only pin, rod constraints; constraints[0] is a 'line'"),
    ("four-bar", "drake: constraint 1 closes a loop"),
])
def test_scenes_beyond_a_tree_of_pins_and_rods_are_left_out_with_the_reason(scene_name, words):
    from engines.errors import Unsupported

    with pytest.raises(Unsupported, match=re.escape(words)):
        drake().check(catalog.build(scene_name))
