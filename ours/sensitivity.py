"""Forward sensitivities of a run: d (q, v)(t) / d p along given directions, by the tangent-linear step.

A direction moves the initial state (dq0, dv0) and, for a physical parameter (g, a mass, a length), the model
(:class:`ModelDirections`). :func:`forward_sensitivities` carries all k directions through one run of
``ours/tangent.py``'s step (the real step once, each direction its derivative alone);
:func:`complex_step_sensitivities` computes the same derivatives independently, one complex run of the kernel's
own step per direction (h = 1e-30: exact to round-off), the check the tests hold the first to. Every cure
(plain, baumgarte, projection, rattle) with every integrator of the maximal-coordinate kernel; not
``lagrangian`` (its own kernel): :class:`~ours.errors.OursError`.

Details: docs/ours.md, "Module notes", ``ours/sensitivity.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ours.errors import OursError
from ours.integrator import Integrator
from ours.method import DEFAULT_K_S, DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, LAGRANGIAN, critical_damping, \
    resolve_pair
from ours.simulate import _count, _kernel, _positive, _state
from ours.specialize import sizes_of, tangent_for
from ours.status import NON_FINITE, OK, STATUS_TEXT
from ours.system import System

#: The complex step's size: far under any round-off of the state, and with no difference taken it costs nothing.
STEP = 1e-30
#: The packed model's arrays a physical parameter moves, in the order of ``ours.system.Packed.model``'s fields.
MOVING_FIELDS = ("inverse_mass", "force", "anchor", "param", "pair_w")


@dataclass(frozen=True, eq=False)
class ModelDirections:
    """The derivatives of the packed model's arrays (``ours.system.Packed``) along k directions: what g, masses
    and lengths move. inverse_mass (k, P) 1/kg, force (k, P, dim) N, anchor (k, C, dim) m, param (k, C, m),
    pair_w (k, N) 1/kg, each per unit of its direction's parameter."""

    inverse_mass: np.ndarray
    force: np.ndarray
    anchor: np.ndarray
    param: np.ndarray
    pair_w: np.ndarray

    @classmethod
    def zeros(cls, system: System, k: int) -> "ModelDirections":
        """k directions that leave the model alone (initial conditions only)."""
        p = system.packed
        return cls(*(np.zeros((k, *getattr(p, name).shape)) for name in MOVING_FIELDS))

    @classmethod
    def of(cls, build: Callable[[float], System], step: float) -> "ModelDirections":
        """One direction: d/dδ of ``build(δ)``'s packed arrays at δ = 0, by central differences at ±step and
        ±step/2 with one Richardson step (error O(step⁴): the arrays are 1/m, m·g, l², smooth in δ)."""
        systems = {delta: build(delta) for delta in (step, -step, step / 2, -step / 2)}
        base = build(0.0)
        for system in systems.values():
            if len(system.packed.pair_k) != len(base.packed.pair_k) or system.n_constraints != base.n_constraints:
                raise OursError("ModelDirections.of: the perturbed systems must have the structure of the unperturbed "
                                "one (the same particles and constraints); only their values may move")

        def derivative(name: str) -> np.ndarray:
            def at(delta: float) -> np.ndarray:
                return np.asarray(getattr(systems[delta].packed, name), dtype=float)

            wide = (at(step) - at(-step)) / (2 * step)
            narrow = (at(step / 2) - at(-step / 2)) / step
            return (4 * narrow - wide) / 3

        return cls(*(derivative(name)[None] for name in MOVING_FIELDS))

    @classmethod
    def stack(cls, directions: list["ModelDirections"]) -> "ModelDirections":
        """The directions of several, in order."""
        return cls(*(np.ascontiguousarray(np.concatenate([getattr(d, name) for d in directions]))
                     for name in MOVING_FIELDS))

    @property
    def arrays(self) -> tuple:
        """The five arrays, C-contiguous, as ``run_tangent``'s ``dmodel``."""
        return tuple(np.ascontiguousarray(getattr(self, name), dtype=float) for name in MOVING_FIELDS)

    def check(self, system: System, k: int) -> None:
        """OursError unless there are k directions of ``system``'s arrays."""
        p = system.packed
        for name in MOVING_FIELDS:
            expected = (k, *getattr(p, name).shape)
            if getattr(self, name).shape != expected:
                raise OursError(f"dmodel.{name}: expected shape {expected} (directions × the packed array), got "
                                f"{getattr(self, name).shape}")


