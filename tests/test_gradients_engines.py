"""Engines' Jacobians against the reference's (compare/gradients/measure.py), and ``xval grad``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from compare.gradients.measure import classify, engine_case
from conftest import ROOT, run_xval
from engines import registry
from engines.external.command import command_engine
from engines.gradients import finite_difference_jacobian
from engines.reference.sensitivity import reference_jacobian, relative_error
from engines.scene.catalog import build

ONE_SECOND = {"bead": {"duration": 1.0}, "double-pendulum": {"duration": 1.0}, "chain-8": {"n": 8, "duration": 1.0}}
WRT = {"bead": ["theta0", "omega0", "g", "radius"], "double-pendulum": ["theta1", "omega2", "g", "m1", "l2"],
       "chain-8": ["theta0", "g", "length"]}


def _scene(key: str):
    return build(key.partition("-8")[0], ONE_SECOND[key])


@pytest.mark.parametrize("engine_id", ["mujoco/hinge-rk4", "ours/lagrangian-rk4"])
@pytest.mark.parametrize("key", list(ONE_SECOND))
def test_float64_rk4_by_differences_of_rollouts_is_correct_to_1e_6(key, engine_id):
    """Float64 RK4 at dt 1e-3 over 1 s: its Jacobian (MuJoCo's: central differences of whole rollouts with
    Richardson; ours/lagrangian-rk4's: its own tangent-linear step, self-consistent to 1e-6) within 1e-6 of the
    reference's, and falling as dt halves unless already at round-off (ours' bead: 3e-12)."""
    engine, variant = registry.resolve(engine_id)
    case = engine_case(engine, variant, None, _scene(key), 1e-3, WRT[key])
    if engine_id.startswith("ours"):
        assert case.method == "analytic" and case.self_consistency is not None and case.self_consistency <= 1e-6
    else:
        assert case.method == "finite-difference" and case.self_consistency is None
    assert case.error <= 1e-6 and case.klass == "correct"
    assert case.error_half < case.error or case.error < 1e-10


@pytest.mark.parametrize("key", list(ONE_SECOND))
def test_mujoco_chained_transition_fd_agrees_with_its_own_rollouts(key):
    """Own derivatives (Engine.jacobian: mjd_transitionFD chained, Euler) against differences of its own rollouts: ≤ 1e-6
    (measured 5e-8 to 1.4e-7), while both are O(dt) off the reference."""
    scene = _scene(key)
    initial = [w for w in WRT[key] if w.startswith(("theta", "omega"))]
    engine, _ = registry.resolve("mujoco/hinge")
    own, method = engine.jacobian(scene, "hinge", None, 1e-3, initial)
    differences = finite_difference_jacobian(engine, scene, "hinge", None, 1e-3, initial).jacobian
    assert method == "finite-difference"
    assert relative_error(own, differences) <= 1e-6
    assert relative_error(own, reference_jacobian(scene, initial, 1.0)) > 1e-4


def test_mujoco_euler_gradient_error_falls_at_first_order():
    scene = _scene("double-pendulum")
    reference = reference_jacobian(scene, ["theta1", "omega2"], 1.0)
    engine, _ = registry.resolve("mujoco/hinge")
    errors = [relative_error(engine.jacobian(scene, "hinge", None, dt, ["theta1", "omega2"])[0], reference)
              for dt in (2e-3, 1e-3, 5e-4)]
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all((orders > 0.8) & (orders < 1.2)), orders


def _gravity_blind_bead(tmp_path: Path) -> Path:
    """examples/python/bead.py with g fixed at 9.81 m/s²: a solver that ignores the g it is given."""
    text = (ROOT / "examples" / "python" / "bead.py").read_text()
    given = 'r, (gx, _, gz) = pin["length"], scene["gravity"]'
    assert given in text
    program = tmp_path / "blind_bead.py"
    program.write_text(text.replace(given, 'r, gx, gz = pin["length"], 0.0, -9.81'))
    return program


def test_a_solver_that_ignores_g_is_wrong_for_g_and_correct_for_the_rest(tmp_path):
    import sys

    engine = command_engine("blind_bead", [sys.executable, str(_gravity_blind_bead(tmp_path))], tmp_path,
                            capabilities=["3d"], where="test")
    case = engine_case(engine, None, None, _scene("bead"), 1e-3, ["theta0", "g"])
    assert case.column_classes == ["correct", "wrong"]
    assert case.column_errors[1] == pytest.approx(1.0, abs=1e-9)  # its d/dg is exactly 0
    assert case.klass == "wrong"


def test_classes_follow_their_definitions():
    assert classify(float("nan"), 1e-3, 1e-9, None, 1.0) == "nan"
    assert classify(1e-2, 1e-2, 1e-9, 5.0, 20.0) == "chaotic"
    assert classify(1e-2, 5e-3, 1e-9, None, 1.0) == "correct"  # first order
    assert classify(1e-2, 0.95e-2, 1e-9, None, 1.0) == "wrong"  # a plateau
    assert classify(5e-10, 5e-10, 1e-9, None, 1.0) == "correct"  # at the floor


def test_xval_grad_json_has_the_documented_fields():
    done = run_xval("grad", "double-pendulum", "--engine", "mujoco/hinge-rk4", "--dt", "1e-3", "--duration", "1",
                    "--wrt", "theta1,g", "--format", "json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert list(answer) == ["scene", "engine", "dt", "duration", "wrt", "outputs", "jacobian", "reference_jacobian",
                            "error", "method", "self_consistency", "class", "horizon"]
    assert answer["engine"] == "mujoco/hinge-rk4" and answer["wrt"] == ["theta1", "g"]
    assert answer["outputs"][:6] == ["p0_x", "p0_y", "p0_z", "v0_x", "v0_y", "v0_z"] and len(answer["outputs"]) == 12
    assert np.shape(answer["jacobian"]) == np.shape(answer["reference_jacobian"]) == (12, 2)
    assert answer["error"] <= 1e-6 and answer["class"] == "correct" and answer["horizon"] is None
    assert answer["method"] == "finite-difference" and answer["self_consistency"] is None


def test_xval_grad_without_engine_is_the_reference_and_says_when_chaotic():
    done = run_xval("grad", "double-pendulum", "--dt", "1e-3", "--duration", "20", "--wrt", "theta1",
                    "--format", "json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["engine"] == "reference/dop853" and answer["method"] == "reference"
    assert answer["class"] == "chaotic" and 2.0 <= answer["horizon"] <= 15.0
    assert math.isfinite(answer["error"])


def test_xval_grad_refuses_an_unknown_parameter_in_one_line():
    done = run_xval("grad", "bead", "--dt", "1e-3", "--duration", "1", "--wrt", "theta1")
    assert done.returncode == 2
    assert done.stderr == ("xval: error: --wrt: bead has no real parameter 'theta1'; choose from: m, radius, theta0, "
                           "omega0, g\n")


@pytest.mark.parametrize("key", list(ONE_SECOND))
def test_drake_autodiff_is_self_consistent_and_second_order_with_rk2(key):
    """AutoDiffXd through the plant and its fixed-step RK2: against differences of its own rollouts ≤ 1e-6
    (measured 2e-11 to 4e-11); against the reference it falls by about 4 as dt halves."""
    engine, variant = registry.resolve("drake/rk2")
    case = engine_case(engine, variant, None, _scene(key), 1e-3, [w for w in WRT[key] if w.startswith(("theta", "omega"))])
    assert case.method == "autodiff" and case.self_consistency <= 1e-6
    assert 1.7 < math.log2(case.error / case.error_half) < 2.3 and case.klass == "correct"


def test_mujoco_rk4_on_the_kuka_model_is_correct_to_1e_6():
    """A model file: outputs the joints' q and v, parameters q0.JOINT and v0.JOINT; MuJoCo's RK4 by differences
    of its rollouts within 1e-6 of Pinocchio's variational equations at dt 1e-3 over 1 s (measured 9e-7)."""
    from engines.model.scene import model_scene

    scene = model_scene("kuka", "pybullet_data:kuka_iiwa/model.urdf",
                        q0={"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}, duration=1.0)
    engine, variant = registry.resolve("mujoco/hinge-rk4")
    case = engine_case(engine, variant, None, scene, 1e-3, ["q0.lbr_iiwa_joint_2", "v0.lbr_iiwa_joint_4"])
    assert case.outputs[:2] == ["q_lbr_iiwa_joint_1", "q_lbr_iiwa_joint_2"]
    assert case.error <= 1e-6 and case.klass == "correct" and case.error_half < case.error


def test_a_rollout_that_blows_up_is_nan_from_its_first_non_finite_sample():
    """ours' explicit Euler with Baumgarte feedback at dt 0.05 s on a 4-link chain: the perturbed runs blow up
    within 5 s (measured at 4.2 s); the Jacobian is nan from that sample on, and the case names it."""
    engine, variant = registry.resolve("ours/baumgarte-euler")
    case = engine_case(engine, variant, None, build("chain", {"n": 4, "duration": 5.0}), 0.05, ["theta0"])
    assert case.klass == "nan" and case.column_classes == ["nan"]
    assert case.first_nonfinite is not None and case.first_nonfinite[1] == "theta0"
    assert 0.05 < case.first_nonfinite[0] <= 5.0
    assert case.error_over_time is not None and np.isfinite(case.error_over_time[0])


def test_a_suite_with_gradients_records_them_and_the_verdict_names_the_wrong_one(tmp_path):
    """[gradients] wrt: each case carries gradient_error, gradient_self_consistency and gradient_wrong (show's
    JSON has them); the verdict lists "wrong gradient" for the solver that ignores g, and only for it."""
    import sys

    program = _gravity_blind_bead(tmp_path)
    suite = tmp_path / "suite.toml"
    engines = f'["mujoco/hinge-rk4", {{ command = ["{sys.executable}", "{program}"], label = "blind-bead" }}]'
    suite.write_text("\n".join([
        'name = "gradients"', "dt = [2e-3, 1e-3]", "duration = 0.5", 'scenes = [{ id = "bead", scene = "bead" }]',
        f"engines = {engines}", 'gradients = { wrt = ["theta0", "g", "theta1"] }', ""]))
    done = run_xval("run", suite, "--output", tmp_path / "out", "--jobs", "1", timeout=600)
    assert done.returncode == 0, done.stderr
    shown = run_xval("show", tmp_path / "out", "--format", "json")
    rows = {(row["engine"], row["dt"]): row for row in json.loads(shown.stdout)}
    mujoco, blind = rows[("mujoco/hinge-rk4", 1e-3)], rows[("command/blind-bead", 1e-3)]
    assert mujoco["gradient_error"] <= 1e-6 and mujoco["gradient_wrong"] == 0
    assert blind["gradient_error"] > 0.1 and blind["gradient_wrong"] == 1
    verdict = json.loads(run_xval("verdict", tmp_path / "out", "--format", "json").stdout)
    text = json.dumps(verdict)
    assert "wrong gradient" in text and text.count("wrong gradient at dt") == 1


def test_an_engine_s_own_sign_flipped_derivative_is_caught_by_both_numbers():
    """A plug-in's Engine.jacobian (here MuJoCo's RK4 adapter answering with the sign flipped, as MuJoCo Warp's
    connect gradients once were): self-consistency against its own rollouts is 2 and the class wrong, while the
    same engine's differences of rollouts are correct."""
    from engines.mujoco.adapter import MuJoCoEngine

    class SignFlipped(MuJoCoEngine):
        def jacobian(self, scene, variant, options, dt, wrt):
            return -finite_difference_jacobian(self, scene, variant, options, dt, wrt).jacobian, "analytic"

    case = engine_case(SignFlipped(), "hinge-rk4", None, _scene("bead"), 1e-3, ["theta0", "g"])
    assert case.method == "analytic" and case.self_consistency == pytest.approx(2.0, rel=1e-9)
    assert case.error == pytest.approx(2.0, rel=1e-6) and case.klass == "wrong"
