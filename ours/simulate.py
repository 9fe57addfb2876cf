"""One call for a whole trajectory: validate, pack, run the compiled loop, return the samples."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ours.specialize import kernel_for, sizes_of
from ours.status import STATUS_TEXT
from ours.errors import ModelError, OursError
from ours.method import (
    BAUMGARTE,
    DEFAULT_K_S,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOLERANCE,
    LAGRANGIAN,
    critical_damping,
    resolve_pair,
)
from ours.system import System



@dataclass(frozen=True, eq=False)
class Result:
    """Samples of one run (S samples, P particles, C constraints, dim 2 or 3).

    t : (S,) s.  q : (S, P, dim) m.  v : (S, P, dim) m/s.
    multipliers : (S, C) λ in N/m for a distance (C = ½(‖d‖² − l²) in m²; N for a
        Line, whose C is in m; N·m for an Ellipse, whose C has no unit).
    forces : (S, C, dim) N, λ_k g_k (g_k = ∂C_k/∂xᵢ; d_k for a distance): the force
        constraint k exerts on its first particle (the second particle, if any, gets the negative).
    steps : steps taken.  wall_time : s in the compiled loop alone.
    status : "ok", or why the loop stopped early ("non-finite", "singular",
        "not-converged"); the samples up to then are kept.
    settings : method, integrator and every gain and tolerance used.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    multipliers: np.ndarray
    forces: np.ndarray
    steps: int
    wall_time: float
    status: str
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def message(self) -> str:
        if self.status == "ok":
            return ""
        hints = {
            "non-finite": "the state blew up; use a smaller dt or a stabler method",
            "singular": "J W Jᵀ became singular (constraints dependent or degenerate)",
            "not-converged": "the constraint solve did not reach the tolerance; raise max_iterations or the tolerance, or use a smaller dt",
        }
        return f"stopped after {self.steps} steps: {hints[self.status]}"


def _state(system: System, value, name: str) -> np.ndarray:
    array = np.ascontiguousarray(value, dtype=np.float64)
    expected = (system.n_particles, system.dim)
    if array.shape != expected:
        raise ModelError(f"{name}: expected shape {expected} (particles × dim), got {array.shape}")
    if not np.isfinite(array).all():
        raise ModelError(f"{name}: every component must be finite")
    return array.copy()


def _positive(value, name: str, fix: str) -> float:
    number = float(value)
    if not math.isfinite(number) or number <= 0.0:
        raise OursError(f"{name}: must be positive and finite, got {value!r}; {fix}")
    return number


def _count(value, name: str) -> int:
    if isinstance(value, bool) or int(value) != value or int(value) < 1:
        raise OursError(f"{name}: must be an integer ≥ 1, got {value!r}")
    return int(value)


