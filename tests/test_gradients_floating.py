"""The reference's sensitivities of models with a quaternion in q (a floating base, ball joints): the right-hand
side's Jacobian in xval's coordinates against differences of the right-hand side, the variational solve against
central differences of tight DOP853 solves, closed forms of a free axisymmetric body in g = 0, and engines'
Jacobians (differences of their rollouts) classed against it (engines/model/dynamics.py,
engines/reference/sensitivity.py, engines/scene/parameters.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import run_xval
from engines.model.dynamics import ModelDynamics
from engines.model.scene import model_scene
from engines.reference.reference import solve
from engines.reference.sensitivity import reference_jacobian, relative_error
from engines.scene.parameters import central_difference, model_parameters, output_columns, perturbed

FIXTURES = Path(__file__).resolve().parent / "fixtures"
BASE = "__floating_base__"  # a URDF's floating base, by the name xval gives it


def _scenes():
    """name -> a model scene moving in every direction: the MJCF quadruped (free joint) and the URDF quadruped
    (``base = floating``) turned, drifting, spinning and swinging their legs; the MJCF ball pendulum and the URDF
    ball chain swinging out of plane."""
    base_q, base_v = [0.1, -0.2, 1.0, 0.1, 0.2, 0.05, 1.0], [0.3, -0.2, 0.1, 0.5, -1.0, 0.8]
    return {
        "mjcf-quadruped": lambda: model_scene("q", str(FIXTURES / "mjcf" / "quadruped.xml"), duration=0.5,
                                              q0={"root": base_q, "fl_hip": 20, "br_knee": -30},
                                              v0={"root": base_v, "fl_hip": 1.0, "br_knee": -0.5}),
        "urdf-quadruped": lambda: model_scene("q", str(FIXTURES / "urdf" / "quadruped.urdf"), duration=0.5,
                                              root_joint="floating",
                                              q0={BASE: base_q, "fl_hip": 20, "fl_knee": -40, "br_knee": -30},
                                              v0={BASE: base_v, "fl_hip": 1.0, "br_knee": -0.5}),
        "ball-pendulum": lambda: model_scene("b", str(FIXTURES / "mjcf" / "ball_pendulum.xml"), duration=1.0,
                                             q0={"shoulder": [0.3, 0.1, 0.0, 0.9], "elbow": 20},
                                             v0={"shoulder": [0.5, -1.0, 2.0], "elbow": 1.0}),
        "ball-chain": lambda: model_scene("c", str(FIXTURES / "urdf" / "ball_chain.urdf"), duration=0.5,
                                          q0={"shoulder": [0.2, 0.0, 0.1, 0.95], "wrist": [0.0, 0.3, 0.0, 0.95]},
                                          v0={"shoulder": [0.4, 0.0, -0.6], "wrist": [0.0, 0.8, 0.3], "elbow": 0.5}),
    }


SCENES = _scenes()


@pytest.mark.parametrize("which", list(SCENES))
def test_the_right_hand_side_s_jacobian_is_exact_in_xval_s_coordinates(which):
    """∂f/∂y (quaternion rows and columns included, at a quaternion off the unit sphere) against central differences
    of f with one Richardson step: ≤ 1e-8 relative (the differences' own error;
    measured 3e-12 to 3e-11 here). Pinocchio's tangent-space derivatives are mapped to xval's q here."""
    scene = SCENES[which]()
    dynamics = ModelDynamics(scene)
    rng = np.random.default_rng(3)
    y = dynamics.initial_state(scene)
    y = y + 0.05 * rng.standard_normal(len(y))  # quaternions off unit norm: the rate is not normalised, R is
    rate, jacobian = dynamics.derivatives(y)
    assert np.allclose(rate, dynamics.rhs(0.0, y), rtol=0, atol=1e-12)
    differences = np.array([central_difference(lambda d, e=e: dynamics.rhs(0.0, y + d * e), 1e-4)
                            for e in np.eye(len(y))]).T
    assert relative_error(jacobian, differences) <= 1e-8


@pytest.mark.parametrize("which", list(SCENES))
def test_the_variational_solve_matches_differences_of_tight_solves(which):
    """J from the variational equations against central differences (one Richardson step, h = 1e-3 rad or SI unit)
    of whole DOP853 solves at rtol 2.3e-14: ≤ 1e-8 relative (measured 2e-12 to 5e-11 on these scenes), for a
    quaternion's tangent directions (q0.J.rx …), a base's position and every kind of v0."""
    scene = SCENES[which]()
    every = model_parameters(scene)
    wrt = every[::3] if len(every) > 12 else every
    assert any(name.endswith(".rx") or name.endswith(".ry") or name.endswith(".rz") for name in wrt)
    jacobian = reference_jacobian(scene, wrt, scene.duration)
    assert jacobian.shape == (len(output_columns(scene)), len(wrt))

    def out(moved):
        return solve(moved, 2.3e-14, 1e-15).ode(np.array([scene.duration]))[:, 0]

    differences = np.array([central_difference(lambda d, name=name: out(perturbed(scene, name, d)), 1e-3)
                            for name in wrt]).T
    assert relative_error(jacobian, differences) <= 1e-8


def test_a_quaternion_s_parameters_are_tangent_turns_that_keep_it_unit():
    """q0.J.rx turns the child about its own x axis (Q ⊗ exp(δ/2)): a unit quaternion, turned by exactly δ."""
    scene = SCENES["ball-pendulum"]()
    assert model_parameters(scene) == ["q0.shoulder.rx", "q0.shoulder.ry", "q0.shoulder.rz", "q0.elbow",
                                       "v0.shoulder.wx", "v0.shoulder.wy", "v0.shoulder.wz", "v0.elbow"]
    assert output_columns(scene)[:5] == ["q_shoulder.qx", "q_shoulder.qy", "q_shoulder.qz", "q_shoulder.qw", "q_elbow"]
    before = scene.initial_q[:4]
    after = perturbed(scene, "q0.shoulder.ry", 0.3).initial_q[:4]
    assert np.linalg.norm(after) == pytest.approx(1.0, abs=1e-14)
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_quat(before).inv() * Rotation.from_quat(after)
    np.testing.assert_allclose(turn.as_rotvec(), [0.0, 0.3, 0.0], atol=1e-14)


@pytest.mark.parametrize("spin", [0.0, 2.0])
def test_a_free_axisymmetric_body_in_zero_gravity_matches_its_closed_forms(spin):
    """A free body (its rotor at rest relative to it: one rigid body, I1 = I2 = 0.11, I3 = 0.06 kg·m², centre of
    mass at the base origin) spinning at ``spin`` rad/s about its axis, g = 0, over T = 1 s. Exact: the base's
    world velocity R v holds, so d p(T)/d v0 = T·R0 = T·I and d v(T)/d v0 = R(T)ᵀ (v in the base frame); the quaternion's
    d Q(T)/d ω3 = Q0 ⊗ (0, 0, T/2 cos(sT/2), −T/2 sin(sT/2)), and (ω1, ω2) turned by Ω T, Ω = (I3 − I1)/I1 · s
    (Euler's equations): ≤ 1e-9."""
    t = 1.0
    scene = model_scene("gyro", str(FIXTURES / "mjcf" / "free_gyro.xml"), g=0.0, duration=t,
                        v0={"free": [0, 0, 0, 0, 0, spin]})
    wrt = ["v0.free.vx", "v0.free.vy", "v0.free.vz", "v0.free.wx", "v0.free.wy", "v0.free.wz"]
    jacobian = reference_jacobian(scene, wrt, t)
    rows = {name: k for k, name in enumerate(output_columns(scene))}
    c, s = np.cos(spin * t), np.sin(spin * t)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # R(T): the spin about z
    expected = np.zeros_like(jacobian)
    expected[[rows["q_free.x"], rows["q_free.y"], rows["q_free.z"]], :3] = t * np.eye(3)  # R0 = I
    linear = [rows[f"v_free.v{a}"] for a in "xyz"]
    expected[np.ix_(linear, range(3))] = turn.T
    expected[rows["q_free.qz"], 5] = t / 2 * np.cos(spin * t / 2)
    expected[rows["q_free.qw"], 5] = -t / 2 * np.sin(spin * t / 2)
    if spin == 0:  # no spin: dQ/dω is ½ T for each axis
        expected[[rows["q_free.qx"], rows["q_free.qy"]], [3, 4]] = t / 2
    else:  # d Q(T) / d ω1, ω2 has no closed form this short; the body's ω has
        expected[[rows["q_free.qx"], rows["q_free.qy"]], 3] = jacobian[[rows["q_free.qx"], rows["q_free.qy"]], 3]
        expected[[rows["q_free.qx"], rows["q_free.qy"]], 4] = jacobian[[rows["q_free.qx"], rows["q_free.qy"]], 4]
    precession = (0.06 - 0.11) / 0.11 * spin * t
    cp, sp = np.cos(precession), np.sin(precession)
    angular = [rows[f"v_free.w{a}"] for a in "xyz"]
    expected[np.ix_(angular, range(3, 6))] = [[cp, -sp, 0], [sp, cp, 0], [0, 0, 1]]
    assert relative_error(jacobian, expected) <= 1e-9


@pytest.mark.parametrize("which, engine_id, wrt", [
    ("urdf-quadruped", "mujoco/hinge-rk4", [f"q0.{BASE}.z", f"q0.{BASE}.rx", "q0.fl_hip", f"v0.{BASE}.wz", "v0.br_knee"]),
    ("urdf-quadruped", "dart/rk4", [f"q0.{BASE}.rx", f"v0.{BASE}.wz", "v0.br_knee"]),
    ("urdf-quadruped", "ours/baumgarte-rk4", [f"q0.{BASE}.z", f"q0.{BASE}.rx", "q0.fl_hip", f"v0.{BASE}.wz"]),
    ("ball-chain", "mujoco/hinge-rk4", ["q0.shoulder.ry", "q0.wrist.rz", "v0.wrist.wx", "v0.elbow"]),
    ("ball-chain", "ours/baumgarte-rk4", ["q0.shoulder.ry", "q0.wrist.rz", "v0.wrist.wx", "v0.elbow"]),
])
def test_rk4_engines_differences_of_rollouts_are_correct_on_floating_and_ball_models(which, engine_id, wrt):
    """Every engine's Jacobian of such a model (differences of its rollouts) against the reference: the RK4 variants
    at dt 1e-3 over 0.5 s are ``correct``, ≤ 1e-6 (measured 4e-11 to 7e-10)."""
    from compare.gradients.measure import engine_case
    from engines import registry

    engine, variant = registry.resolve(engine_id)
    case = engine_case(engine, variant, None, SCENES[which](), 1e-3, wrt)
    assert case.klass == "correct" and case.error <= 1e-6, (case.klass, case.error)


def test_xval_grad_answers_for_a_ball_joint_model():
    """The command a user runs, on the MJCF ball pendulum with MuJoCo's RK4 (measured: error 6.8e-11, correct)."""
    done = run_xval("grad", "--model", str(FIXTURES / "mjcf" / "ball_pendulum.xml"), "--engine", "mujoco/hinge-rk4",
                    "--dt", "1e-3", "--duration", "1", "--param", "q0.shoulder=0.3,0.1,0,0.9", "--param", "q0.elbow=20",
                    "--param", "v0.shoulder=0.5,-1,2", "--param", "v0.elbow=1",
                    "--wrt", "q0.shoulder.rx,q0.elbow,v0.shoulder.wz", "--format", "json", timeout=600)
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["outputs"][:5] == ["q_shoulder.qx", "q_shoulder.qy", "q_shoulder.qz", "q_shoulder.qw", "q_elbow"]
    assert answer["method"] == "finite-difference" and answer["class"] == "correct" and answer["error"] <= 1e-6
    assert np.shape(answer["jacobian"]) == (9, 3)


def test_a_ball_joint_s_parameter_is_named_by_its_tangent():
    """q0.shoulder (the whole quaternion) is no direction: the one-line error lists the tangent's names."""
    done = run_xval("grad", "--model", str(FIXTURES / "mjcf" / "ball_pendulum.xml"), "--dt", "1e-3", "--duration",
                    "0.1", "--wrt", "q0.shoulder")
    assert done.returncode == 2 and done.stderr.strip().splitlines()[-1] == (
        "xval: error: --wrt: ball_pendulum has no real parameter 'q0.shoulder'; choose from: q0.shoulder.rx, "
        "q0.shoulder.ry, q0.shoulder.rz, q0.elbow, v0.shoulder.wx, v0.shoulder.wy, v0.shoulder.wz, v0.elbow")


def test_an_engine_that_misreads_the_file_is_judged_on_the_file_s_physics():
    """DART's MJCF reader ignores ``<inertial>`` (docs/models.md), so on the MJCF ball pendulum its trajectory is
    another pendulum's, and its Jacobian (differences of its RK4 rollouts) is ``wrong``: off by as much at dt/2."""
    from compare.gradients.measure import engine_case
    from engines import registry

    engine, variant = registry.resolve("dart/rk4")
    case = engine_case(engine, variant, None, SCENES["ball-pendulum"](), 1e-3, ["q0.shoulder.rx", "v0.shoulder.wz"])
    assert case.klass == "wrong" and case.error > 0.1 and case.error_half > 0.1
