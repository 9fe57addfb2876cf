"""The reference's equations of motion for a model scene: Pinocchio's articulated-body algorithm.

:class:`ModelDynamics` has the shape of the catalog's reduced-coordinate
models (engines/reference/reference.py integrates it with DOP853): the state is
y = (q, v) in xval's order (a floating base's pose and velocity first, its
quaternion's rate ½ q ⊗ ω: :func:`base_rate`; a ball joint's the same), ``rhs`` is (q̇, aba(q, v, τ)) with τ
the file's joint damping (−d·v) when the scene keeps it (friction, being
non-smooth, is left out of the reference and said so), and ``evaluate``
turns states into the link frames' positions and velocities. It holds only
the scene, so it pickles small (Pinocchio's model is rebuilt where needed).
"""

from __future__ import annotations

import functools

import numpy as np

from engines.model.floating import rotation, skew
from engines.model.scene import ModelScene


def base_rate(pose: np.ndarray, v: np.ndarray) -> np.ndarray:
    """d/dt of a floating base's pose (p (3,) m, quaternion x y z w) for its velocity v (linear m/s, angular
    rad/s, both in the base frame): ṗ = R v, q̇ = ½ q ⊗ (ω, 0) (the quaternion's norm is kept by the flow; R
    normalises it)."""
    return np.concatenate([rotation(pose[3:7]) @ v[:3], quaternion_rate(pose[3:7], v[3:6])])


def quaternion_rate(quaternion: np.ndarray, angular: np.ndarray) -> np.ndarray:
    """d/dt of a quaternion (x y z w) turning at ``angular`` rad/s in its own (body) frame: ½ q ⊗ (ω, 0)."""
    vector, scalar = quaternion[:3], quaternion[3]
    return np.concatenate([0.5 * (scalar * angular + np.cross(vector, angular)), [-0.5 * vector @ angular]])


