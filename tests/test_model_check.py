"""`xval model check`: each fixture's verdict against an independent computation written out in the test
(closed forms, and the 1 kg / dropped-inertia substitutions by hand), pybullet_data's arms, bad input.
Every engine is real; rotations here come from scipy, not from xval's own kinematics."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import eigh
from scipy.spatial.transform import Rotation

from compare.model.parity import TOLERANCE, check, read_description
from engines.model.importers import ENGINES, REFERENCE, importer
from cli_support import run_cli

MODELS = Path(__file__).resolve().parents[1] / "models"
G = 9.81
ALL = (*ENGINES, REFERENCE)


def loaded(path, engine, **options):
    source, model = read_description(str(path))
    return importer(engine).load(source, model, **options)


def verdicts(path, **kw) -> dict[str, bool]:
    return {e.engine: e.agrees for e in check(str(path), states=10, **kw).engines}


def rpy(r, p, y) -> np.ndarray:
    """URDF rpy: fixed axes x, then y, then z."""
    return Rotation.from_euler("xyz", [r, p, y]).as_matrix()


def revolute_mass_matrix(axes, points, bodies) -> np.ndarray:
    """M at one configuration of a serial chain of revolute joints, from the Jacobian sum
    M_ij = sum_k m_k (a_i x (c_k - p_i)) . (a_j x (c_k - p_j)) + a_i . I_k a_j over the links k that both
    joints move. axes, points: per joint (world); bodies: per joint, the list of (m, com, I) it moves."""
    n = len(axes)
    m = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            for mass, com, inertia in bodies[max(i, j)]:
                vi, vj = np.cross(axes[i], com - points[i]), np.cross(axes[j], com - points[j])
                m[i, j] += mass * vi @ vj + axes[i] @ inertia @ axes[j]
    return m


# -- the compound double pendulum ----------------------------------------------------------------

M1, L1, C1, M2, C2, R = 1.0, 1.0, 0.5, 2.0, 0.4, 0.02
I1 = M1 * (3 * R**2 + L1**2) / 12
I2 = M2 * (3 * R**2 + 0.8**2) / 12


def pendulum_m(q2: float) -> np.ndarray:
    m11 = I1 + M1 * C1**2 + I2 + M2 * (L1**2 + C2**2 + 2 * L1 * C2 * np.cos(q2))
    m12 = I2 + M2 * (C2**2 + L1 * C2 * np.cos(q2))
    return np.array([[m11, m12], [m12, I2 + M2 * C2**2]])


def pendulum_gravity(q1: float, q2: float) -> np.ndarray:
    return G * np.array([M1 * C1 * np.sin(q1) + M2 * (L1 * np.sin(q1) + C2 * np.sin(q1 + q2)),
                         M2 * C2 * np.sin(q1 + q2)])


@pytest.mark.parametrize("engine", ALL)
def test_every_engine_holds_the_double_pendulum_written_out_by_hand(engine):
    model = loaded(MODELS / "double_pendulum.urdf", engine)
    for q in ([0.0, 0.0], [0.7, -1.2], [2.5, 0.4]):
        q = np.array(q)
        np.testing.assert_allclose(model.mass_matrix(q), pendulum_m(q[1]), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(model.bias(q, np.zeros(2)), pendulum_gravity(*q), rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("engine", ALL)
def test_the_double_pendulum_linearised_in_each_engine_has_the_analytic_frequencies(engine):
    """omega^2 are the eigenvalues of (K, M0); each engine's K is the derivative of its gravity torque at rest."""
    k = G * np.array([[M1 * C1 + M2 * (L1 + C2), M2 * C2], [M2 * C2, M2 * C2]])
    analytic = np.sqrt(eigh(k, pendulum_m(0.0), eigvals_only=True))
    model, h = loaded(MODELS / "double_pendulum.urdf", engine), 1e-6
    stiffness = np.column_stack([(model.bias(h * e, np.zeros(2)) - model.bias(-h * e, np.zeros(2))) / (2 * h)
                                 for e in np.eye(2)])
    measured = np.sqrt(eigh((stiffness + stiffness.T) / 2, model.mass_matrix(np.zeros(2)), eigvals_only=True))
    np.testing.assert_allclose(measured, analytic, rtol=1e-8)
    assert analytic == pytest.approx([2.71236, 8.57180], abs=1e-5)  # rad/s: the closed form above, evaluated


