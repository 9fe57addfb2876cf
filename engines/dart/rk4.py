"""Classic RK4 over a DART Skeleton's forward dynamics: the adapter's ``rk4`` integrator, for catalog and
model scenes alike."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np


def rk4_stepper(skeleton: Any, dt: float) -> Callable[[], None]:
    """A function that advances ``skeleton`` one classic RK4 step of ``dt`` s (4th order, not symplectic).

    f(q, v) = (v, a(q, v)), a from DART's forward dynamics (its forces as set: none here); valid for
    joints whose position rate is their velocity (revolute, prismatic), which ``_check`` ensures.
    """
    set_q, set_v, forward, get_a = (skeleton.setPositions, skeleton.setVelocities,
                                    skeleton.computeForwardDynamics, skeleton.getAccelerations)
    get_q, get_v = skeleton.getPositions, skeleton.getVelocities
    half, sixth = 0.5 * dt, dt / 6.0

    def acceleration(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        set_q(q)
        set_v(v)
        forward()
        return get_a()

    def step() -> None:
        q, v = get_q(), get_v()
        a1 = acceleration(q, v)
        v2 = v + half * a1
        a2 = acceleration(q + half * v, v2)
        v3 = v + half * a2
        a3 = acceleration(q + half * v2, v3)
        v4 = v + dt * a3
        a4 = acceleration(q + dt * v3, v4)
        set_q(q + sixth * (v + 2.0 * v2 + 2.0 * v3 + v4))
        set_v(v + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4))

    return step
