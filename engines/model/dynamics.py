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

from engines.model.scene import ModelScene


def base_rate(pose: np.ndarray, v: np.ndarray) -> np.ndarray:
    """d/dt of a floating base's pose (p (3,) m, quaternion x y z w) for its velocity v (linear m/s, angular
    rad/s, both in the base frame): ṗ = R v, q̇ = ½ q ⊗ (ω, 0) (the quaternion's norm is kept by the flow; R
    normalises it)."""
    from engines.model.floating import rotation

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

    def derivatives(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q̈ (nq,), ∂q̈/∂q (nq, nq), ∂q̈/∂v (nq, nq)) at y = (q, v): Pinocchio's computeABADerivatives (analytic),
        the file's joint damping τ = −d·v included when the scene keeps it; for the variational equations."""
        pin, loaded, damping = self._model
        if loaded.description.floating is not None or loaded.description.balls:  # a quaternion in q: its
            from engines.errors import Unsupported  # derivatives live in the tangent space

            what = "a floating-base model" if loaded.description.floating is not None else "a model with ball joints"
            raise Unsupported(f"reference: derivatives of {what} are not computed yet")
        n = len(y) // 2
        rates = loaded._vector(y[n:])
        by_q, by_v, minv = pin.computeABADerivatives(loaded.model, loaded.data, loaded.configuration(y[:n]), rates,
                                                     -damping * rates)
        minv = np.triu(minv) + np.triu(minv, 1).T  # Pinocchio fills the upper triangle
        dof = np.ix_(loaded.dof, loaded.dof)
        return loaded.data.ddq[loaded.dof].copy(), by_q[dof], (by_v - minv * damping)[dof]

    def evaluate(self, scene: ModelScene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Link frame positions (n, L, 3) m and velocities (n, L, 3) m/s at states (n, nconfig + nv); no
        constraint forces."""
        positions, velocities = scene.frame_states(*scene.split(states))
        return positions, velocities, np.zeros((len(states), 0, 3))

    def __getstate__(self) -> dict:
        return {"scene": self.scene}

    def __setstate__(self, state: dict) -> None:
        self.scene = state["scene"]