def test_the_double_pendulum_and_the_cart_pole_agree_everywhere():
    assert verdicts(MODELS / "double_pendulum.urdf") == dict.fromkeys(ENGINES, True)
    assert verdicts(MODELS / "cart_pole.urdf") == dict.fromkeys(ENGINES, True)


@pytest.mark.parametrize("engine", ALL)
def test_every_engine_holds_the_cart_pole_written_out_by_hand(engine):
    mc, mp, c, iyy = 2.0, 0.5, 0.3, 0.015
    model = loaded(MODELS / "cart_pole.urdf", engine)
    for x, theta in ((0.0, 0.0), (0.5, 1.0), (-1.2, 4.0)):
        q = np.array([x, theta])
        expected = np.array([[mc + mp, mp * c * np.cos(theta)], [mp * c * np.cos(theta), iyy + mp * c**2]])
        np.testing.assert_allclose(model.mass_matrix(q), expected, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(model.bias(q, np.zeros(2)), [0.0, -mp * G * c * np.sin(theta)], atol=1e-12)


# -- pitfalls --------------------------------------------------------------------------------------

def test_rotated_and_offset_inertial_frames_by_hand_in_every_engine():
    r_arm = rpy(0.4, -0.3, 0.7)
    i_arm = r_arm @ np.array([[0.05, 0.01, 0], [0.01, 0.08, 0], [0, 0, 0.11]]) @ r_arm.T
    r_joint = rpy(0.3, 0, 0)  # the pitch joint's frame, at (0.5, 0, 0)
    r_fore = r_joint @ rpy(1.1, 0.2, -0.4)
    i_fore = r_fore @ np.array([[0.01, 0.002, -0.001], [0.002, 0.02, 0.003], [-0.001, 0.003, 0.025]]) @ r_fore.T
    c_fore = np.array([0.5, 0, 0]) + r_joint @ np.array([0.2, 0, 0])
    arm, fore = (1.5, np.array([0.3, 0.1, 0.2]), i_arm), (0.8, c_fore, i_fore)
    expected = revolute_mass_matrix([np.array([0, 0, 1.0]), r_joint @ np.array([0, 1.0, 0])],
                                    [np.zeros(3), np.array([0.5, 0, 0])], [[arm, fore], [fore]])
    for engine in ALL:
        # PyBullet diagonalises the inertia less exactly (1e-10 of M's largest entry measured; the tolerance is 1e-6).
        np.testing.assert_allclose(loaded(MODELS / "pitfalls/rotated_inertial.urdf", engine).mass_matrix(np.zeros(2)),
                                   expected, rtol=0, atol=1e-9 * np.abs(expected).max(), err_msg=engine)
    assert verdicts(MODELS / "pitfalls/rotated_inertial.urdf") == dict.fromkeys(ENGINES, True)


def test_a_fixed_joint_with_rpy_carrying_a_massive_link_by_hand():
    r_tool = rpy(0.3, 0.5, -0.2)
    c_tool = np.array([0.4, 0, 0.1]) + r_tool @ np.array([0.1, 0.05, 0])
    bodies = [(0.5, np.array([0.2, 0, 0]), np.diag([0.001, 0.007, 0.007])),
              (5.0, c_tool, r_tool @ np.diag([0.2, 0.3, 0.4]) @ r_tool.T)]
    axis = np.array([0, 1.0, 0])
    expected_m = revolute_mass_matrix([axis], [np.zeros(3)], [bodies])
    # gravity torque b = -axis . sum(c x m g): the moment of the weights about the hinge
    expected_g = -axis @ sum(np.cross(c, m * np.array([0, 0, -G])) for m, c, _ in bodies)
    for engine in ALL:
        model = loaded(MODELS / "pitfalls/fixed_rpy.urdf", engine)
        np.testing.assert_allclose(model.mass_matrix(np.zeros(1)), expected_m, rtol=1e-12, err_msg=engine)
        np.testing.assert_allclose(model.bias(np.zeros(1), np.zeros(1)), [expected_g], rtol=1e-12, err_msg=engine)
    assert verdicts(MODELS / "pitfalls/fixed_rpy.urdf") == dict.fromkeys(ENGINES, True)


def test_a_moving_link_without_inertial_pybullet_and_dart_give_it_1_kg():
    path = MODELS / "pitfalls/no_inertial.urdf"
    axis = np.array([0, 1.0, 0])
    arm = (1.0, np.array([0.25, 0, 0]), np.diag([0.001, 0.02, 0.02]))
    tool = (2.0, np.array([0.8, 0, 0]), 0.004 * np.eye(3))
    sensor_1kg = (1.0, np.array([0.5, 0, 0]), np.eye(3))  # the substitution: 1 kg at the link origin, 1 kg·m²
    points = [np.zeros(3), np.array([0.5, 0, 0])]
    as_written = revolute_mass_matrix([axis, axis], points, [[arm, tool], [tool]])
    substituted = revolute_mass_matrix([axis, axis], points, [[arm, tool, sensor_1kg], [tool, sensor_1kg]])
    for engine in ALL:
        expected = substituted if engine in ("pybullet", "dart") else as_written
        np.testing.assert_allclose(loaded(path, engine).mass_matrix(np.zeros(2)), expected, rtol=1e-12, err_msg=engine)
    report = check(str(path), states=10)
    assert {e.engine: e.agrees for e in report.engines} == {"mujoco": True, "pybullet": False, "drake": True, "dart": False}
    assert report.diagnosis == ("link sensor: no <inertial> — pybullet gives it 1 kg and 1 kg·m², "
                                "dart gives it 1 kg and 1 kg·m²",)


def test_a_zero_mass_link_with_inertia_mujoco_drops_it_drake_gives_it_1_kg():
    path = MODELS / "pitfalls/zero_mass_inertia.urdf"
    arm_zz, as_written = 0.06 + 2.0 * 0.3**2, 0.06 + 2.0 * 0.3**2 + 0.1
    q0 = np.zeros(1)
    for engine in ("pinocchio", "pybullet", "dart"):
        assert loaded(path, engine).mass_matrix(q0)[0, 0] == pytest.approx(as_written, rel=1e-12)
    assert loaded(path, "mujoco").mass_matrix(q0)[0, 0] == pytest.approx(arm_zz, rel=1e-12)  # the 0.1 dropped
    drake = loaded(path, "drake")
    flange = drake.link_inertias()["flange"]
    assert flange.mass == pytest.approx(1.0, rel=1e-12) and 0 < flange.inertia[2, 2] < 0.01
    assert drake.mass_matrix(q0)[0, 0] == pytest.approx(arm_zz + 1.0 * 0.6**2 + flange.inertia[2, 2], rel=1e-12)
    report = check(str(path), states=10)
    assert {e.engine: e.agrees for e in report.engines} == {"mujoco": False, "pybullet": True, "drake": False, "dart": True}
    assert report.diagnosis[0].startswith("link flange: mass 0 with inertia 0.1 kg·m² — mujoco drops the inertia, "
                                          "drake gives it 1 kg and ")


def test_a_continuous_joint_is_one_angle_in_every_engine():
    m, c, iyy = 1.2, 0.4, 0.02
    for engine in ALL:
        model = loaded(MODELS / "pitfalls/continuous.urdf", engine)
        for angle in (0.3, 7.0, -9.5):  # beyond a turn: Pinocchio's (cos, sin) must see the same angle
            q = np.array([angle])
            assert model.mass_matrix(q)[0, 0] == pytest.approx(iyy + m * c**2, rel=1e-12)
            assert model.bias(q, np.zeros(1))[0] == pytest.approx(m * G * c * np.sin(angle), rel=1e-12)
    assert verdicts(MODELS / "pitfalls/continuous.urdf") == dict.fromkeys(ENGINES, True)


def test_an_inertia_against_the_triangle_inequality_mujoco_refuses_unless_asked():
    path = MODELS / "pitfalls/triangle_inequality.urdf"
    report = check(str(path), states=10)
    mujoco = report.engines[0]
    assert (mujoco.engine, mujoco.loaded, mujoco.agrees) == ("mujoco", False, False)
    assert mujoco.message == "Error: inertia must satisfy A + B >= C; use 'balanceinertia' to fix Element name 'plate', id 2"
    assert mujoco.options["balanceinertia"] == "false"  # what it was given, stated though it refused
    # PyBullet drops such an inertia (keeps the mass): M = m r^2 instead of izz + m r^2.
    assert loaded(path, "pybullet").mass_matrix(np.zeros(1))[0, 0] == pytest.approx(1.0 * 0.2**2, rel=1e-12)
    assert loaded(path, "pinocchio").mass_matrix(np.zeros(1))[0, 0] == pytest.approx(0.05 + 0.2**2, rel=1e-12)
    balanced = check(str(path), engines=("mujoco",), states=10, balance_inertia=True).engines[0]
    assert balanced.loaded and not balanced.agrees and balanced.options["balanceinertia"] == "true"


def test_missing_meshes_are_left_out_with_a_note():
    report = check(str(MODELS / "pitfalls/missing_meshes.urdf"), states=10)
    assert all(e.agrees for e in report.engines)
    assert report.notes == ("dynamics need no geometry: 2 <visual> and 1 <collision> elements removed before import "
                            "(3 mesh files they name are not there: meshes/arm_does_not_exist.stl, "
                            "meshes/base_does_not_exist.stl, package://nowhere/meshes/arm.stl)",)


# -- pybullet_data's arms, through the command -------------------------------------------------

def test_the_kuka_arm_agrees_everywhere(capsys):
    code, out, err = run_cli(capsys, "model", "check", "pybullet_data:kuka_iiwa/model.urdf", "--states", "20",
                             "--format", "json")
    report = json.loads(out)
    assert (code, err) == (0, "")
    assert [(e["engine"], e["loaded"], e["agrees"]) for e in report["engines"]] == [(e, True, True) for e in ENGINES]
    assert max(e[q] for e in report["engines"] for q in ("mass_matrix", "bias", "forward")) < 1e-11
    assert report["reference"]["name"] == "pinocchio" and report["states"] == 20
    assert report["diagnosis"] == [] and report["reference"]["diagnosis"] == []


def test_a_model_whose_bias_is_round_off_agrees():
    """r2d2's joints all turn about vertical axes: |b| is 1e-18, measured against the sample's torques."""
    assert verdicts("pybullet_data:r2d2.urdf") == dict.fromkeys(ENGINES, True)


def test_the_panda_flags_mujoco_and_drake_and_names_the_two_links(capsys):
    code, out, err = run_cli(capsys, "model", "check", "pybullet_data:franka_panda/panda.urdf", "--states", "20")
    assert (code, err) == (1, "")
    rows = {line.split()[0]: line.split()[-1] for line in out.splitlines()[2:6]}
    assert rows == {"mujoco": "no", "pybullet": "yes", "drake": "no", "dart": "yes"}
    assert ("links panda_link8, panda_grasptarget: mass 0 with inertia 0.1 kg·m² — mujoco drops the inertia, "
            "drake gives them 1 kg and ") in out


def test_the_json_has_one_entry_per_engine_with_the_three_differences(capsys):
    code, out, _ = run_cli(capsys, "model", "check", MODELS / "pitfalls/no_inertial.urdf", "--engine", "pybullet",
                           "--states", "3", "--seed", "7", "--format", "json")
    report = json.loads(out)
    assert code == 1
    assert set(report) >= {"model", "reference", "states", "seed", "tolerance", "engines", "diagnosis"}
    assert report["tolerance"] == TOLERANCE and report["seed"] == 7
    (entry,) = report["engines"]
    assert set(entry) >= {"engine", "loaded", "agrees", "mass_matrix", "bias", "forward", "diagnosis"}
    assert entry["diagnosis"] == ["link sensor: no <inertial> — pybullet gives it 1 kg and 1 kg·m²"]


# -- bad input: one line, exit 2, nothing on stdout ------------------------------------------------

BAD = {
    "malformed.urdf": ('<robot name="r"><link name="a"></robot>',
                      r"model .*malformed.urdf: not well-formed XML \(mismatched tag: line 1, column 33\); fix the file"),
    "planar.urdf": ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
                    '<inertia ixx="1" iyy="1" izz="1"/></inertial></link><joint name="slide" type="planar">'
                    '<parent link="a"/><child link="b"/></joint></robot>',
                    r"joint slide: type 'planar' is not supported; use one of revolute, continuous, prismatic, fixed"),
    "negative.urdf": ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="-2"/>'
                      '<inertia ixx="1" iyy="1" izz="1"/></inertial></link><joint name="j" type="continuous">'
                      '<parent link="a"/><child link="b"/></joint></robot>',
                      r"link b: mass -2 kg is negative or not finite; give <inertial><mass value=…> a value ≥ 0"),
    "indefinite.urdf": ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
                        '<inertia ixx="1" ixy="2" iyy="1" izz="1"/></inertial></link><joint name="j" '
                        'type="continuous"><parent link="a"/><child link="b"/></joint></robot>',
                        r"link b: the inertia is not positive semidefinite \(principal moments -1, 1, 3 kg·m²\); "),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input_is_one_line_and_exit_2(capsys, tmp_path, name):
    text, message = BAD[name]
    (tmp_path / name).write_text(text)
    code, out, err = run_cli(capsys, "model", "check", tmp_path / name)
    assert (code, out) == (2, "")
    assert len(err.splitlines()) == 1
    assert re.match(rf"xval: error: {message}", err), err


