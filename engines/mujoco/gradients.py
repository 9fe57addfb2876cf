"""MuJoCo's own derivatives: ``mjd_transitionFD``'s one-step Jacobians, chained over a run.

``mjd_transitionFD(m, d, eps, centered, A, ...)`` gives A = d x(t + dt) / d x(t) for MuJoCo's state x =
(qpos in the tangent space, qvel) by central differences in C. Their product over the run is d x(T) / d x(0);
the chain rule (engines.gradients.chained_jacobian) turns it into d outputs(T) / d p for the initial-condition
parameters (angles, rates). MuJoCo refuses RK4 there ("RK4 integrator is not supported"), and a physical
parameter (g, a mass, a length) changes the model rather than the state: those get central differences of
whole rollouts (engines.gradients.finite_difference_jacobian), as every engine does.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from engines.gradients import chained_jacobian, finite_difference_jacobian, is_initial_condition
from engines.mujoco.library import mujoco
from engines.scene.scene import Scene

#: The integrators mjd_transitionFD differentiates.
DIFFERENTIATED = ("Euler", "implicit", "implicitfast")
#: mjd_transitionFD's step (central differences of one step: error O(eps²) ≈ 1e-12 relative).
EPS = 1e-6


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str], initial_velocities: Callable[[Scene, Any], np.ndarray]) -> tuple[np.ndarray, str] | None:
    """(J (6P, k), "finite-difference") from chained mjd_transitionFD, or None where it does not apply (RK4,
    the connect formulation, or no initial-condition parameter among ``wrt``). ``engine`` : MuJoCo's adapter;
    initial_velocities : its map from a scene and its hinge model to the joint velocities qvel (nv,)."""
    if scene.is_model:  # a model's own derivatives are not chained here yet: differences of rollouts
        return None
    settings = engine.resolve(variant, options)
    if settings["formulation"] != "hinge" or settings["integrator"] not in DIFFERENTIATED:
        return None
    initial = [name for name in wrt if is_initial_condition(scene, name)]
    if not initial:
        return None
    model, _, _ = engine.build(scene, dt, settings)
    data = mujoco.MjData(model)
    data.qvel[:] = initial_velocities(scene, model)
    mujoco.mj_forward(model, data)
    x0 = _state(model, data)
    transition = transition_product(model, data, max(1, round(scene.duration / dt)))
    columns = dict(zip(initial, chained_jacobian(scene, initial, transition, hinge_readout(scene, model), x0,
                                                 _state(model, data)).T))
    physical = [name for name in wrt if name not in columns]
    if physical:
        differences = finite_difference_jacobian(engine, scene, variant, options, dt, physical).jacobian
        columns.update(zip(physical, differences.T))
    return np.array([columns[name] for name in wrt]).T, "finite-difference"


def transition_product(model: Any, data: Any, n_steps: int) -> np.ndarray:
    """(2nv, 2nv) d x(n_steps·dt) / d x(0): each step's mjd_transitionFD, multiplied in order; ``data`` is
    stepped to the end."""
    n = 2 * model.nv + model.na
    product, step = np.eye(n), np.empty((n, n))
    for _ in range(n_steps):
        mujoco.mjd_transitionFD(model, data, EPS, True, step, None, None, None)
        product = step @ product
        mujoco.mj_step(model, data)
    return product


def _state(model: Any, data: Any) -> np.ndarray:
    """(2nv,) the hinge model's state (qpos, qvel): planar hinges, so qpos is its own tangent space."""
    return np.concatenate([data.qpos, data.qvel])


def hinge_readout(scene: Scene, model: Any) -> Callable[[np.ndarray], np.ndarray]:
    """The outputs of a hinge model's state: a function of x = (qpos, qvel) (2nv,) giving (6P,) each particle's
    site position (m) and world velocity (m/s), in the CSV's order (p{i}_x..z v{i}_x..z), after mj_forward.
    Planar hinges only (qpos is then its own tangent space)."""
    data = mujoco.MjData(model)
    sites = [model.site(f"s{i}").id for i in range(len(scene.particles))]
    velocity = np.empty(6)

    def readout(x: np.ndarray) -> np.ndarray:
        data.qpos[:], data.qvel[:] = x[:model.nq], x[model.nq:]
        mujoco.mj_forward(model, data)
        out = []
        for site in sites:
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, site, velocity, 0)
            out.extend([*data.site_xpos[site], *velocity[3:]])
        return np.array(out)

    return readout
