"""ours' own derivatives on a model file (its rigid bodies): forward sensitivities by the tangent-linear rigid step
(ours.rigid.tangent through ours.rigid.sensitivity; method "analytic"), every method and integrator.

A model's parameters, q0.JOINT and v0.JOINT, move ours' initial state y0 (13 per body, maximal coordinates,
engines.ours.model.start_state) along dy0/dp, a kinematic map differentiated by central differences with one
Richardson step (within about 1e-11: INITIAL_STEP). The tangent-linear step carries every dy0/dp beside one
real run through ours' own step to every sample, exact to round-off; the outputs' derivatives are those of ours' readout
of the joints' q and v from its state (engines.ours.model's joint_coordinates), taken along each carried
direction by the same differences. A floating base is left to differences of rollouts (None).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from engines.adapter import Schedule
from engines.gradients import SAMPLE_INTERVAL
from engines.scene.parameters import central_difference, perturbed

#: Steps of the kinematic maps' differences, where their truncation O(h⁴) and round-off meet (on the KUKA iiwa
#: each is then within about 1e-11 of the derivative): dy0/dp, in the parameter's SI unit; the readout, along a
#: unit direction of the state (its joint rates cancel the bodies' large angular velocities: smaller steps lose
#: more to round-off than they gain, 2e-9 at h = 1e-5).
INITIAL_STEP = 1e-3
READOUT_STEP = 1e-2


def jacobian(engine: Any, scene: Any, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str]) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """(J (2 nq, k), "analytic", times (n,) s, J at each (n, 2 nq, k)) for a
    fixed-base model scene, sampled as differences of rollouts are (every SAMPLE_INTERVAL); None for a floating base or ball joints, a model or a method and
    integrator ours' rigid bodies refuse, or a run that stops early. ``engine`` : ours' adapter; ``wrt`` : the
    model's q0.JOINT, v0.JOINT."""
    from engines.errors import Unsupported
    from engines.ours.model import of_scene, start_state
    from ours import OursError
    from ours.rigid.method import resolve
    from ours.rigid.sensitivity import forward_sensitivities

    settings = engine.resolve(variant, options)
    try:
        resolve(settings["method"], settings["integrator"])
    except OursError:
        return None  # refused for rigid bodies: the run's own check says why
    try:
        model = of_scene(scene)
    except Unsupported:
        return None  # a model ours cannot express: its runs are skipped, with the reason
    if model.base >= 0 or scene.description.balls:  # a quaternion in q: left to differences of rollouts
        return None
    schedule = Schedule.make(scene.duration, dt, SAMPLE_INTERVAL)

    def start(name: str, delta: float) -> np.ndarray:
        return start_state(model, perturbed(scene, name, delta))

    directions = np.array([central_difference(lambda delta, name=name: start(name, delta), INITIAL_STEP)
                           for name in wrt])
    result = forward_sensitivities(
        model.mechanism, start_state(model, scene), directions, dt, schedule.n_steps, schedule.stride,
        method=settings["method"], integrator=settings["integrator"], k_s=settings["k_s"], k_d=settings["k_d"],
        tolerance=settings["tolerance"], max_iterations=settings["max_iterations"])
    if result.status != "ok":
        return None  # a run that stopped early has no derivative at T: differences of rollouts say what it does
    over_time = readout_tangent(model.mechanism, result.y, result.dy)
    return over_time[-1], "analytic", result.t, over_time


def readout_tangent(mech: Any, y: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """(S, 2 nq, k) d (q, v) along each direction: y (S, 13 nb) states, dy (S, k, 13 nb) their derivatives.

    Central differences with one Richardson step of joint_coordinates along each unit direction, scaled back;
    an angle's difference is taken modulo 2π (the readout gives angles in (−π, π])."""
    from ours.rigid import joint_coordinates

    norms = np.linalg.norm(dy, axis=-1, keepdims=True)
    norms[norms == 0] = 1.0
    unit, at = dy / norms, np.broadcast_to(y[:, None, :], dy.shape)
    centre = joint_coordinates(mech, at)[0]  # (S, k, nq): three axes, so no unwrapping along a series

    def outputs(delta: float) -> np.ndarray:
        q, v = joint_coordinates(mech, at + delta * unit)
        return np.concatenate([centre + np.remainder(q - centre + np.pi, 2 * np.pi) - np.pi, v], axis=-1)

    return np.swapaxes(central_difference(outputs, READOUT_STEP) * norms, 1, 2)
