"""Forward sensitivities of a run: d (q, v)(t) / d (q, v)(0) along given directions, by complex step through
the compiled step itself.

Each direction (dq0, dv0) starts ``ours.kernel.run_perturbed`` (``run``'s own step, typed for complex128) from
(q0 + i h dq0, v0 + i h dv0), h = 1e-30. The step is real-analytic arithmetic (numpy's square root in the
Cholesky; tests and Newton stops read real parts only), so Im(state)/h is the derivative of what the kernel
computes, exact to round-off (no difference, no cancellation). The real parts are the real run's bit for bit,
so every branch goes as there. Like forward-mode automatic differentiation with dual numbers (Martins, Sturdza
and Alonso, 2003, show the two equivalent), it carries the derivative through the arithmetic; each direction
costs one complex run.

Covered: every cure (plain, baumgarte, projection, rattle) with every integrator of the maximal-coordinate
kernel. Not covered: ``lagrangian`` (its own kernel): :class:`~ours.errors.OursError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ours.errors import OursError
from ours.method import DEFAULT_K_S, DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, LAGRANGIAN, critical_damping, \
    resolve_pair
from ours.simulate import _count, _kernel, _positive, _state
from ours.status import NON_FINITE, OK, STATUS_TEXT
from ours.system import System

#: The complex step's size: far under any round-off of the state, and with no difference taken it costs nothing.
STEP = 1e-30


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


def forward_sensitivities(system: System, q0, v0, dq0, dv0, dt: float, n_steps: int, *, method: str = "baumgarte",
                          integrator: str | None = None, k_s: float | None = None, k_d: float | None = None,
                          tolerance: float = DEFAULT_TOLERANCE,
                          max_iterations: int = DEFAULT_MAX_ITERATIONS,
                          sample_every: int | None = None) -> Sensitivities:
    """Run ``system`` from (q0, v0) (P, dim) for ``n_steps`` steps of ``dt`` s, as ours.simulate does with the
    same settings, and carry the directions dq0, dv0 (k, P, dim) along: one complex run per direction, sampled
    as ours.simulate samples (every ``sample_every`` steps and the last)."""
    chosen, scheme = resolve_pair(method, integrator)
    if chosen.code == LAGRANGIAN:
        raise OursError("forward_sensitivities: method 'lagrangian' steps in link angles with its own kernel, "
                        "which is not differentiated; use plain, baumgarte, projection or rattle")
    q, v = _state(system, q0, "q0"), _state(system, v0, "v0")
    dq0, dv0 = np.asarray(dq0, dtype=float), np.asarray(dv0, dtype=float)
    if dq0.shape != dv0.shape or dq0.shape[1:] != q.shape:
        raise OursError(f"dq0, dv0: expected shape (k, {q.shape[0]}, {q.shape[1]}) each (directions × particles × "
                        f"dim), got {dq0.shape} and {dv0.shape}")
    dt = _positive(dt, "dt", "pass a time step in seconds such as 1e-3")
    n_steps = _count(n_steps, "n_steps")
    ks = DEFAULT_K_S if k_s is None else float(k_s)
    kd = critical_damping(ks) if k_d is None else float(k_d)
    kernel = _kernel(system)
    p = system.packed
    work = kernel.workspace(system.n_particles, system.n_constraints, system.dim, p.bandwidth, scheme.stages,
                            np.complex128)
    k = len(dq0)
    stride = n_steps if sample_every is None else _count(sample_every, "sample_every")
    marks = np.unique(np.r_[np.arange(0, n_steps, stride), n_steps])
    dq, dv = np.empty_like(dq0), np.empty_like(dv0)
    sample_dq = np.full((len(marks), k, *q.shape), np.nan)
    sample_dv = np.full_like(sample_dq, np.nan)
    end_q, end_v, steps, status = q.astype(complex), v.astype(complex), 0, OK
    for direction in range(max(k, 1)):
        zq, zv = q.astype(complex), v.astype(complex)
        if k:
            zq += 1j * STEP * dq0[direction]
            zv += 1j * STEP * dv0[direction]
            sample_dq[0, direction], sample_dv[0, direction] = dq0[direction], dv0[direction]
        steps, status = 0, OK
        for s, (start, stop) in enumerate(zip(marks[:-1], marks[1:]), 1):
            taken, status = kernel.run_perturbed(chosen.code, scheme.code, scheme.A, scheme.b, zq, zv, p.model,
                                                 work, ks, kd, dt, int(stop - start), float(tolerance),
                                                 int(max_iterations))
            steps += taken
            if status != OK:
                break
            if k:
                sample_dq[s, direction], sample_dv[s, direction] = zq.imag / STEP, zv.imag / STEP
        if k:
            dq[direction], dv[direction] = zq.imag / STEP, zv.imag / STEP
        end_q, end_v = zq, zv
    q_end, v_end = end_q.real.copy(), end_v.real.copy()
    if status == OK and not (np.isfinite(q_end).all() and np.isfinite(v_end).all()):
        status = NON_FINITE
    return Sensitivities(q_end, v_end, dq, dv, int(steps), STATUS_TEXT[int(status)], marks, sample_dq, sample_dv)
