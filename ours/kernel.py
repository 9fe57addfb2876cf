"""The compiled stepping loop in maximal coordinates (positions and velocities of every particle).

Everything here is numba-compiled (``ours.banded.compiled``: cached, no
reference counting): the first call compiles (tens of seconds), later calls and
later processes load the cached machine code. All calls use the same argument
types (float64 / int64 C arrays, dim 2 or 3 as a runtime size), so each
function has one compiled specialization. The compiled code allocates
nothing: scratch arrays come from :func:`workspace`.

Shapes: P particles, C constraints, dim 2 or 3. ``model`` is the tuple
(inverse_mass (P,), force (P, dim), ends (C, 2), anchor (C, dim), length2 (C,),
pair_k, pair_l, pair_w (N,), bandwidth) of :class:`ours.system.Packed`.
"""

from __future__ import annotations

import math

import numpy as np

from ours.banded import cholesky_banded, compiled, solve_banded


def workspace(P: int, C: int, dim: int, bandwidth: int, stages: int) -> tuple:
    """Scratch arrays for :func:`run`, allocated here in Python because the compiled code has no allocator."""
    z = np.zeros
    rattle = (z((C, dim)), z((C, dim)), z((C, bandwidth + 1)), z(C), z(C), z((P, dim)))
    return (z((C, dim)), z((C, dim)), z((C, bandwidth + 1)), z(C), z((stages, P, dim)), z((stages, P, dim)),
            z((P, dim)), z((P, dim)), rattle)


#: Why the loop stopped (0 = ran to the end).
OK, NON_FINITE, SINGULAR, NOT_CONVERGED = 0, 1, 2, 3

# Method and integrator codes (mirrors of ours.method / ours.integrator, kept
# literal here so the compiled code has no Python-object lookups).
_PLAIN, _BAUMGARTE, _PROJECTION, _RATTLE_METHOD = 0, 1, 2, 3
_EXPLICIT_RK, _SYMPLECTIC_EULER, _RATTLE = 0, 1, 2


@compiled
def constraint_vectors(q, ends, anchor, D):
    """D[k] = x_i − x_j (or − the fixed point), m."""
    dim = q.shape[1]
    for k in range(ends.shape[0]):
        i, j = ends[k, 0], ends[k, 1]
        for a in range(dim):
            D[k, a] = q[i, a] - (q[j, a] if j >= 0 else anchor[k, a])


@compiled
def relative_velocities(v, ends, V):
    """V[k] = v_i − v_j (a fixed end does not move), m/s."""
    dim = v.shape[1]
    for k in range(ends.shape[0]):
        i, j = ends[k, 0], ends[k, 1]
        for a in range(dim):
            V[k, a] = v[i, a] - (v[j, a] if j >= 0 else 0.0)


@compiled
def _dot(X, k, Y, l):
    s = 0.0
    for a in range(X.shape[1]):
        s += X[k, a] * Y[l, a]
    return s


@compiled
def assemble(D, pair_k, pair_l, pair_w, band):
    """The lower band of J W Jᵀ (m²/kg) from the constraint vectors D."""
    for k in range(band.shape[0]):
        for j in range(band.shape[1]):
            band[k, j] = 0.0
    for n in range(pair_k.shape[0]):
        k, l = pair_k[n], pair_l[n]
        band[k, k - l] += pair_w[n] * _dot(D, k, D, l)


@compiled
def solve_jwjt(D, model, band, x):
    """x ← (J W Jᵀ)⁻¹ x in place, J from the constraint vectors D; False when J W Jᵀ is singular."""
    bandwidth = model[8]
    assemble(D, model[5], model[6], model[7], band)
    if not cholesky_banded(band, bandwidth):
        return False
    solve_banded(band, bandwidth, x)
    return True


@compiled
def add_constraint_term(x, scale, inverse_mass, ends, D, lam):
    """x += scale · W Jᵀ λ (per particle: +w_i λ_k d_k on the first end, −w_j λ_k d_k on the second)."""
    dim = x.shape[1]
    for k in range(ends.shape[0]):
        i, j = ends[k, 0], ends[k, 1]
        for a in range(dim):
            x[i, a] += scale * inverse_mass[i] * lam[k] * D[k, a]
            if j >= 0:
                x[j, a] -= scale * inverse_mass[j] * lam[k] * D[k, a]