def configuration_rate(description, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q̇ (nconfig,) of a model (engines.model.description.ModelDescription) at xval's q (nconfig,), v (nv,): a
    floating base's pose moving by :func:`base_rate`, each ball joint's quaternion by :func:`quaternion_rate` (its
    v is the child's angular velocity in the child frame), the other joints' v itself. The reference's and any
    engine's integrator in xval's coordinates (engines/dart/rk4.py) share it."""
    if description.floating is None and not description.balls:
        return v
    parts = [base_rate(q[:7], v[:6])] if description.floating is not None else []
    for joint in description.moving_joints:
        where_q, where_v = description.slots[joint.name]
        parts.append(quaternion_rate(q[where_q], v[where_v]) if joint.type == "ball" else v[where_v])
    return np.concatenate(parts)


def rotation_increment(quaternion: np.ndarray) -> np.ndarray:
    """(3, 4) dθ/dQ: the body-frame rotation (rad) that a change dQ of a quaternion (x y z w, any norm) makes once
    normalised, n ⊕ dθ = n ⊗ exp(dθ/2) (Pinocchio's SO(3) tangent): dθ = 2 vec(n* ⊗ dn), dn = (I − n nᵀ) dQ / |Q|
    (the radial part of dQ turns nothing: vec(n* ⊗ n) = 0, so the projection drops out)."""
    norm = np.linalg.norm(quaternion)
    vector, scalar = quaternion[:3] / norm, quaternion[3] / norm
    return (2.0 / norm) * np.hstack([scalar * np.eye(3) - skew(vector), -vector[:, None]])


def quaternion_rate_jacobian(quaternion: np.ndarray, angular: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(∂q̇/∂Q (4, 4), ∂q̇/∂ω (4, 3)) of :func:`quaternion_rate` (bilinear, so exact): q̇ = ½ Q ⊗ (ω, 0)."""
    vector, scalar = quaternion[:3], quaternion[3]
    by_q = 0.5 * np.block([[-skew(angular), angular[:, None]], [-angular[None, :], np.zeros((1, 1))]])
    by_w = 0.5 * np.vstack([scalar * np.eye(3) + skew(vector), -vector[None, :]])
    return by_q, by_w


def configuration_rate_jacobian(description, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(∂q̇/∂q (nconfig, nconfig), ∂q̇/∂v (nconfig, nv)) of :func:`configuration_rate`, exact: a base's ṗ = R(Q) v
    moves with Q by −R [v]× dθ (dθ from :func:`rotation_increment`), each quaternion's rate by
    :func:`quaternion_rate_jacobian`, the other joints' q̇ = v by the identity."""
    by_q, by_v = np.zeros((description.nconfig, description.nconfig)), np.zeros((description.nconfig, description.nv))
    if description.floating is not None:
        r = rotation(q[3:7])
        by_v[:3, :3] = r
        by_q[:3, 3:7] = -r @ skew(v[:3]) @ rotation_increment(q[3:7])
        by_q[3:7, 3:7], by_v[3:7, 3:6] = quaternion_rate_jacobian(q[3:7], v[3:6])
    for joint in description.moving_joints:
        where_q, where_v = description.slots[joint.name]
        if joint.type == "ball":
            by_q[where_q, where_q], by_v[where_q, where_v] = quaternion_rate_jacobian(q[where_q], v[where_v])
        else:
            by_v[where_q, where_v] = np.eye(where_q.stop - where_q.start)
    return by_q, by_v


def tangent_map(description, q: np.ndarray) -> np.ndarray:
    """(nv, nconfig) ∂δ/∂q: the tangent step δ of Pinocchio's q ⊕ δ that a change of xval's q makes. A free-flyer's
    δ is its SE(3) twist in the base frame (to first order p ⊕ δ = p + R δ_linear, R ⊕ δ = R exp([δ_angular]×)),
    so δ_linear = Rᵀ dp and δ_angular = dθ of :func:`rotation_increment`; a ball's δ is its quaternion's dθ; a
    1-degree-of-freedom joint's is dq itself (a continuous joint's (cos, sin) included)."""
    out = np.zeros((description.nv, description.nconfig))
    if description.floating is not None:
        out[:3, :3] = rotation(q[3:7]).T
        out[3:6, 3:7] = rotation_increment(q[3:7])
    for joint in description.moving_joints:
        where_q, where_v = description.slots[joint.name]
        out[where_v, where_q] = rotation_increment(q[where_q]) if joint.type == "ball" else \
            np.eye(where_q.stop - where_q.start)
    return out


class ModelDynamics:
    """ẏ = f(y) for y = (q, v) (nconfig + nv,) of ``scene``: q̇ from v and Pinocchio's ABA acceleration."""

    def __init__(self, scene: ModelScene) -> None:
        self.scene = scene

    def initial_state(self, scene: ModelScene) -> np.ndarray:
        return np.concatenate([scene.initial_q, scene.initial_v])

    @functools.cached_property
    def _model(self):
        import pinocchio as pin

        from engines.model import pinocchio as reference_import

        scene = self.scene
        loaded = reference_import.load(scene.source, scene.description)
        loaded.model.gravity.linear = np.asarray(scene.gravity, dtype=float)
        damping = np.zeros(loaded.model.nv)
        if scene.file_dynamics == "keep":
            for joint in scene.description.moving_joints:
                damping[loaded.dof[scene.description.slots[joint.name][1]]] = joint.damping
        return pin, loaded, damping

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        pin, loaded, damping = self._model
        n = loaded.description.nconfig
        q, v = y[:n], y[n:]
        rates = loaded._vector(v)
        a = pin.aba(loaded.model, loaded.data, loaded.configuration(q), rates, -damping * rates)[loaded.dof]
        return np.concatenate([configuration_rate(loaded.description, q, v), a])

    def derivatives(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ẏ (nconfig + nv,), ∂ẏ/∂y (nconfig + nv, nconfig + nv)) at y = (q, v) in xval's coordinates, for the
        variational equations: q̇'s rows from :func:`configuration_rate_jacobian` (exact), q̈'s from Pinocchio's
        computeABADerivatives (analytic, the file's joint damping τ = −d·v included when the scene keeps it).
        Pinocchio differentiates along its tangent space (q ⊕ δ, δ (nv,)); :func:`tangent_map` turns xval's
        coordinates into δ: ∂q̈/∂q = ∂q̈/∂δ · ∂δ/∂q."""
        pin, loaded, damping = self._model
        description = loaded.description
        n = description.nconfig
        q, v = y[:n], y[n:]
        rates = loaded._vector(v)
        by_q, by_v, minv = pin.computeABADerivatives(loaded.model, loaded.data, loaded.configuration(q), rates,
                                                     -damping * rates)
        minv = np.triu(minv) + np.triu(minv, 1).T  # Pinocchio fills the upper triangle
        dof = np.ix_(loaded.dof, loaded.dof)
        rate_by_q, rate_by_v = configuration_rate_jacobian(description, q, v)
        jacobian = np.block([[rate_by_q, rate_by_v],
                             [by_q[dof] @ tangent_map(description, q), (by_v - minv * damping)[dof]]])
        return np.concatenate([configuration_rate(description, q, v), loaded.data.ddq[loaded.dof]]), jacobian

    def evaluate(self, scene: ModelScene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Link frame positions (n, L, 3) m and velocities (n, L, 3) m/s at states (n, nconfig + nv); no
        constraint forces."""
        positions, velocities = scene.frame_states(*scene.split(states))
        return positions, velocities, np.zeros((len(states), 0, 3))

    def __getstate__(self) -> dict:
        return {"scene": self.scene}

    def __setstate__(self, state: dict) -> None:
        self.scene = state["scene"]
