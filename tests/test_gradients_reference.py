"""The reference's sensitivities (engines/reference/sensitivity.py) against closed forms and an independent solve."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engines.errors import Unsupported, UserError
from engines.reference.closed_form import normal_modes
from engines.reference.sensitivity import (
    bound_sensitivity,
    finite_difference_reference,
    output_columns,
    relative_error,
    reference_jacobian,
)
from engines.scene.catalog import build


def _rotation(omegas: np.ndarray, shapes: np.ndarray, t: float) -> np.ndarray:
    """(2n, 2n) d(θ, θ̇)(t) / d(θ, θ̇)(0) of the linearised chain: each normal mode turns in its phase plane."""
    inverse = np.linalg.inv(shapes)

    def modal(diagonal):
        return shapes @ np.diag(diagonal) @ inverse

    c, s = np.cos(omegas * t), np.sin(omegas * t)
    return np.block([[modal(c), modal(s / omegas)], [modal(-omegas * s), modal(c)]])


def test_bead_at_rest_turns_its_perturbations_as_the_small_oscillation_solution():
    """At the bottom, θ(t) = θ0' cos ωt + ω0'/ω sin ωt exactly for the perturbations, ω = √(g/R);
    x = R sin θ and v_x = R θ̇ move with them, z = −R moves with the radius only, g moves nothing."""
    radius, g, t = 0.7, 9.81, 1.3
    scene = build("bead", {"theta0": 0, "radius": radius, "g": g, "duration": t})
    wrt = ["theta0", "omega0", "radius", "g"]
    jacobian = reference_jacobian(scene, wrt, t)
    w = math.sqrt(g / radius)
    exact = np.zeros((6, 4))
    exact[0, :2] = radius * math.cos(w * t), radius * math.sin(w * t) / w  # p0_x
    exact[3, :2] = -radius * w * math.sin(w * t), radius * math.cos(w * t)  # v0_x
    exact[2, 2] = -1.0  # p0_z = −R
    assert output_columns(scene) == ["p0_x", "p0_y", "p0_z", "v0_x", "v0_y", "v0_z"]
    assert relative_error(jacobian, exact) <= 1e-9


def test_double_pendulum_at_rest_rotates_each_normal_mode_in_phase_space():
    t = 2.0
    scene = build("double-pendulum", {"theta1": 0, "theta2": 0, "duration": t})
    wrt = ["theta1", "theta2", "omega1", "omega2"]
    rotation = _rotation(*normal_modes([1.0, 1.0], [1.0, 1.0], 9.81), t)  # d(θ1 θ2 θ̇1 θ̇2)(t) / d(...)(0)
    exact = np.zeros((12, 4))
    exact[0], exact[6] = rotation[0], rotation[0] + rotation[1]  # p0_x = sin θ1, p1_x = sin θ1 + sin θ2 (l = 1)
    exact[3], exact[9] = rotation[2], rotation[2] + rotation[3]  # v0_x, v1_x
    assert relative_error(reference_jacobian(scene, wrt, t), exact) <= 1e-9


@pytest.mark.parametrize("name, params, wrt, steps", [
    ("double-pendulum", {"duration": 1.0}, ["theta1", "omega2", "g", "m1", "l2"], None),
    ("chain", {"n": 8, "duration": 1.0}, ["theta0", "g", "length"], {"length": 2.5e-4}),
], ids=["double-pendulum", "chain-8"])
def test_variational_solve_matches_differences_of_whole_reference_solves(name, params, wrt, steps):
    """Central differences of tight solves with one Richardson step (error O(h⁴)); the chain's lengths
    (0.25 m) need a smaller step than 1e-3 m for that error to be under 1e-9 (measured: 2e-9 at 5e-4)."""
    scene = build(name, params)
    jacobian = reference_jacobian(scene, wrt, 1.0)
    assert np.abs(jacobian).max() > 0.1
    assert relative_error(jacobian, finite_difference_reference(scene, wrt, 1.0, steps)) <= 1e-8


def test_double_pendulum_over_20_s_is_resolved_only_up_to_a_horizon():
    """The default double pendulum is chaotic (Lyapunov exponent about 1/s): its Jacobian's norm grows by
    orders of magnitude, and the two solves part past a horizon well inside the run."""
    bound = bound_sensitivity(build("double-pendulum", {"duration": 20.0}), ["theta1", "omega2"],
                              times=np.linspace(0.0, 20.0, 401))
    assert bound.horizon is not None and 2.0 <= bound.horizon <= 15.0
    assert bound.growth[-1] > 1e5 * bound.growth[0]
    assert bound.difference[bound.t < 1.0].max() < 1e-9


def test_regular_bead_has_no_horizon():
    bound = bound_sensitivity(build("bead", {"duration": 5.0}), ["theta0", "g"])
    assert bound.horizon is None and bound.error < 1e-9


def test_bad_parameters_are_refused_by_name():
    scene = build("chain", {"n": 3})
    with pytest.raises(UserError, match=r"--wrt: chain has no real parameter 'n'; choose from: length, mass"):
        reference_jacobian(scene, ["n"], 1.0)
    with pytest.raises(UserError, match="named twice"):
        reference_jacobian(scene, ["g", "g"], 1.0)
    with pytest.raises(Unsupported, match="planar chains"):
        reference_jacobian(build("spherical-pendulum", {}), ["g"], 1.0)


def _kuka():
    from engines.model.scene import model_scene

    return model_scene("kuka", "pybullet_data:kuka_iiwa/model.urdf", q0={"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45},
                       duration=1.0)


@pytest.mark.parametrize("which, step, tolerance", [("double_pendulum.urdf", 1e-3, 1e-8), ("kuka", 1e-4, 1e-6)])
def test_model_sensitivities_from_pinocchio_match_differences_of_whole_solves(which, step, tolerance):
    """Model files: Pinocchio's computeABADerivatives in the variational equations, against central differences
    of tight solves. The KUKA iiwa's light distal links move fast (|J| grows 3e3-fold in 1 s), so its differences
    need h = 1e-4 rad (measured: 5e-4 off at 1e-3, 4e-6 at 3e-4; O(h⁴))."""
    from engines.model.scene import model_scene
    from engines.scene.parameters import central_difference, perturbed
    from engines.reference.reference import solve

    if which == "kuka":
        scene, wrt = _kuka(), ["q0.lbr_iiwa_joint_2", "v0.lbr_iiwa_joint_4", "q0.lbr_iiwa_joint_6"]
    else:
        scene = model_scene("dp", "models/double_pendulum.urdf", q0={"shoulder": 30, "elbow": -20}, duration=1.0)
        wrt = ["q0.shoulder", "v0.elbow"]
    jacobian = reference_jacobian(scene, wrt, 1.0)
    assert output_columns(scene)[0] == f"q_{scene.joint_names[0]}" and jacobian.shape == (2 * len(scene.joint_names), len(wrt))

    def out(moved):
        return solve(moved, 2.3e-14, 1e-15).ode(np.array([1.0]))[:, 0]

    differences = np.array([central_difference(lambda d, name=name: out(perturbed(scene, name, d)), step)
                            for name in wrt]).T
    assert relative_error(jacobian, differences) <= tolerance