def simulate(
    system: System,
    q0,
    v0,
    dt: float,
    n_steps: int,
    sample_every: int = 1,
    *,
    method: str = "baumgarte",
    integrator: str | None = None,
    k_s: float | None = None,
    k_d: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> Result:
    """Simulate ``system`` from (q0, v0) for ``n_steps`` steps of ``dt`` seconds.

    q0, v0 : (P, dim) m, m/s.  Samples are taken at step 0, every
    ``sample_every`` steps and at the last step.
    method : plain, baumgarte, projection, rattle or lagrangian (``ours.method``).
    integrator : euler, symplectic-euler, midpoint, rk4 or rattle; None takes
        the method's own default (rk4; rattle for rattle). An invalid pair
        raises InvalidPair.
    k_s (1/s²), k_d (1/s) : Baumgarte gains, default 100 and 2·√k_s (used by baumgarte only).
    tolerance : projection / RATTLE stop at max_k |C_k|/l_k² ≤ tolerance.
    max_iterations : most Newton / SHAKE iterations per step.
    """
    chosen, scheme = resolve_pair(method, integrator)
    q = _state(system, q0, "q0")
    v = _state(system, v0, "v0")
    dt = _positive(dt, "dt", "pass a time step in seconds such as 1e-3")
    n_steps = _count(n_steps, "n_steps")
    stride = _count(sample_every, "sample_every")
    ks = DEFAULT_K_S if k_s is None else float(k_s)
    if not math.isfinite(ks) or ks < 0.0:
        raise OursError(f"k_s: must be ≥ 0 (1/s²), got {k_s!r}")
    kd = critical_damping(ks) if k_d is None else float(k_d)
    if not math.isfinite(kd) or kd < 0.0:
        raise OursError(f"k_d: must be ≥ 0 (1/s), got {k_d!r}; 2·sqrt(k_s) is critical damping")
    tolerance = _positive(tolerance, "tolerance", "1e-12 is near round-off for lengths of order 1 m")
    max_iterations = _count(max_iterations, "max_iterations")

    settings = {"method": chosen.name, "integrator": scheme.name, "tolerance": tolerance,
                "max_iterations": max_iterations}
    if chosen.code == BAUMGARTE:
        settings.update(k_s=ks, k_d=kd)
    n_samples = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    out_q = np.full((n_samples, system.n_particles, system.dim), np.nan)
    out_v = np.full_like(out_q, np.nan)
    out_lam = np.full((n_samples, system.n_constraints), np.nan)
    p = system.packed
    model = p.model

    if chosen.code == LAGRANGIAN:
        from ours import lagrangian  # imports numba: only when a run needs it

        theta, omega = lagrangian.chain_coordinates(system, q, v)  # ModelError unless a planar chain
        tail, lengths, gravity, anchor = lagrangian.chain_arrays(system)
        work = lagrangian.workspace(system.n_particles, scheme.stages)
        start = time.perf_counter()
        written, steps, status = lagrangian.run(
            scheme.A, scheme.b, theta, omega, tail, lengths, gravity, anchor, work,
            dt, n_steps, stride, out_q, out_v,
        )
        wall_time = time.perf_counter() - start
        C = system.n_constraints
        _kernel(system).sample_multipliers(
            out_q[:written], out_v[:written], model, np.zeros((C, system.dim)),
            np.zeros((C, p.bandwidth + 1)), out_lam[:written],
        )
    else:
        compiled = _kernel(system)
        work = compiled.workspace(system.n_particles, system.n_constraints, system.dim, p.bandwidth, scheme.stages)
        if id(compiled) not in _warmed:
            # Compile (or load from the cache) before the clock starts: one step on copies.
            compiled.run(chosen.code, scheme.code, scheme.A, scheme.b, q.copy(), v.copy(), model, work, ks, kd, dt,
                         1, 1, tolerance, max_iterations, out_q[:2].copy(), out_v[:2].copy(), out_lam[:2].copy())
            _warmed.add(id(compiled))
        start = time.perf_counter()
        written, steps, status = compiled.run(
            chosen.code, scheme.code, scheme.A, scheme.b, q, v, model, work, ks, kd, dt, n_steps, stride,
            tolerance, max_iterations, out_q, out_v, out_lam,
        )
        wall_time = time.perf_counter() - start

    sample_steps = np.minimum(np.arange(n_samples) * stride, n_steps)
    forces = out_lam[:written, :, None] * _constraint_vectors(system, out_q[:written])
    return Result(
        t=sample_steps[:written] * dt,
        q=out_q[:written],
        v=out_v[:written],
        multipliers=out_lam[:written],
        forces=forces,
        steps=int(steps),
        wall_time=wall_time,
        status=STATUS_TEXT[int(status)],
        settings=settings,
    )


def _constraint_vectors(system: System, q: np.ndarray) -> np.ndarray:
    """(S, C, dim): g_k = ∂C_k/∂xᵢ at each sample (d_k = first particle − other end, m, for a distance)."""
    out = np.zeros((q.shape[0], system.n_constraints, system.dim))
    if q.shape[0] and system.n_constraints:
        _kernel(system).sample_gradients(np.ascontiguousarray(q), system.packed.model, out)
    return out


def multipliers(system: System, q, v, k_s: float = 0.0, k_d: float = 0.0) -> np.ndarray:
    """(C,) λ (N/m) at one state from the compiled banded solve (same code as the stepping loop)."""
    q = _state(system, q, "q")
    v = _state(system, v, "v")
    p = system.packed
    C = system.n_constraints
    lam = np.zeros(C)
    if not _kernel(system).multipliers(q, v, p.model, float(k_s), float(k_d), np.zeros((C, system.dim)),
                                       np.zeros((C, p.bandwidth + 1)), lam):
        raise ModelError("J W Jᵀ is singular at this state: the constraints are dependent or degenerate")
    return lam


_warmed: set[int] = set()


def _kernel(system: System):
    """The kernel specialised for ``system``'s dimension (and sizes, when it is small)."""
    p = system.packed
    return kernel_for(system.dim, sizes_of(system.n_particles, system.n_constraints, p.bandwidth, len(p.pair_k)))


def compile_all() -> float:
    """Compile (or load from the cache) the loops of a planar double pendulum; returns the seconds it took.

    Each structure's kernel (``ours.specialize``) is compiled on its first :func:`simulate`
    anyway, before the clock starts; this is a warm-up for the common case.
    """""
    from ours.constraint import Pin, Rod

    start = time.perf_counter()
    tiny = System((1.0, 1.0), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0), Rod(0, 1, 1.0)))
    q0 = np.array([[1.0, 0.0], [2.0, 0.0]])
    simulate(tiny, q0, np.zeros((2, 2)), 1e-3, 1, method="baumgarte")
    simulate(tiny, q0, np.zeros((2, 2)), 1e-3, 1, method="lagrangian")
    multipliers(tiny, q0, np.zeros((2, 2)))
    return time.perf_counter() - start
