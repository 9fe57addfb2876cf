"""Derivatives of a run's outputs at T with respect to scene parameters, from any engine.

The quantity is engine-neutral: J = d outputs(T) / d p, outputs the CSV's state columns
(``p{i}_x..z v{i}_x..z``, or a model's ``q_<joint> v_<joint>``; engines.scene.parameters.output_columns) at the run's last sample,
p the catalog parameters of ``wrt`` per SI unit (per radian for angles). An engine that computes
derivatives of its own (analytic, autodiff) answers through ``Engine.jacobian``; every engine,
outside programs included, can be differentiated by :func:`finite_difference_jacobian`: central
differences of whole rollouts, each parameter with a step proportional to its scale, refined by one
Richardson extrapolation (error O(h⁴)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from engines.scene.parameters import central_difference, check_wrt, output_columns, outputs_of, perturbed, si_scale
from engines.scene.scene import Scene

if TYPE_CHECKING:
    from engines.adapter import Engine

#: The methods an answer may name (the JSON's ``method``).
METHODS = ("reference", "analytic", "autodiff", "finite-difference")
#: Relative step of the differences of rollouts: h = STEP · scale, scale = |p| (1 rad for an angle,
#: 1 SI unit for a parameter at 0). With one Richardson step the truncation is O(h⁴) ≈ 1e-12 and the
#: round-off of a float64 rollout about ε·|out|/h ≈ 1e-13 ...
STEP = 1e-3
#: ... and of a float32 rollout: round-off ε/h and truncation h⁴ balance near h = ε^(1/5) ≈ 0.04.
STEP_FLOAT32 = 3e-2
#: A model scene's steps are this fraction of a catalog scene's (parameter_step).
MODEL_STEP_FACTOR = 0.1


def single_precision(engine: "Engine", variant: str | None, options: Mapping[str, Any] | None) -> bool:
    """Whether this variant computes in float32 (its ``precision`` or ``dtype`` setting says so)."""
    settings = engine.resolve(variant, options)
    return "float32" in (str(settings.get("precision")), str(settings.get("dtype")))


@dataclass(frozen=True)
class EngineJacobian:
    """An engine's answer: jacobian (m, k) per SI unit; method, one of METHODS; time : s, the outputs' time;
    own : whether the engine computed it itself (Engine.jacobian), not the harness by differences of rollouts;
    times (n,) s and over_time (n, m, k): the Jacobian at every sample, when known (differences of rollouts)."""

    jacobian: np.ndarray
    method: str
    time: float
    own: bool = False
    times: np.ndarray | None = None
    over_time: np.ndarray | None = None


def parameter_step(scene: Scene, name: str, relative: float = STEP) -> float:
    """SI units: the difference step of parameter ``name`` (``relative`` of its scale)."""
    if scene.is_model:
        # q0 in rad (or m), v0 in rad/s (or m/s): 1 SI unit is a joint's scale, but a robot's light distal links
        # move fast: on the KUKA iiwa, differences of the reference at h = 1e-3 rad are 5e-4 off, at 1e-4 about 5e-8.
        return relative * MODEL_STEP_FACTOR
    if si_scale(scene.name, name) != 1.0:
        return relative  # an angle: 1 rad is its scale wherever it points
    value = abs(float(scene.parameters[name]))
    return relative * (value if value > 0 else 1.0)


#: s between the samples at which differences of rollouts give the Jacobian (its error over time, the first NaN).
SAMPLE_INTERVAL = 0.01


def rollout_outputs(engine: "Engine", scene: Scene, variant: str | None, options: Mapping[str, Any] | None,
                    dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(outputs (n, m) at every sample, the sample times (n,) s), sampled every SAMPLE_INTERVAL (or every step,
    for a longer step); the samples a run did not reach (it blew up or failed) are NaN."""
    from engines.adapter import Schedule

    times = Schedule.make(scene.duration, dt, SAMPLE_INTERVAL).times
    out = np.full((len(times), len(output_columns(scene))), np.nan)
    trajectory = engine.simulate(scene, dt, variant=variant, options=options, sample_interval=SAMPLE_INTERVAL)
    # An unstable run's samples stop before its first non-finite state; a failed run has none to trust.
    n = trajectory.n_samples if trajectory.info.status in ("ok", "unstable") else 0
    if n == 0:
        return out, times
    if scene.is_model:  # a model's outputs are its joints' q and v
        if trajectory.joint_states is not None:
            out[:n] = np.asarray(trajectory.joint_states[:n], dtype=float)
    else:
        out[:n] = outputs_of(trajectory.positions[:n], trajectory.velocities[:n])
    return out, times


