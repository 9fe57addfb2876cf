"""ours on robot models: the engine-neutral description (engines/model) translated to ours.rigid, checked
against Pinocchio's forward dynamics integrated by scipy's DOP853 (rtol 1e-13) in this file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from engines.errors import Unsupported
from engines.model import pinocchio as reference
from engines.model.kinematics import link_poses
from engines.model.source import resolve
from engines.model.urdf import read
from engines.ours.model import link_origins, run, translate

MODELS = Path(__file__).resolve().parent.parent / "models"


def _load(name: str):
    source = resolve(name, MODELS)
    description = read(source)
    return description, reference.load(source, description)


def _reference_links(description, pinocchio, q0, v0, times):
    """Each link frame's origin (len(times), links, 3) m along Pinocchio's forward dynamics."""
    n = description.nq

    def rhs(_, s):
        return np.concatenate([s[n:], pinocchio.forward(s[:n], s[n:], np.zeros(n))])

    sol = solve_ivp(rhs, (0.0, times[-1]), np.concatenate([q0, v0]), method="DOP853", rtol=1e-13, atol=1e-14,
                    t_eval=times)
    links = [b.name for b in description.bodies]
    return np.array([[link_poses(description, q)[name][1] for name in links] for q in sol.y[:n].T]), sol.y[:n].T


def _distance_from_reference(name, q0, v0, method, dts, t_end=2.0, samples=50):
    description, pinocchio = _load(name)
    model = translate(description)
    names = [j.name for j in description.moving_joints]
    times = np.linspace(0.0, t_end, samples + 1)
    links = [b.name for b in description.bodies]
    expected, expected_q = _reference_links(description, pinocchio, np.array(q0), np.array(v0), times)
    errors, q_errors, gaps = [], [], []
    for dt in dts:
        n = int(round(t_end / dt))
        result, q, _ = run(model, dict(zip(names, q0)), dict(zip(names, v0)), dt, n, n // samples,
                           method=method, integrator="rk4")
        assert result.status == "ok"
        errors.append(np.linalg.norm(link_origins(model, result.y, links) - expected, axis=-1).max())
        q_errors.append(np.abs(q - expected_q).max())
        from ours.rigid import joint_errors

        gaps.append(joint_errors(model.mechanism, result.y)[0].max())
    return np.array(errors), np.array(q_errors), np.array(gaps)


@pytest.mark.parametrize("method", ["baumgarte", "projection"])
def test_double_pendulum_fixture_matches_pinocchio_to_fourth_order(method):
    errors, q_errors, gaps = _distance_from_reference("double_pendulum.urdf", [0.9, -0.6], [0.3, 1.1], method,
                                                      [4e-3, 2e-3, 1e-3])
    assert errors[-1] <= 1e-9 and q_errors[-1] <= 3e-9  # m (the bound) and rad, at dt 1e-3 over 2 s
    assert np.all(np.abs(np.log2(errors[:-1] / errors[1:]) - 4) < 0.3), errors
    if method == "projection":
        assert gaps.max() <= 1e-10  # m: the joints held


def test_cart_pole_fixture_prismatic_and_revolute_match_pinocchio():
    errors, q_errors, _ = _distance_from_reference("cart_pole.urdf", [0.1, 0.4], [0.5, -1.0], "projection",
                                                   [1e-3], t_end=1.0)
    assert errors[-1] <= 1e-9 and q_errors[-1] <= 1e-9


def test_kuka_iiwa_matches_pinocchio():
    """Seven revolute joints with rotated origins and offset inertias: the translation at full stretch."""
    errors, q_errors, _ = _distance_from_reference("pybullet_data:kuka_iiwa/model.urdf", [0.3] * 7, [0.5] * 7,
                                                   "projection", [1e-3], t_end=0.5, samples=10)
    assert errors[-1] <= 1e-8 and q_errors[-1] <= 1e-8


def test_links_welded_to_the_root_are_the_world_and_welded_children_are_fused():
    description, _ = _load("pitfalls/fixed_rpy.urdf")
    model = translate(description)
    fixed = [j for j in description.joints if j.type == "fixed"]
    assert len(model.mechanism.bodies) == description.nq
    assert all(model.carriers[j.child][0] == model.carriers[j.parent][0] for j in fixed)
    total = sum(b.inertial.mass for b in description.bodies if model.carriers[b.name][0] >= 0)
    assert sum(b.mass for b in model.mechanism.bodies) == pytest.approx(total, rel=1e-15)


def test_a_massless_link_carrying_a_welded_tool_moves_as_the_tool():
    """pitfalls/no_inertial.urdf: "sensor" declares nothing, the 2 kg "tool" is welded to it; fused, they
    are one body of 2 kg (as Pinocchio, MuJoCo and Drake read it)."""
    errors, q_errors, _ = _distance_from_reference("pitfalls/no_inertial.urdf", [0.2, -0.4], [0.0, 1.0],
                                                   "projection", [1e-3], t_end=1.0)
    # RK4's own error at dt 1e-3 is ~2e-9 m and ~1e-8 rad here; a tool left out or misplaced is off by cm
    assert errors[-1] <= 1e-8 and q_errors[-1] <= 3e-8


def test_a_moving_link_without_mass_is_refused_naming_it(tmp_path):
    path = tmp_path / "empty_link.urdf"
    path.write_text('''<robot name="empty_link"><link name="base"/><link name="ghost"/>
      <joint name="hinge" type="revolute"><parent link="base"/><child link="ghost"/><axis xyz="0 1 0"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>''')
    with pytest.raises(Unsupported, match=r"ours: the moving link ghost has mass 0 kg .* maximal coordinates need a "
                                          r"positive mass and inertia for every moving body"):
        translate(read(resolve(str(path))))


def test_the_stepper_advancing_in_chunks_is_the_one_call_run_bit_for_bit():
    """OursStepper (the model scenes' stepping protocol) against run(): same kernel, same arithmetic;
    angles read continuously through several turns of a fast joint."""
    from types import SimpleNamespace

    from engines.ours.model import OursStepper

    description, _ = _load("double_pendulum.urdf")
    q0, v0 = np.array([0.9, -0.6]), np.array([0.3, 60.0])  # the whirl turns the shoulder over and over
    scene = SimpleNamespace(description=description, initial_q=q0, initial_v=v0, model="double_pendulum.urdf")
    stepper = OursStepper(scene, 1e-3, "projection", "rk4")
    samples = [stepper.state()]
    for _ in range(50):  # 20 steps between samples: under half a turn each
        stepper.advance(20)
        samples.append(stepper.state())
    names = [j.name for j in description.moving_joints]
    _, q, v = run(translate(description), dict(zip(names, q0)), dict(zip(names, v0)), 1e-3, 1000, 20,
                  method="projection", integrator="rk4")
    np.testing.assert_array_equal(np.array([s[0] for s in samples]), q)
    np.testing.assert_array_equal(np.array([s[1] for s in samples]), v)
    assert np.abs(q).max() > 4 * np.pi  # a joint went round twice: read on, not wrapped back
