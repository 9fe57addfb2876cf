"""ours' own derivatives on a model file (its rigid bodies): forward sensitivities by complex step through the
compiled rigid step (ours.rigid.sensitivity).

A model's parameters, q0.JOINT and v0.JOINT, move ours' initial state y0 (13 per body, maximal coordinates,
engines.ours.model.start_state) along dy0/dp, a kinematic map differentiated by central differences with one
Richardson step (O(h⁴) ≈ 1e-20 at h = 1e-5, round-off ≈ 1e-11). One complex run per parameter carries dy0/dp
through ours' own step to every sample, exact to round-off; the outputs' derivatives are those of ours' readout
of the joints' q and v from its state (engines.ours.model's joint_coordinates), taken along each carried
direction by the same differences. A floating base is left to differences of rollouts (None).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from engines.adapter import Schedule
from engines.gradients import SAMPLE_INTERVAL, parameter_step
from engines.scene.parameters import central_difference, perturbed

#: Relative step of the kinematic maps' differences (dy0/dp and the readout along a direction), of a unit scale.
KINEMATIC_STEP = 1e-4


def jacobian(engine: Any, scene: Any, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str]) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """(J (2 nq, k), "autodiff", times (n,) s, J at each (n, 2 nq, k)) for a fixed-base model scene, sampled as
    differences of rollouts are (every SAMPLE_INTERVAL); None for a floating base, a model or a method and
    integrator ours' rigid bodies refuse, or a run that stops early. ``engine`` : ours' adapter; ``wrt`` : q0.JOINT, v0.JOINT."""
    from engines.errors import Unsupported
    from engines.ours.model import GRAVITY, start_state, translate
    from ours import OursError
    from ours.rigid.method import resolve
    from ours.rigid.sensitivity import forward_sensitivities

    settings = engine.resolve(variant, options)
    try:
        resolve(settings["method"], settings["integrator"])
    except OursError:
        return None  # refused for rigid bodies: the run's own check says why
    try:
        model = translate(scene.description, gravity=tuple(getattr(scene, "gravity", GRAVITY)))
    except Unsupported:
        return None  # a model ours cannot express: its runs are skipped, with the reason
    if model.base >= 0:
        return None
    schedule = Schedule.make(scene.duration, dt, SAMPLE_INTERVAL)
    directions = np.array([central_difference(lambda delta, name=name: start_state(model, perturbed(scene, name, delta)),
                                              parameter_step(scene, name, KINEMATIC_STEP)) for name in wrt])
    result = forward_sensitivities(
        model.mechanism, start_state(model, scene), directions, dt, schedule.n_steps, schedule.stride,
        method=settings["method"], integrator=settings["integrator"], k_s=settings["k_s"], k_d=settings["k_d"],
        tolerance=settings["tolerance"], max_iterations=settings["max_iterations"])
    if result.status != "ok":
        return None  # a run that stopped early has no derivative at T: differences of rollouts say what it does
    over_time = readout_tangent(model.mechanism, result.y, result.dy)
    return over_time[-1], "autodiff", result.t, over_time


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

    return np.swapaxes(central_difference(outputs, KINEMATIC_STEP) * norms, 1, 2)