@compiled
def multipliers(q, v, model, k_s, k_d, D, V, band, lam):
    """λ (N/m) from J W Jᵀ λ = −J̇q̇ − J W f − k_s C − k_d Ċ; False when the matrix is singular."""
    inverse_mass, force, ends, anchor, length2 = model[0], model[1], model[2], model[3], model[4]
    constraint_vectors(q, ends, anchor, D)
    relative_velocities(v, ends, V)
    dim = q.shape[1]
    for k in range(ends.shape[0]):
        i, j = ends[k, 0], ends[k, 1]
        jwf = 0.0
        for a in range(dim):
            # J W f: the unconstrained acceleration's component along the constraint.
            accel = inverse_mass[i] * force[i, a] - (inverse_mass[j] * force[j, a] if j >= 0 else 0.0)
            jwf += D[k, a] * accel
        c = 0.5 * (_dot(D, k, D, k) - length2[k])
        c_dot = _dot(D, k, V, k)
        lam[k] = -_dot(V, k, V, k) - jwf - k_s * c - k_d * c_dot
    return solve_jwjt(D, model, band, lam)


@compiled
def acceleration(q, v, model, k_s, k_d, D, V, band, lam, acc):
    """acc = W (f + Jᵀλ), m/s²; False when J W Jᵀ is singular."""
    inverse_mass, force = model[0], model[1]
    ok = multipliers(q, v, model, k_s, k_d, D, V, band, lam)
    for p in range(q.shape[0]):
        for a in range(q.shape[1]):
            acc[p, a] = inverse_mass[p] * force[p, a]
    add_constraint_term(acc, 1.0, inverse_mass, model[2], D, lam)
    return ok


@compiled
def max_violation(D, length2):
    """max_k |C_k| / l_k² (≈ the largest relative length error)."""
    worst = 0.0
    for k in range(D.shape[0]):
        worst = max(worst, abs(0.5 * (_dot(D, k, D, k) - length2[k])) / length2[k])
    return worst


@compiled
def project_velocities(q, v, model, D, band, mu):
    """v ← v − W Jᵀ (J W Jᵀ)⁻¹ J v: the nearest velocity (in the mass metric) with J v = 0."""
    inverse_mass, ends, anchor = model[0], model[2], model[3]
    constraint_vectors(q, ends, anchor, D)
    dim = q.shape[1]
    for k in range(ends.shape[0]):
        i, j = ends[k, 0], ends[k, 1]
        s = 0.0
        for a in range(dim):
            s += D[k, a] * (v[i, a] - (v[j, a] if j >= 0 else 0.0))
        mu[k] = s
    if not solve_jwjt(D, model, band, mu):
        return False
    add_constraint_term(v, -1.0, inverse_mass, ends, D, mu)
    return True


@compiled
def project_positions(q, model, tolerance, max_iterations, D, band, delta):
    """Newton in the mass-weighted metric: q ← q − W Jᵀ (J W Jᵀ)⁻¹ C until max|C|/l² ≤ tolerance.

    Returns OK, SINGULAR or NOT_CONVERGED.
    """
    inverse_mass, ends, anchor, length2 = model[0], model[2], model[3], model[4]
    for _ in range(max_iterations + 1):
        constraint_vectors(q, ends, anchor, D)
        if max_violation(D, length2) <= tolerance:
            return OK
        for k in range(ends.shape[0]):
            delta[k] = 0.5 * (_dot(D, k, D, k) - length2[k])
        if not solve_jwjt(D, model, band, delta):
            return SINGULAR
        add_constraint_term(q, -1.0, inverse_mass, ends, D, delta)
    return NOT_CONVERGED


@compiled
def rattle_step(q, v, h, model, tolerance, max_iterations, work):
    """One RATTLE step (order 2, symplectic) in place; returns OK, SINGULAR or NOT_CONVERGED.

    Half kick with the old constraint directions, drift, and Λ chosen so that
    C(q_{n+1}) = 0 (SHAKE: a Newton-like iteration with J_n W J_nᵀ, factored once
    per step; it contracts by O((hω)²) per iteration). Then the second half kick
    and v projected so that J(q_{n+1}) v_{n+1} = 0.
    """
    inverse_mass, force, ends, anchor, length2, pair_k, pair_l, pair_w, bandwidth = model
    D0, D, band, Lam, delta, q_new = work
    P, dim = q.shape
    constraint_vectors(q, ends, anchor, D0)
    assemble(D0, pair_k, pair_l, pair_w, band)
    if not cholesky_banded(band, bandwidth):
        return SINGULAR
    for p in range(P):
        for a in range(dim):
            q_new[p, a] = q[p, a] + h * v[p, a] + 0.5 * h * h * inverse_mass[p] * force[p, a]
    for k in range(Lam.shape[0]):
        Lam[k] = 0.0
    converged = False
    for _ in range(max_iterations + 1):
        constraint_vectors(q_new, ends, anchor, D)
        if max_violation(D, length2) <= tolerance:
            converged = True
            break
        for k in range(ends.shape[0]):
            delta[k] = -0.5 * (_dot(D, k, D, k) - length2[k])
        solve_banded(band, bandwidth, delta)
        for k in range(ends.shape[0]):
            Lam[k] += delta[k]
        add_constraint_term(q_new, 1.0, inverse_mass, ends, D0, delta)
    if not converged:
        return NOT_CONVERGED
    # v_{n+1/2} = v_n + h/2 W f + W J_nᵀ Λ / h, then the second half kick with f.
    for p in range(P):
        for a in range(dim):
            v[p, a] += h * inverse_mass[p] * force[p, a]
    add_constraint_term(v, 1.0 / h, inverse_mass, ends, D0, Lam)
    _copy(q, q_new)
    if not project_velocities(q, v, model, D, band, delta):
        return SINGULAR
    return OK


