"""MJX's own derivatives: forward mode (``jax.jvp``) through its stepping loop, in float64 or float32.

Forward mode through ``fori_loop(mjx.step)`` (a ``while_loop`` for a traced step count, which forward mode
differentiates and reverse mode would not) gives d x(t + n·dt) / d x(t) · e for MJX's state x = (qpos, qvel),
one direction e at a time: the loop body (one step and its tangent) compiles once, for any n and any direction.
A single direction compiles in less time than ``jax.jacfwd`` (the same tangents, vmapped over all directions)
and runs slower: the compile is most of the cost of a Jacobian over a few seconds (scripts/mjx_chain_gradients.py
prints both on the chain of 8). The run is differentiated one sample interval at a time and the interval
Jacobians multiplied, so the Jacobian is known at every sample and the first one holding a NaN or an infinity
is named (:func:`transition_over_time`). The chain rule (engines.gradients.chained_jacobian, with MuJoCo's
readout of the same model) turns it into d outputs(T) / d p for initial-condition parameters; g, masses and
lengths change the model, and get central differences of MJX's rollouts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from engines.gradients import chained_jacobian, finite_difference_jacobian, is_initial_condition
from engines.mjx import library
from engines.mujoco.builder import hinge_readout
from engines.mujoco.library import mujoco
from engines.scene.scene import Scene

#: Compiled jit(jvp(advance)) by (model structure, x64): one compile serves every dt, length and direction.
_compiled: dict[tuple[str, bool], Any] = {}


@dataclass(frozen=True)
class Transition:
    """d x(t) / d x(0) at each sample: times (n,) s, product (n, 2nv, 2nv) (float64 copies of MJX's numbers);
    states (n, 2nv); first_nonfinite : s, the first sample whose Jacobian holds a NaN or an infinity, or None."""

    times: np.ndarray
    product: np.ndarray
    states: np.ndarray
    first_nonfinite: float | None


def transition_over_time(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                         interval: float = 0.01) -> tuple[Any, Transition]:
    """(the MuJoCo model, the Transition) of ``scene`` run for its duration at ``dt``, sampled every ``interval`` s."""
    jax, mjx = library.jax_mjx()
    settings = engine.resolve(variant, options)
    hinge = engine.build(scene, dt, settings)
    model, xml = hinge.model, hinge.structure
    data = mujoco.MjData(model)
    data.qvel[:] = hinge.qvel
    mujoco.mj_forward(model, data)
    x64 = settings["precision"] == "float64"
    n_steps = max(1, round(scene.duration / dt))
    stride = max(1, round(interval / dt))
    counts = np.diff(np.unique(np.append(np.arange(0, n_steps, stride), n_steps)))
    with jax.enable_x64(x64):
        mx = mjx.put_model(model, impl="jax")
        dx = mjx.put_data(model, data, impl="jax")
        step = _compiled.get((xml, x64))
        x = np.concatenate([dx.qpos, dx.qvel])
        directions = np.eye(len(x), dtype=x.dtype)
        if step is None:
            library.trace_in(jax, x64)
            step = _compiled[(xml, x64)] = library.compiled(jax, _tangent_of_steps(jax, mjx, model.nq), mx, dx, x,
                                                            directions[0], np.int32(1))
        product = np.eye(len(x))
        times, products, states = [0.0], [product], [np.asarray(x, dtype=float)]
        done = 0
        for count in counts:
            columns = [step(mx, dx, x, e, np.int32(count)) for e in directions]
            jacobian = np.stack([np.asarray(tangent, dtype=float) for _, tangent in columns], axis=1)
            x = columns[0][0]
            product = jacobian @ product
            done += int(count)
            times.append(done * dt)
            products.append(product)
            states.append(np.asarray(x, dtype=float))
    finite = [bool(np.isfinite(p).all() and np.isfinite(s).all()) for p, s in zip(products, states)]
    first = None if all(finite) else times[finite.index(False)]
    return model, Transition(np.array(times), np.array(products), np.array(states), first)


def _tangent_of_steps(jax, mjx, nq: int):
    """(mx, dx, x, e, n -> (x_n, d x_n / d x · e)) for MJX's state x = (qpos, qvel) after n steps."""
    jnp = jax.numpy

    def advance(x, mx, dx, n):
        d = dx.replace(qpos=x[:nq], qvel=x[nq:])
        d = jax.lax.fori_loop(0, n, lambda _, s: mjx.step(mx, s), d)
        return jnp.concatenate([d.qpos, d.qvel])

    return lambda mx, dx, x, e, n: jax.jvp(lambda y: advance(y, mx, dx, n), (x,), (e,))


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str]) -> tuple[np.ndarray, str] | None:
    """(J (6P, k), "autodiff"): forward mode for initial-condition parameters, differences of rollouts for the rest;
    None when no parameter of ``wrt`` is an initial condition."""
    if scene.is_model:  # a model's own derivatives are not chained here yet: differences of rollouts
        return None
    initial = [name for name in wrt if is_initial_condition(scene, name)]
    if not initial:
        return None
    model, transition = transition_over_time(engine, scene, variant, options, dt)
    readout = hinge_readout(scene, model)
    columns = dict(zip(initial, chained_jacobian(scene, initial, transition.product[-1], readout,
                                                 transition.states[0], transition.states[-1]).T))
    physical = [name for name in wrt if name not in columns]
    if physical:
        differences = finite_difference_jacobian(engine, scene, variant, options, dt, physical).jacobian
        columns.update(zip(physical, differences.T))
    return np.array([columns[name] for name in wrt]).T, "autodiff"
