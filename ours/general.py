"""The general λ formula for any constraint kind, in maximal coordinates (dense J; numpy).

The compiled loop (``ours.kernel``) is specialised to the distance family,
whose J rows are ±d and whose J̇q̇ is ‖ḋ‖². A system holding a curve
constraint (``Line``, ``Ellipse``) is stepped here instead, from each
constraint's closed forms (``value``, ``jacobian``, ``jdot_qdot``):

    J W Jᵀ λ = −J̇q̇ − J W f − k_s C − k_d Ċ,    q̈ = W (f + Jᵀ λ)

with the same methods (plain, baumgarte, projection, rattle) and integrators
(explicit Runge–Kutta tables, symplectic Euler, RATTLE) as the compiled loop,
so a variant means the same scheme on either path. The matrix is dense and
factored by Cholesky each evaluation: fine for the few constraints of a
mechanism, O(C³) in general. Not compiled (it is not on the hot path of any
distance-only scene); its wall time is honest numpy time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ours import status as kernel  # the stop codes (OK, …), shared with the compiled loop
from ours.constraint import CurveConstraint
from ours.errors import ModelError
from ours.method import BAUMGARTE, LAGRANGIAN, PROJECTION, Method
from ours.integrator import RATTLE, SYMPLECTIC_EULER, Integrator


class _Singular(Exception):
    """J W Jᵀ is not positive definite at this state."""


class DenseSystem:
    """Dense closed forms of a System, flattened: q, v as (P·dim,) vectors.

    w : (P·dim,) 1/kg, the inverse mass per coordinate.  f : (P·dim,) N, the applied force m·g.
    """

    def __init__(self, system) -> None:
        self.system = system
        self.shape = (system.n_particles, system.dim)
        masses = np.array(system.masses)
        self.w = np.repeat(1.0 / masses, system.dim)
        self.f = (masses[:, None] * np.array(system.gravity)[None, :]).ravel()
        self.wf = self.w * self.f
        self.first = np.array([c.particles[0] for c in system.constraints], dtype=np.int64)
        # Relative violation: |C| / l² for a distance kind (C in m²), the curve's own rule otherwise.
        self.length2 = np.array([0.0 if isinstance(c, CurveConstraint) else c.length**2 for c in system.constraints])

    def _q(self, x: np.ndarray) -> np.ndarray:
        return x.reshape(self.shape)

    def values(self, x: np.ndarray) -> np.ndarray:
        q = self._q(x)
        return np.array([c.value(q) for c in self.system.constraints])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(C, P·dim)."""
        q = self._q(x)
        return np.array([c.jacobian(q).ravel() for c in self.system.constraints]).reshape(len(self.first), -1)

    def jdot_qdot(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        q, v = self._q(x), self._q(u)
        return np.array([c.jdot_qdot(q, v) for c in self.system.constraints])

    def violation(self, x: np.ndarray) -> float:
        """max over constraints of the relative violation (the projection / RATTLE stopping rule)."""
        q = self._q(x)
        worst = 0.0
        for k, c in enumerate(self.system.constraints):
            rel = c.violation(q) if isinstance(c, CurveConstraint) else abs(c.value(q)) / self.length2[k]
            worst = max(worst, rel)
        return worst

    def _solve(self, J: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """(J W Jᵀ)⁻¹ rhs; _Singular when the matrix is singular (LAPACK's LU meets a zero pivot or the
        answer is not finite). The matrix is symmetric positive semi-definite, so LU serves as well as
        Cholesky, in one numpy call instead of three."""
        try:
            out = np.linalg.solve((J * self.w) @ J.T, rhs)
        except np.linalg.LinAlgError:
            raise _Singular from None
        if not np.isfinite(out).all():
            raise _Singular
        return out

    def multipliers(self, x, u, k_s, k_d) -> tuple[np.ndarray, np.ndarray]:
        """(λ (C,), J (C, P·dim)) from the general formula."""
        J = self.jacobian(x)
        rhs = -self.jdot_qdot(x, u) - J @ self.wf
        if k_s or k_d:
            rhs = rhs - k_s * self.values(x) - k_d * (J @ u)
        return self._solve(J, rhs), J

    def acceleration(self, x, u, k_s, k_d) -> np.ndarray:
        lam, J = self.multipliers(x, u, k_s, k_d)
        return self.wf + self.w * (J.T @ lam)

    def project_positions(self, x, tolerance, max_iterations) -> int:
        """Newton in the mass metric, x ← x − W Jᵀ (J W Jᵀ)⁻¹ C, in place; OK or NOT_CONVERGED."""
        for _ in range(max_iterations + 1):
            if self.violation(x) <= tolerance:
                return kernel.OK
            J = self.jacobian(x)
            x -= self.w * (J.T @ self._solve(J, self.values(x)))
        return kernel.NOT_CONVERGED

    def project_velocities(self, x, u) -> None:
        """u ← u − W Jᵀ (J W Jᵀ)⁻¹ J u, in place."""
        J = self.jacobian(x)
        u -= self.w * (J.T @ self._solve(J, J @ u))

    def rattle_step(self, x, u, h, tolerance, max_iterations) -> int:
        """One RATTLE step in place (as ``kernel.rattle_step``): SHAKE with J₀ W J₀ᵀ, then v projected."""
        J0 = self.jacobian(x)
        x_new = x + h * u + 0.5 * h * h * self.wf
        lam = np.zeros(len(self.first))
        for _ in range(max_iterations + 1):
            if self.violation(x_new) <= tolerance:
                break
            delta = self._solve(J0, -self.values(x_new))
            lam += delta
            x_new += self.w * (J0.T @ delta)
        else:
            return kernel.NOT_CONVERGED
        u += h * self.wf + self.w * (J0.T @ lam) / h
        x[:] = x_new
        self.project_velocities(x, u)
        return kernel.OK


@dataclass(frozen=True, eq=False)
class Run:
    """What :func:`run` returns (``ours.simulate`` wraps it in its Result).

    t : (S,) s.  q, v : (S, P, dim) m, m/s.  multipliers : (S, C).  forces : (S, C, dim) N on each
    constraint's first particle.  steps : taken.  wall_time : s of the stepping loop.
    status : a ``kernel`` status code.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    multipliers: np.ndarray
    forces: np.ndarray
    steps: int
    wall_time: float
    status: int


def run(system, q, v, dt: float, n_steps: int, stride: int, chosen: Method, scheme: Integrator,
        k_s: float, k_d: float, tolerance: float, max_iterations: int) -> Run:
    """Step a system holding curve constraints.

    Arguments are those of :func:`ours.simulate.simulate`, already validated
    (q, v : (P, dim) copies; the method and integrator records).
    """
    if chosen.code == LAGRANGIAN:
        raise ModelError(
            "method 'lagrangian' needs a planar (2-D) chain hung from a fixed point; this system holds a "
            "curve constraint (Line or Ellipse), which is not a chain link"
        )
    dense = DenseSystem(system)
    ks = k_s if chosen.code == BAUMGARTE else 0.0
    kd = k_d if chosen.code == BAUMGARTE else 0.0
    P, dim, C = system.n_particles, system.dim, system.n_constraints
    n_samples = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    out_q = np.full((n_samples, P, dim), np.nan)
    out_v = np.full_like(out_q, np.nan)
    out_lam = np.full((n_samples, C), np.nan)
    x, u = q.ravel().copy(), v.ravel().copy()
    A, b, stages = scheme.A, scheme.b, scheme.stages

    def record(n: int) -> None:
        out_q[n], out_v[n] = x.reshape(P, dim), u.reshape(P, dim)
        try:
            out_lam[n] = dense.multipliers(x, u, ks, kd)[0]
        except _Singular:
            pass

    record(0)
    written, step, status = 1, 0, kernel.OK
    h = dt
    start = time.perf_counter()
    while step < n_steps:
        try:
            if scheme.code == RATTLE:
                status = dense.rattle_step(x, u, h, tolerance, max_iterations)
            elif scheme.code == SYMPLECTIC_EULER:
                u += h * dense.acceleration(x, u, ks, kd)
                x += h * u
            else:
                Kq, Kv = [], []
                for i in range(stages):
                    xs, us = x.copy(), u.copy()
                    for j in range(i):
                        if A[i, j] != 0.0:
                            xs += h * A[i, j] * Kq[j]
                            us += h * A[i, j] * Kv[j]
                    Kq.append(us)
                    Kv.append(dense.acceleration(xs, us, ks, kd))
                for i in range(stages):
                    if b[i] != 0.0:
                        x += h * b[i] * Kq[i]
                        u += h * b[i] * Kv[i]
            if status == kernel.OK and chosen.code == PROJECTION:
                status = dense.project_positions(x, tolerance, max_iterations)
                if status == kernel.OK:
                    dense.project_velocities(x, u)
        except _Singular:
            status = kernel.SINGULAR
        step += 1
        finite = bool(np.isfinite(x).all() and np.isfinite(u).all())
        if status != kernel.OK or not finite:
            status = kernel.NON_FINITE if not finite else status
            break
        if step % stride == 0 or step == n_steps:
            record(written)
            written += 1
    wall_time = time.perf_counter() - start

    sample_steps = np.minimum(np.arange(n_samples) * stride, n_steps)
    qs = out_q[:written]
    # The force on each constraint's first particle: λ_k times J_k's block on that particle.
    forces = np.zeros((written, C, dim))
    for s in range(written):
        J = dense.jacobian(qs[s].ravel()).reshape(C, P, dim)
        forces[s] = out_lam[s][:, None] * J[np.arange(C), dense.first]
    return Run(sample_steps[:written] * dt, qs, out_v[:written], out_lam[:written], forces, int(step),
               wall_time, int(status))
