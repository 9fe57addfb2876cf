"""Classic RK4 over a DART Skeleton's forward dynamics: the adapter's ``rk4`` integrator, for catalog and
model scenes alike (a floating base's model in xval's coordinates, where its quaternion has a rate)."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from engines.model.dynamics import configuration_rate


def rk4(rate: Callable[[np.ndarray], np.ndarray], y: np.ndarray, dt: float) -> np.ndarray:
    """y advanced one classic RK4 step of ``dt`` s along ẏ = rate(y) (4th order, not symplectic)."""
    k1 = rate(y)
    k2 = rate(y + 0.5 * dt * k1)
    k3 = rate(y + 0.5 * dt * k2)
    k4 = rate(y + dt * k3)
    return y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rk4_stepper(skeleton: Any, dt: float) -> Callable[[], None]:
    """A function that advances ``skeleton`` one RK4 step of ``dt`` s in its own coordinates.

    f(q, v) = (v, a(q, v)), a from DART's forward dynamics (its forces as set: none here); valid for
    joints whose position rate is their velocity (revolute, prismatic), which ``_check`` ensures.
    """
    n = skeleton.getNumDofs()
    set_q, set_v, forward, get_a = (skeleton.setPositions, skeleton.setVelocities,
                                    skeleton.computeForwardDynamics, skeleton.getAccelerations)

    def rate(y: np.ndarray) -> np.ndarray:
        set_q(y[:n])
        set_v(y[n:])
        forward()
        return np.concatenate([y[n:], get_a()])

    def step() -> None:
        y = rk4(rate, np.concatenate([skeleton.getPositions(), skeleton.getVelocities()]), dt)
        set_q(y[:n])
        set_v(y[n:])

    return step


def floating_rk4_stepper(loaded: Any, dt: float) -> Callable[[], None]:
    """A function that advances a floating-base model, or one with ball joints (engines.dart.model.DartModel), one
    RK4 step of ``dt`` s in xval's coordinates (docs/models.md, "Floating bases"), as the reference integrates it.

    DART's FreeJoint positions are a rotation vector, whose rate is not the angular velocity; xval's state
    (p, quaternion x y z w, joints; v, ω in the base frame, joint rates) has ṗ = R v and the quaternion's rate
    ½ q ⊗ ω (engines.model.dynamics.configuration_rate, the reference's), and v̇ is DART's forward dynamics
    mapped to xval's velocities (DartModel.forward); a BallJoint's rotation vector likewise, its quaternion's rate
    ½ q ⊗ ω. Each quaternion is normalised after each step (a projection that keeps the order)."""
    nconfig = loaded.description.nconfig
    zero = np.zeros(loaded.description.nv)

    def rate(y: np.ndarray) -> np.ndarray:
        q, v = y[:nconfig], y[nconfig:]
        return np.concatenate([configuration_rate(loaded.description, q, v), loaded.forward(q, v, zero)])

    description = loaded.description
    # Every quaternion of the configuration: the base's, each ball joint's.
    turns = ([slice(3, 7)] if description.floating is not None else []) + \
        [description.slots[joint.name][0] for joint in description.balls]

    def step() -> None:
        y = rk4(rate, np.concatenate(loaded.xval_state()), dt)
        for where in turns:
            y[where] /= np.linalg.norm(y[where])
        loaded._set(y[:nconfig], y[nconfig:])

    return step