def finite_difference_jacobian(engine: "Engine", scene: Scene, variant: str | None, options: Mapping[str, Any] | None,
                               dt: float, wrt: Sequence[str], relative: float | None = None) -> EngineJacobian:
    """Central differences of whole rollouts at p ± h and p ± h/2, one Richardson step: (4 D(h/2) − D(h)) / 3.

    Four rollouts per parameter; a fixed-step rollout is a smooth function of the parameters (same steps,
    same dt), so the differences converge as for any smooth function. ``relative`` : the step's fraction of
    each parameter's scale, default STEP (STEP_FLOAT32 for a float32 variant). The Jacobian comes at every
    sample (``over_time``) as well as at T.
    """
    check_wrt(scene, wrt)
    if relative is None:
        relative = STEP_FLOAT32 if single_precision(engine, variant, options) else STEP
    times = np.empty(0)

    def outputs(name: str, delta: float) -> np.ndarray:
        nonlocal times
        out, times = rollout_outputs(engine, perturbed(scene, name, delta), variant, options, dt)
        return out

    columns = [central_difference(lambda delta, name=name: outputs(name, delta), parameter_step(scene, name, relative))
               for name in wrt]
    over_time = np.stack(columns, axis=-1)  # (n, m, k)
    return EngineJacobian(over_time[-1], "finite-difference", float(times[-1]), times=times, over_time=over_time)


def engine_jacobian(engine: "Engine", scene: Scene, variant: str | None, options: Mapping[str, Any] | None,
                    dt: float, wrt: Sequence[str]) -> EngineJacobian:
    """The engine's best answer: its own (``Engine.jacobian``: (J, method), or (J, method, times, J over time))
    when it has one for this case, else :func:`finite_difference_jacobian`."""
    check_wrt(scene, wrt)
    own = engine.jacobian(scene, variant, options, dt, list(wrt))
    if own is None:
        return finite_difference_jacobian(engine, scene, variant, options, dt, wrt)
    jacobian, method = own[0], own[1]
    times, over_time = (own[2], own[3]) if len(own) == 4 else (None, None)  # optional: J at every sample
    if method not in METHODS:
        raise ValueError(f"{engine.name}.jacobian: method must be one of {', '.join(METHODS)}, got {method!r}")
    shape = (len(output_columns(scene)), len(wrt))
    if np.shape(jacobian) != shape:
        raise ValueError(f"{engine.name}.jacobian: J must have shape {shape} (outputs × parameters), got "
                         f"{np.shape(jacobian)}")
    if over_time is not None and (np.shape(over_time)[1:] != shape or len(over_time) != len(times)):
        raise ValueError(f"{engine.name}.jacobian: J over time must have shape (samples, {shape[0]}, {shape[1]}), "
                         f"one per time, got {np.shape(over_time)} for {len(times)} times")
    return EngineJacobian(np.asarray(jacobian, dtype=float), method, float(round(scene.duration / dt) * dt), own=True,
                          times=None if times is None else np.asarray(times, dtype=float),
                          over_time=None if over_time is None else np.asarray(over_time, dtype=float))


# -- the chain rule for engines that differentiate their own step -------------------------------


def is_initial_condition(scene: Scene, name: str) -> bool:
    """Whether parameter ``name`` moves only the initial state (positions, velocities), not the physics: an
    engine's derivative of its own step answers for these; for g, masses and lengths its model changes. A model
    scene's parameters (q0, v0) all are."""
    if scene.is_model:
        return True
    moved = perturbed(scene, name, parameter_step(scene, name))
    return (np.array_equal(moved.masses, scene.masses) and moved.gravity == scene.gravity
            and moved.constraints == scene.constraints)


def initial_output_directions(scene: Scene, wrt: Sequence[str]) -> np.ndarray:
    """(m, k) d outputs(0) / d p: how each parameter moves the initial positions and velocities, by central
    differences with one Richardson step (the catalog's maps are sines and cosines: O(h⁴) ≈ 1e-16 at h = 1e-4)."""

    def out(name: str, delta: float) -> np.ndarray:
        moved = perturbed(scene, name, delta)
        return outputs_of(moved.initial_positions, moved.initial_velocities)

    return np.array([central_difference(lambda delta, name=name: out(name, delta), parameter_step(scene, name, 1e-4))
                     for name in wrt]).T


def readout_jacobian(readout, x: np.ndarray, step: float = 1e-5) -> np.ndarray:
    """(m, n) d readout / d x at ``x`` (n,): central differences with one Richardson step of the engine's map
    from its state to the outputs (kinematics only, so O(h⁴) ≈ 1e-20 and round-off ≈ 1e-11)."""
    basis = np.eye(len(x))
    return np.array([central_difference(lambda delta, e=e: readout(x + delta * e), step) for e in basis]).T


def chained_jacobian(scene: Scene, wrt: Sequence[str], transition: np.ndarray, readout, x0: np.ndarray,
                     x_end: np.ndarray) -> np.ndarray:
    """(m, k) d outputs(T) / d p for initial-condition parameters from an engine's own state Jacobian.

    transition : (n, n) d x(T) / d x(0), the product of the engine's one-step Jacobians (or its autodiff);
    readout : the engine's map from its state x (n,) to the outputs (m,); x0, x_end : its states at 0 and T.
    The initial state's direction dx0/dp is the least-squares solution of D readout(x0) · dx0 = d outputs(0)/dp
    (exact: a perturbed scene's initial state is again a state of the engine's model).
    """
    start = np.linalg.lstsq(readout_jacobian(readout, x0), initial_output_directions(scene, wrt), rcond=None)[0]
    return readout_jacobian(readout, x_end) @ transition @ start
