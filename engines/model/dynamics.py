"""The reference's equations of motion for a model scene: Pinocchio's articulated-body algorithm.

:class:`ModelDynamics` has the shape of the catalog's reduced-coordinate
models (engines/reference/reference.py integrates it with DOP853): the state is
y = (q, v) in the model's joint order, ``rhs`` is (v, aba(q, v, τ)) with τ
the file's joint damping (−d·v) when the scene keeps it (friction, being
non-smooth, is left out of the reference and said so), and ``evaluate``
turns states into the link frames' positions and velocities. It holds only
the scene, so it pickles small (Pinocchio's model is rebuilt where needed).
"""

from __future__ import annotations

import functools

import numpy as np

from engines.model.scene import ModelScene


class ModelDynamics:
    """ẏ = f(y) for y = (q, v) (2·nq,) of ``scene``: v and Pinocchio's ABA acceleration."""

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
            for joint, dof in zip(scene.description.moving_joints, loaded.dof):
                damping[dof] = joint.damping
        return pin, loaded, damping

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        pin, loaded, damping = self._model
        n = len(y) // 2
        q, v = y[:n], y[n:]
        rates = loaded._vector(v)
        a = pin.aba(loaded.model, loaded.data, loaded.configuration(q), rates, -damping * rates)[loaded.dof]
        return np.concatenate([v, a])

    def derivatives(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q̈ (nq,), ∂q̈/∂q (nq, nq), ∂q̈/∂v (nq, nq)) at y = (q, v): Pinocchio's computeABADerivatives (analytic),
        the file's joint damping τ = −d·v included when the scene keeps it; for the variational equations."""
        pin, loaded, damping = self._model
        n = len(y) // 2
        rates = loaded._vector(y[n:])
        by_q, by_v, minv = pin.computeABADerivatives(loaded.model, loaded.data, loaded.configuration(y[:n]), rates,
                                                     -damping * rates)
        minv = np.triu(minv) + np.triu(minv, 1).T  # Pinocchio fills the upper triangle
        dof = np.ix_(loaded.dof, loaded.dof)
        return loaded.data.ddq[loaded.dof].copy(), by_q[dof], (by_v - minv * damping)[dof]

    def evaluate(self, scene: ModelScene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Link frame positions (n, L, 3) m and velocities (n, L, 3) m/s at states (n, 2·nq); no constraint forces."""
        n = states.shape[1] // 2
        positions, velocities = scene.frame_states(states[:, :n], states[:, n:])
        return positions, velocities, np.zeros((len(states), 0, 3))

    def __getstate__(self) -> dict:
        return {"scene": self.scene}

    def __setstate__(self, state: dict) -> None:
        self.scene = state["scene"]