@dataclass(frozen=True, eq=False)
class Sensitivities:
    """The state at T and its derivatives along the k directions.

    q, v : (P, dim) m, m/s at T; dq, dv : (k, P, dim) d q(T) / d direction, d v(T) / d direction (per unit of
    the direction); steps : steps taken; status : "ok", or why the run stopped early (as ours.simulate says).
    """

    q: np.ndarray
    v: np.ndarray
    dq: np.ndarray
    dv: np.ndarray
    steps: int
    status: str
    #: (S,) the steps of the samples (0, every ``sample_every`` steps and the last; without it 0 and the last),
    #: and (S, k, P, dim) dq, dv there (NaN past an early stop).
    sample_steps: np.ndarray
    sample_dq: np.ndarray
    sample_dv: np.ndarray


@dataclass(frozen=True)
class _Run:
    """The validated arguments both methods share."""

    code: int
    scheme: Integrator
    q: np.ndarray
    v: np.ndarray
    dq0: np.ndarray
    dv0: np.ndarray
    dmodel: ModelDirections | None
    dt: float
    ks: float
    kd: float
    tolerance: float
    max_iterations: int
    marks: np.ndarray


def _prepare(caller: str, system: System, q0, v0, dq0, dv0, dt, n_steps, *, dmodel: ModelDirections | None = None,
             method: str = "baumgarte", integrator: str | None = None, k_s: float | None = None,
             k_d: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
             max_iterations: int = DEFAULT_MAX_ITERATIONS, sample_every: int | None = None) -> _Run:
    """The arguments both methods take, checked; the keywords' one home (their defaults are ours.simulate's)."""
    chosen, scheme = resolve_pair(method, integrator)
    q, v = _state(system, q0, "q0"), _state(system, v0, "v0")
    dq0, dv0 = np.ascontiguousarray(dq0, dtype=float), np.ascontiguousarray(dv0, dtype=float)
    if dq0.shape != dv0.shape or dq0.shape[1:] != q.shape:
        raise OursError(f"dq0, dv0: expected shape (k, {q.shape[0]}, {q.shape[1]}) each (directions × particles × "
                        f"dim), got {dq0.shape} and {dv0.shape}")
    if dmodel is not None:
        dmodel.check(system, len(dq0))
    dt = _positive(dt, "dt", "pass a time step in seconds such as 1e-3")
    n_steps = _count(n_steps, "n_steps")
    ks = DEFAULT_K_S if k_s is None else float(k_s)
    kd = critical_damping(ks) if k_d is None else float(k_d)
    stride = n_steps if sample_every is None else _count(sample_every, "sample_every")
    marks = np.unique(np.r_[np.arange(0, n_steps, stride), n_steps])
    return _Run(chosen.code, scheme, q, v, dq0, dv0, dmodel, dt, ks, kd, float(tolerance), int(max_iterations), marks)


def _result(run: _Run, q_end, v_end, dq, dv, steps, status, sample_dq, sample_dv) -> Sensitivities:
    q_end, v_end = np.array(q_end, dtype=float), np.array(v_end, dtype=float)
    if status == OK and not (np.isfinite(q_end).all() and np.isfinite(v_end).all()):
        status = NON_FINITE
    return Sensitivities(q_end, v_end, dq, dv, int(steps), STATUS_TEXT[int(status)], run.marks, sample_dq, sample_dv)


