"""The one floating-base convention inside xval (Pinocchio's), and each engine's mapped to it (ball joints too).

xval's configuration is (p (3,) m, quaternion x y z w, joint q) with p and the
quaternion the base frame's pose in the world; its velocity is (v (3,) m/s,
ω (3,) rad/s, joint v), the base origin's linear velocity and the base's
angular velocity, both in the base frame. An engine whose velocity is
u = T(q) v (its own order and frames; T invertible, depending on the pose only)
has, with Ṫ v from Ṙ = R [ω]×:

    M = Tᵀ M_e T,   b = Tᵀ (b_e + M_e Ṫ v),   a = T⁻¹ (a_e − Ṫ v),   τ_e = T⁻ᵀ τ.

Each layout below is what tests/test_floating_base.py measured by
invariants (½ vᵀ M v against the links' kinetic energy, the base rows of M v
against the total momentum), not a reading of its documentation.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from engines.model.kinematics import quaternion_rotation

def linear_world_angular_body(r: np.ndarray) -> np.ndarray:
    """u = (R v, ω): the linear velocity in the world, the angular in the body (MuJoCo's free joint)."""
    return np.block([[r, np.zeros((3, 3))], [np.zeros((3, 3)), np.eye(3)]])


def angular_linear_world(r: np.ndarray) -> np.ndarray:
    """u = (R ω, R v): angular first, both in the world (Drake's floating body, DART's FreeJoint as measured,
    though DART's documentation says the body frame)."""
    return np.block([[np.zeros((3, 3)), r], [r, np.zeros((3, 3))]])


rotation = quaternion_rotation


def continuous(quaternion: np.ndarray, last: np.ndarray | None) -> np.ndarray:
    """``quaternion`` (x y z w) or its negative, whichever is nearer ``last`` (the one read before; None: as is):
    q and −q are one turn, so a quaternion read back from an engine's other coordinates is kept continuous."""
    return -quaternion if last is not None and quaternion @ last < 0 else quaternion


def skew(w) -> np.ndarray:
    """[w]×, so that skew(w) @ u = w × u."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


class Mapping:
    """An engine's velocity u = T v at one configuration q (xval's, (nconfig,)) and velocity v ((nv,) or None).

    block : the engine's base layout, R -> (6, 6), linear in R (one of the functions above).
    nv : the velocity's size (default nconfig − 1: one entry per joint coordinate; give it with ball joints).
    T : (nv, nv), the base block then the identity on the joints.
    """

    @classmethod
    def identity(cls, size: int) -> "Mapping":
        """T = I (a fixed base), for ball joints' blocks to be set in (:func:`with_balls`)."""
        mapping = cls.__new__(cls)
        mapping.T, mapping.Tdot_v = np.eye(size), np.zeros(size)
        return mapping

    def __init__(self, block: Callable[[np.ndarray], np.ndarray], q: np.ndarray, v: np.ndarray | None = None,
                 nv: int | None = None) -> None:
        r = rotation(q[3:7])
        size = len(q) - 1 if nv is None else nv  # nv: the velocity's size, when a ball joint's quaternion is in q
        self.T = np.eye(size)
        self.T[:6, :6] = block(r)
        self.Tdot_v = np.zeros(size)
        if v is not None:
            # Ṫ: R replaced by Ṙ = R [ω]×, the constant blocks (identities) dropped (block is affine in R).
            self.Tdot_v[:6] = (block(r @ skew(v[3:6])) - block(np.zeros((3, 3)))) @ v[:6]

    def velocity(self, v: np.ndarray) -> np.ndarray:
        return self.T @ v

    def mass_matrix(self, m_engine: np.ndarray) -> np.ndarray:
        return self.T.T @ m_engine @ self.T

    def bias(self, m_engine: np.ndarray, b_engine: np.ndarray) -> np.ndarray:
        return self.T.T @ (b_engine + m_engine @ self.Tdot_v)

    def force(self, tau: np.ndarray) -> np.ndarray:
        """The engine's generalised force for xval's τ."""
        return np.linalg.solve(self.T.T, tau)

    def acceleration(self, a_engine: np.ndarray) -> np.ndarray:
        return np.linalg.solve(self.T, a_engine - self.Tdot_v)


def with_balls(description, q: np.ndarray, mapping: Mapping | None) -> Mapping | None:
    """``mapping`` (None: a fixed base's identity) with each ball joint's block R(Q), for an engine whose ball
    velocity is the angular velocity in the joint's parent frame (u = R(Q) ω, R(Q) the child frame's rotation
    in the joint frame; Drake's BallRpyJoint as measured). Ṫ v adds nothing: Ṙ ω = R [ω]× ω = 0. None when the
    description has no ball joint and no base."""
    if not description.balls:
        return mapping
    out = Mapping.identity(description.nv) if mapping is None else mapping
    for joint in description.balls:
        where_q, where_v = description.slots[joint.name]
        out.T[where_v, where_v] = rotation(q[where_q])
    return out