@compiled
def _copy(y, x):
    """y[...] = x for (P, dim) arrays (slice assignment may allocate a temporary)."""
    for p in range(y.shape[0]):
        for a in range(y.shape[1]):
            y[p, a] = x[p, a]


@compiled
def _axpy(y, x, alpha, s):
    """y = x + alpha · s (all (P, dim))."""
    for p in range(y.shape[0]):
        for a in range(y.shape[1]):
            y[p, a] = x[p, a] + alpha * s[p, a]


@compiled
def _finite(x):
    """True when every entry of the (rows, cols) array is finite."""
    for p in range(x.shape[0]):
        for a in range(x.shape[1]):
            if not math.isfinite(x[p, a]):
                return False
    return True


@compiled
def _record(n, q, v, model, k_s, k_d, D, V, band, out_q, out_v, out_lam):
    for p in range(q.shape[0]):
        for a in range(q.shape[1]):
            out_q[n, p, a] = q[p, a]
            out_v[n, p, a] = v[p, a]
    if not multipliers(q, v, model, k_s, k_d, D, V, band, out_lam[n]):
        for k in range(out_lam.shape[1]):
            out_lam[n, k] = np.nan


@compiled
def run(method, integrator, A, b, q, v, model, work, k_s, k_d, dt, n_steps, stride, tolerance, max_iterations,
        out_q, out_v, out_lam):
    """Step the system ``n_steps`` times from (q, v) (modified in place), recording every ``stride`` steps
    and the last one into out_q / out_v (S, P, dim) and out_lam (S, C).

    method, integrator : codes from ours.method / ours.integrator. A (s, s), b (s,) : Butcher table.
    work : the arrays of :func:`workspace`. Returns (samples written, steps taken, status).
    """
    stages = b.shape[0]
    D, V, band, lam, Kq, Kv, qs, vs, rattle_work = work
    # Only baumgarte feeds C and Ċ back; its λ at a sample includes the feedback it applied.
    ks = k_s if method == _BAUMGARTE else 0.0
    kd = k_d if method == _BAUMGARTE else 0.0
    h = dt

    _record(0, q, v, model, ks, kd, D, V, band, out_q, out_v, out_lam)
    n = 1
    status = OK
    step = 0
    while step < n_steps:
        if integrator == _RATTLE:
            status = rattle_step(q, v, h, model, tolerance, max_iterations, rattle_work)
        elif integrator == _SYMPLECTIC_EULER:
            if not acceleration(q, v, model, ks, kd, D, V, band, lam, Kv[0]):
                status = SINGULAR
            _axpy(v, v, h, Kv[0])
            _axpy(q, q, h, v)
        else:
            for i in range(stages):
                _copy(qs, q)
                _copy(vs, v)
                for j in range(i):
                    if A[i, j] != 0.0:
                        _axpy(qs, qs, h * A[i, j], Kq[j])
                        _axpy(vs, vs, h * A[i, j], Kv[j])
                _copy(Kq[i], vs)
                if not acceleration(qs, vs, model, ks, kd, D, V, band, lam, Kv[i]):
                    status = SINGULAR
            for i in range(stages):
                if b[i] != 0.0:
                    _axpy(q, q, h * b[i], Kq[i])
                    _axpy(v, v, h * b[i], Kv[i])
        if status == OK and method == _PROJECTION:
            status = project_positions(q, model, tolerance, max_iterations, D, band, lam)
            if status == OK and not project_velocities(q, v, model, D, band, lam):
                status = SINGULAR
        step += 1
        if status != OK:
            if not (_finite(q) and _finite(v)):
                status = NON_FINITE
            break
        if step % stride == 0 or step == n_steps:
            if not (_finite(q) and _finite(v)):
                status = NON_FINITE
                break
            _record(n, q, v, model, ks, kd, D, V, band, out_q, out_v, out_lam)
            n += 1
    return n, step, status
