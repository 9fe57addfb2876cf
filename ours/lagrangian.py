"""Reduced coordinates for a planar chain: link angles from Lagrange's equations.

Link k joins particle k − 1 (or the fixed point, for k = 0) to particle k;
θ_k is its absolute angle from the −y axis toward +x, so
x_k = a + Σ_{i ≤ k} l_i (sin θ_i, −cos θ_i). With μ_ij = Σ_{k ≥ max(i, j)} m_k,

    Σ_j μ_ij l_i l_j cos(θ_i − θ_j) θ̈_j
        = −Σ_j μ_ij l_i l_j sin(θ_i − θ_j) θ̇_j² + μ_ii l_i (g_x cos θ_i + g_y sin θ_i),

so the constraints hold by construction (up to round-off in the positions).
The mass matrix is dense: each step costs O(n³) in the number of links (this
form is for the short chains where it is the accurate choice, not for speed).
"""

from __future__ import annotations

import math

import numpy as np

from ours.banded import cholesky_banded, compiled, solve_banded
from ours.errors import ModelError
from ours.status import NON_FINITE, OK, SINGULAR


@compiled
def angular_acceleration(theta, omega, tail, lengths, gravity, M, alpha):
    """θ̈ (rad/s²) into ``alpha``; False when the mass matrix is singular. M : (n, n) workspace."""
    n = theta.shape[0]
    for i in range(n):
        s = tail[i] * lengths[i] * (gravity[0] * math.cos(theta[i]) + gravity[1] * math.sin(theta[i]))
        for j in range(n):
            mu = tail[max(i, j)] * lengths[i] * lengths[j]
            s -= mu * math.sin(theta[i] - theta[j]) * omega[j] * omega[j]
            if j <= i:
                M[i, i - j] = mu * math.cos(theta[i] - theta[j])
        alpha[i] = s
    if not cholesky_banded(M, n, n - 1):
        return False
    solve_banded(M, n, n - 1, alpha)
    return True


@compiled
def to_cartesian(theta, omega, lengths, anchor, q, v):
    """Particle positions (n, 2) m and velocities (n, 2) m/s of the chain."""
    x, y, vx, vy = anchor[0], anchor[1], 0.0, 0.0
    for k in range(theta.shape[0]):
        s, c = math.sin(theta[k]), math.cos(theta[k])
        x += lengths[k] * s
        y -= lengths[k] * c
        vx += lengths[k] * omega[k] * c
        vy += lengths[k] * omega[k] * s
        q[k, 0], q[k, 1], v[k, 0], v[k, 1] = x, y, vx, vy


@compiled
def _finite(x):
    for k in range(x.shape[0]):
        if not math.isfinite(x[k]):
            return False
    return True


@compiled
def run(A, b, theta, omega, tail, lengths, gravity, anchor, work, dt, n_steps, stride, out_q, out_v):
    """Step (θ, θ̇) with the explicit Runge–Kutta table (A, b), recording Cartesian samples.

    The multipliers at the samples (the constraint forces of the exact motion: the
    acceleration-level solve with no feedback) are computed afterwards by
    ``sample_multipliers`` of the maximal-coordinate kernel (``ours.simulate``).

    tail : (n,) kg, μ_ii = Σ_{k ≥ i} m_k.  lengths : (n,) m.  gravity, anchor : (2,).
    work : the arrays of :func:`workspace`. Returns (samples written, steps taken, status).
    """
    n_links = theta.shape[0]
    stages = b.shape[0]
    M, Kt, Kw, ts, ws = work
    h = dt
    # The sample's rows, not an index: a constant index made numba compile a copy per constant.
    to_cartesian(theta, omega, lengths, anchor, out_q[0], out_v[0])
    n = 1
    status = OK
    step = 0
    while step < n_steps:
        for i in range(stages):
            for k in range(n_links):
                ts[k] = theta[k]
                ws[k] = omega[k]
            for j in range(i):
                if A[i, j] != 0.0:
                    for k in range(n_links):
                        ts[k] += h * A[i, j] * Kt[j, k]
                        ws[k] += h * A[i, j] * Kw[j, k]
            for k in range(n_links):
                Kt[i, k] = ws[k]
            if not angular_acceleration(ts, ws, tail, lengths, gravity, M, Kw[i]):
                status = SINGULAR
        for i in range(stages):
            for k in range(n_links):
                theta[k] += h * b[i] * Kt[i, k]
                omega[k] += h * b[i] * Kw[i, k]
        step += 1
        if not (_finite(theta) and _finite(omega)):
            status = NON_FINITE
        if status != OK:
            break
        if step % stride == 0 or step == n_steps:
            to_cartesian(theta, omega, lengths, anchor, out_q[n], out_v[n])
            n += 1
    return n, step, status


def workspace(n: int, stages: int) -> tuple:
    """Scratch arrays for :func:`run` (the compiled code allocates nothing)."""
    z = np.zeros
    return (z((n, n)), z((stages, n)), z((stages, n)), z(n), z(n))


def check_chain(system) -> None:
    """ModelError unless ``system`` is a planar chain hung from a fixed point (what this form steps)."""
    why = system.why_not_a_chain()
    if system.dim != 2 or why is not None:
        raise ModelError(
            "method 'lagrangian' needs a planar (2-D) chain hung from a fixed point; "
            + (why and f"this system is not one: {why}" or f"this system is {system.dim}-D")
        )


def chain_arrays(system) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The chain's arrays :func:`run` reads: tail (n,) kg (μ_ii = Σ_{k ≥ i} m_k), lengths (n,) m, gravity (2,)
    m/s², anchor (2,) m."""
    masses = np.array(system.masses)
    tail = np.ascontiguousarray(np.cumsum(masses[::-1])[::-1])
    lengths = np.array([c.length for c in system.constraints])
    anchor = np.asarray(system.constraints[0].ends()[2], dtype=float)
    return tail, lengths, np.array(system.gravity), anchor


def chain_coordinates(system, q0: np.ndarray, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(θ, θ̇) of a planar chain from Cartesian (q0, v0) (n, 2): absolute link angles, rad and rad/s; ModelError
    unless ``system`` is a planar chain."""
    check_chain(system)
    theta = np.empty(system.n_particles)
    omega = np.empty(system.n_particles)
    anchor = np.asarray(system.constraints[0].ends()[2], dtype=float)
    for k in range(len(system.constraints)):
        base_q = anchor if k == 0 else q0[k - 1]
        base_v = np.zeros(2) if k == 0 else v0[k - 1]
        d, dd = q0[k] - base_q, v0[k] - base_v
        theta[k] = math.atan2(d[0], -d[1])
        omega[k] = (d[0] * dd[1] - d[1] * dd[0]) / float(d @ d)
    return theta, omega