def forward_sensitivities(system: System, q0, v0, dq0, dv0, dt: float, n_steps: int, **settings: Any
                          ) -> Sensitivities:
    """Run ``system`` from (q0, v0) (P, dim) for ``n_steps`` steps of ``dt`` s, as ours.simulate does with the
    same settings, and carry the directions dq0, dv0 (k, P, dim) along, all k in one tangent-linear run.

    settings (keywords): dmodel, the model's :class:`ModelDirections` along each direction (default None: the
    model does not move); method (default "baumgarte"), integrator, k_s, k_d, tolerance, max_iterations as
    ours.simulate takes them; sample_every, steps between samples (default None: 0 and the last step only).
    """
    run = _prepare("forward_sensitivities", system, q0, v0, dq0, dv0, dt, n_steps, **settings)
    k = len(run.dq0)
    if run.code == LAGRANGIAN:
        return _lagrangian_sensitivities(system, run)
    p = system.packed
    kernel = tangent_for(system.dim, sizes_of(system.n_particles, system.n_constraints, p.bandwidth, len(p.pair_k)))
    scheme = run.scheme
    stages = scheme.stages
    work = kernel.workspace(system.n_particles, system.n_constraints, system.dim, p.bandwidth, stages)
    tangent_work = kernel.tangent_workspace(k, system.n_particles, system.n_constraints, system.dim, stages)
    moving = (run.dmodel or ModelDirections.zeros(system, k)).arrays
    q, v, dq, dv = run.q, run.v, run.dq0.copy(), run.dv0.copy()
    sample_dq = np.full((len(run.marks), k, *q.shape), np.nan)
    sample_dv = np.full_like(sample_dq, np.nan)
    sample_dq[0], sample_dv[0] = dq, dv
    steps, status = 0, OK
    for s, (start, stop) in enumerate(zip(run.marks[:-1], run.marks[1:]), 1):
        taken, status = kernel.run_tangent(run.code, scheme.code, scheme.A, scheme.b,
                                           q, v, p.model, work, run.ks, run.kd, run.dt, int(stop - start),
                                           run.tolerance, run.max_iterations, dq, dv, moving, run.dmodel is not None,
                                           tangent_work)
        steps += taken
        if status != OK:
            break
        sample_dq[s], sample_dv[s] = dq, dv
    return _result(run, q, v, dq, dv, steps, status, sample_dq, sample_dv)


def _complex_model(system: System, dmodel: ModelDirections | None, direction: int) -> tuple:
    """The packed model with its moving arrays advanced by i·STEP along ``direction`` (the real model without
    ``dmodel``: the kernel keeps its real-model compilation)."""
    model = system.packed.model
    if dmodel is None:
        return model
    fields = dict(zip(MOVING_FIELDS, (0, 1, 3, 5, 9)))
    moved = list(model)
    for name, index in fields.items():
        moved[index] = np.ascontiguousarray(model[index] + 1j * STEP * getattr(dmodel, name)[direction])
    return tuple(moved)


def complex_step_sensitivities(system: System, q0, v0, dq0, dv0, dt: float, n_steps: int, **settings: Any
                               ) -> Sensitivities:
    """:func:`forward_sensitivities`' derivatives (the same arguments) computed independently, by complex step: one
    complex run per direction (the check the tests hold the tangent-linear step to)."""
    run = _prepare("complex_step_sensitivities", system, q0, v0, dq0, dv0, dt, n_steps, **settings)
    if run.code == LAGRANGIAN:
        raise OursError("complex_step_sensitivities: method 'lagrangian' steps in link angles with its own kernel, "
                        "which has no complex form; use plain, baumgarte, projection or rattle")
    kernel = _kernel(system)
    p = system.packed
    scheme = run.scheme
    work = kernel.workspace(system.n_particles, system.n_constraints, system.dim, p.bandwidth,
                            scheme.stages, np.complex128)
    k = len(run.dq0)
    dq, dv = np.empty_like(run.dq0), np.empty_like(run.dv0)
    sample_dq = np.full((len(run.marks), k, *run.q.shape), np.nan)
    sample_dv = np.full_like(sample_dq, np.nan)
    end_q, end_v, steps, status = run.q.astype(complex), run.v.astype(complex), 0, OK
    for direction in range(max(k, 1)):
        zq, zv = run.q.astype(complex), run.v.astype(complex)
        model = p.model
        if k:
            zq += 1j * STEP * run.dq0[direction]
            zv += 1j * STEP * run.dv0[direction]
            model = _complex_model(system, run.dmodel, direction)
            sample_dq[0, direction], sample_dv[0, direction] = run.dq0[direction], run.dv0[direction]
        steps, status = 0, OK
        for s, (start, stop) in enumerate(zip(run.marks[:-1], run.marks[1:]), 1):
            taken, status = kernel.run_perturbed(run.code, scheme.code, scheme.A,
                                                 scheme.b, zq, zv, model, work,
                                                 run.ks, run.kd, run.dt, int(stop - start), run.tolerance,
                                                 run.max_iterations)
            steps += taken
            if status != OK:
                break
            if k:
                sample_dq[s, direction], sample_dv[s, direction] = zq.imag / STEP, zv.imag / STEP
        if k:
            dq[direction], dv[direction] = zq.imag / STEP, zv.imag / STEP
        end_q, end_v = zq, zv
    return _result(run, end_q.real, end_v.real, dq, dv, steps, status, sample_dq, sample_dv)