def test_a_missing_file_is_one_line_and_exit_2(capsys, tmp_path):
    code, out, err = run_cli(capsys, "model", "check", tmp_path / "nowhere.urdf")
    assert (code, out) == (2, "")
    assert err.startswith(f"xval: error: model {tmp_path / 'nowhere.urdf'}: no such file") and err.count("\n") == 1


def test_the_mjcf_double_pendulum_is_the_urdf_one_and_which_engines_hold_its_inertials():
    """The MJCF description (MuJoCo's compiled model) equals the hand-written M; PyBullet's loadMJCF drops
    the inertias and DART's MjcfParser gives every body 1 kg and 1 kg·m² (measured; docs/models.md)."""
    path = MODELS / "double_pendulum.xml"
    for engine in ("mujoco", "drake", "pinocchio"):
        model = loaded(path, engine)
        for q in ([0.0, 0.0], [0.7, -1.2]):
            np.testing.assert_allclose(model.mass_matrix(np.array(q)), pendulum_m(q[1]), rtol=1e-12, err_msg=engine)
    report = check(str(path), states=10)
    assert {e.engine: e.agrees for e in report.engines} == {"mujoco": True, "pybullet": False, "drake": True, "dart": False}
    assert report.notes == ("the description of an MJCF file is MuJoCo's compiled model",)
    dart = {name: link.mass for name, link in loaded(path, "dart").link_inertias().items()}
    assert dart == {"rod1": 1.0, "rod2": 1.0}


def test_an_unknown_engine_is_a_usage_error_pointing_at_the_subcommand(capsys):
    code, out, err = run_cli(capsys, "model", "check", "pybullet_data:kuka_iiwa/model.urdf", "--engine", "ode")
    assert (code, out) == (2, "")
    assert err == ("xval: error: Invalid value for '--engine': 'ode' is not one of 'mujoco', 'pybullet', 'drake', "
                   "'dart'. (see 'xval model check --help')\n")