def _lagrangian_sensitivities(system: System, run: _Run) -> Sensitivities:
    """:func:`forward_sensitivities` for the reduced-coordinate chain (``ours/lagrangian_tangent.py``): the
    directions taken into link angles, carried by its tangent-linear step, and back to particles at each sample;
    the model's directions become the chain's (d tail, d lengths, d gravity, d anchor)."""
    from ours import lagrangian
    from ours import lagrangian_tangent as tangent

    k, scheme = len(run.dq0), run.scheme
    theta, omega = lagrangian.chain_coordinates(system, run.q, run.v)
    tail, lengths, gravity, anchor = lagrangian.chain_arrays(system)
    dmodel = run.dmodel or ModelDirections.zeros(system, k)
    masses = np.array(system.masses)
    d_masses = -dmodel.inverse_mass * masses**2  # d(1/m) = −dm/m²
    d_tail = np.ascontiguousarray(np.cumsum(d_masses[:, ::-1], axis=1)[:, ::-1])
    d_lengths = np.ascontiguousarray(dmodel.param[:, :, 0] / (2.0 * lengths))  # param = l²
    d_gravity = np.ascontiguousarray((dmodel.force[:, 0, :] - d_masses[:, :1] * gravity) / masses[0])  # f = m g
    d_anchor = dmodel.anchor[:, 0, :]
    dtheta, domega = (np.ascontiguousarray(x) for x in tangent.coordinates_tangent(run.q, run.v, run.dq0, run.dv0,
                                                                                    anchor, d_anchor))
    work = lagrangian.workspace(system.n_particles, scheme.stages)
    tangent_work = tangent.tangent_workspace(k, system.n_particles, scheme.stages)
    sample_dq = np.full((len(run.marks), k, *run.q.shape), np.nan)
    sample_dv = np.full_like(sample_dq, np.nan)
    sample_dq[0], sample_dv[0] = run.dq0, run.dv0
    steps, status = 0, OK
    for s, (start, stop) in enumerate(zip(run.marks[:-1], run.marks[1:]), 1):
        taken, status = tangent.run_tangent(scheme.A, scheme.b, theta, omega, tail, lengths, gravity, work, run.dt,
                                            int(stop - start), dtheta, domega, d_tail, d_lengths, d_gravity,
                                            tangent_work)
        steps += taken
        if status != OK:
            break
        sample_dq[s], sample_dv[s] = tangent.cartesian_tangent(theta, omega, dtheta, domega, lengths, d_lengths,
                                                               d_anchor)
    q, v = np.empty_like(run.q), np.empty_like(run.v)
    lagrangian.to_cartesian(theta, omega, lengths, anchor, q, v)
    dq, dv = tangent.cartesian_tangent(theta, omega, dtheta, domega, lengths, d_lengths, d_anchor)
    return _result(run, q, v, dq, dv, steps, status, sample_dq, sample_dv)
