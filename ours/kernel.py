"""The compiled stepping loop in maximal coordinates (positions and velocities of every particle).

Everything here is numba-compiled (``ours.banded.compiled``: cached, no
reference counting). The compiled code allocates nothing: scratch arrays come
from :func:`workspace`.

Details: docs/ours.md, "Module notes", ``ours/kernel.py``.
"""

from __future__ import annotations

import math

import numpy as np

from ours.banded import cholesky_banded, compiled, inlined, llvm_inlined, solve_banded
from ours.constraint import DISTANCE, ELLIPSE, LINE
from ours.status import NON_FINITE, NOT_CONVERGED, OK, SINGULAR

# The functions a step calls per stage or per iteration (``acceleration``, ``multipliers``,
# ``constraint_value``, ``constraint_rate``; ``rattle_step``, ``violations``, ``project_velocities``)
# are ``llvm_inlined``: a call between compiled functions copies every field of every array argument
# (``model`` alone is 11 arrays) onto the stack; pasted, the double pendulum's RK4 step costs about
# half as much and its RATTLE step about a third (``bench/bench_ours.py``; figures in docs/ours.md).


# ---- SIZES (ours.specialize replaces this block with constants) ----


@compiled
def _dim(x):
    """Number of coordinates per particle (columns of a (P, dim) or (C, dim) array)."""
    return x.shape[1]


@compiled
def _particles(x):
    """P, the rows of a (P, dim) array."""
    return x.shape[0]


@compiled
def _constraints(x):
    """C, the rows of a (C, …) array."""
    return x.shape[0]


@compiled
def _band_columns(band):
    """bandwidth + 1, the columns of the (C, bandwidth + 1) band of J W Jᵀ."""
    return band.shape[1]


@compiled
def _pairs(pair_k):
    """N, the nonzeros of the lower band of J W Jᵀ (entries of the pair tables)."""
    return pair_k.shape[0]


@compiled
def _closed_form(band):
    """Whether J W Jᵀ is solved in closed form (``solve_closed``): only in a copy specialised for at
    most 3 constraints."""
    return False


# ---- END SIZES ----


def workspace(P: int, C: int, dim: int, bandwidth: int, stages: int, dtype: type = np.float64) -> tuple:
    """Scratch arrays for :func:`run`, allocated here in Python because the compiled code has no allocator
    (complex128 for :func:`run_perturbed`'s complex step)."""

    def z(shape):
        return np.zeros(shape, dtype)

    rattle = (z((C, dim)), z((C, dim)), z((C, bandwidth + 1)), z(C), z(C), z((P, dim)))
    return (z((C, dim)), z((C, bandwidth + 1)), z(C), z((stages, P, dim)), z((stages, P, dim)),
            z((P, dim)), z((P, dim)), rattle)


# Why the loop stopped (0 = ran to the end): ours.status.

# Method and integrator codes (mirrors of ours.method / ours.integrator, kept
# literal here so the compiled code has no Python-object lookups).
_PLAIN, _BAUMGARTE, _PROJECTION, _RATTLE_METHOD = 0, 1, 2, 3
_EXPLICIT_RK, _SYMPLECTIC_EULER, _RATTLE = 0, 1, 2

# Constraint kinds (set by ``encode`` in ``ours.constraint``); a curve kind holds one particle
# (j = −1) on a curve about its anchor, d = xᵢ − anchor:
# DISTANCE: C = ½(‖d‖² − l²), param = (l²,), g = d, J̇q̇ = ‖ḋ‖², scale l².
# LINE: C = n·d (m), param = n (the unit normal), g = n, J̇q̇ = 0, scale 1.
# ELLIPSE: C = ½(Σₐ dₐ² / sₐ² − 1), param = (1/sₐ²) (the inverse squared semi-axes),
#     gₐ = dₐ / sₐ², J̇q̇ = Σₐ vₐ² / sₐ², scale 1.


@llvm_inlined
def constraint_value(k, q, ends, anchor, kind, param, G):
    """C_k (the constraint's own unit) at q; writes g = ∂C_k/∂d into G[k] (dim,).

    ends, anchor, kind, param : the fields of ``model`` (passed one by one: a call that
    is not inlined copies its arguments)."""
    i, j = ends[k, 0], ends[k, 1]
    dim = _dim(q)
    if kind[k] == DISTANCE:
        s = 0.0
        for a in range(dim):
            d = q[i, a] - (q[j, a] if j >= 0 else anchor[k, a])
            G[k, a] = d
            s += d * d
        return 0.5 * (s - param[k, 0])
    if kind[k] == LINE:
        s = 0.0
        for a in range(dim):
            G[k, a] = param[k, a]
            s += param[k, a] * (q[i, a] - anchor[k, a])
        return s
    if kind[k] == ELLIPSE:
        s = 0.0
        for a in range(dim):
            d = q[i, a] - anchor[k, a]
            G[k, a] = d * param[k, a]
            s += d * d * param[k, a]
        return 0.5 * (s - 1.0)
    return np.nan


@llvm_inlined
def constraint_rate(k, v, ends, kind, param, G):
    """(J̇q̇, Ċ) of constraint k with g = G[k] already set by :func:`constraint_value`.

    J̇q̇ = ḋᵀ (∂²C/∂d²) ḋ and Ċ = g·ḋ, with ḋ = vᵢ − vⱼ (a fixed end does not move).
    """
    i, j = ends[k, 0], ends[k, 1]
    dim = _dim(v)
    jdot = 0.0
    rate = 0.0
    if kind[k] == DISTANCE:
        for a in range(dim):
            dd = v[i, a] - (v[j, a] if j >= 0 else 0.0)
            jdot += dd * dd
            rate += G[k, a] * dd
    elif kind[k] == LINE:  # a straight line does not turn: J̇q̇ = 0
        for a in range(dim):
            rate += G[k, a] * v[i, a]
    elif kind[k] == ELLIPSE:
        for a in range(dim):
            jdot += param[k, a] * v[i, a] * v[i, a]
            rate += G[k, a] * v[i, a]
    return jdot, rate


@compiled
def assemble(G, pair_k, pair_l, pair_w, band):
    """The lower band of J W Jᵀ from the gradients G (C, dim)."""
    dim = _dim(G)
    for k in range(_constraints(band)):
        for j in range(_band_columns(band)):
            band[k, j] = 0.0
    for n in range(_pairs(pair_k)):
        k, l = pair_k[n], pair_l[n]
        s = 0.0
        for a in range(dim):
            s += G[k, a] * G[l, a]
        band[k, k - l] += pair_w[n] * s


@compiled
def solve_jwjt(G, model, band, x):
    """x ← (J W Jᵀ)⁻¹ x in place, J from the gradients G; False when J W Jᵀ is not positive definite.

    By Cholesky on the band, or in closed form (Cramer's rule) when the kernel is specialised for
    at most 3 constraints (``_closed_form``): no square roots, one division."""
    n, bandwidth = _constraints(band), _band_columns(band) - 1
    assemble(G, model[7], model[8], model[9], band)
    if _closed_form(band):
        return solve_closed(band, n, bandwidth, x)
    if not cholesky_banded(band, n, bandwidth):
        return False
    solve_banded(band, n, bandwidth, x)
    return True


@compiled
def _entry(band, bandwidth, k, l):
    """A[k, l] (l ≤ k) of the matrix whose lower band is ``band``; 0 outside the band."""
    return band[k, k - l] if k - l <= bandwidth else 0.0


@compiled
def solve_closed(band, n, bandwidth, x):
    """x ← A⁻¹ x for a symmetric positive-definite A of n ≤ 3 rows (lower band in ``band``), by Cramer's
    rule; False when a leading minor is not positive (where Cholesky would fail). The tests read the real
    parts: the same code serves ours.sensitivity's complex step."""
    a00 = band[0, 0]
    if n == 1:
        if not a00.real > 0.0:
            return False
        x[0] = x[0] / a00
        return True
    a10, a11 = _entry(band, bandwidth, 1, 0), band[1, 0]
    m2 = a00 * a11 - a10 * a10
    if n == 2:
        if not (a00.real > 0.0 and m2.real > 0.0):
            return False
        r0, r1 = x[0], x[1]
        x[0] = (a11 * r0 - a10 * r1) / m2
        x[1] = (a00 * r1 - a10 * r0) / m2
        return True
    a20, a21, a22 = _entry(band, bandwidth, 2, 0), _entry(band, bandwidth, 2, 1), band[2, 0]
    c00 = a11 * a22 - a21 * a21
    c10 = a21 * a20 - a10 * a22
    c20 = a10 * a21 - a11 * a20
    det = a00 * c00 + a10 * c10 + a20 * c20
    if not (a00.real > 0.0 and m2.real > 0.0 and det.real > 0.0):
        return False
    c11 = a00 * a22 - a20 * a20
    c21 = a10 * a20 - a00 * a21
    r0, r1, r2 = x[0], x[1], x[2]
    x[0] = (c00 * r0 + c10 * r1 + c20 * r2) / det
    x[1] = (c10 * r0 + c11 * r1 + c21 * r2) / det
    x[2] = (c20 * r0 + c21 * r1 + m2 * r2) / det
    return True


@compiled
def add_constraint_term(x, scale, inverse_mass, ends, G, lam):
    """x += scale · W Jᵀ λ (per particle: +w_i λ_k g_k on the first end, −w_j λ_k g_k on the second)."""
    dim = _dim(x)
    for k in range(_constraints(ends)):
        i, j = ends[k, 0], ends[k, 1]
        si = scale * inverse_mass[i] * lam[k]
        for a in range(dim):
            x[i, a] += si * G[k, a]
        if j >= 0:
            sj = scale * inverse_mass[j] * lam[k]
            for a in range(dim):
                x[j, a] -= sj * G[k, a]


@llvm_inlined
def multipliers(q, v, model, k_s, k_d, G, band, lam):
    """λ from J W Jᵀ λ = −J̇q̇ − J W f − k_s C − k_d Ċ; False when the matrix is singular.

    G (C, dim) receives the gradients.
    """
    inverse_mass, force, ends = model[0], model[1], model[2]
    dim = _dim(q)
    for k in range(_constraints(ends)):
        c = constraint_value(k, q, ends, model[3], model[4], model[5], G)
        jdot, c_dot = constraint_rate(k, v, ends, model[4], model[5], G)
        i, j = ends[k, 0], ends[k, 1]
        jwf = 0.0
        for a in range(dim):
            # J W f: the unconstrained acceleration's component along the constraint.
            accel = inverse_mass[i] * force[i, a] - (inverse_mass[j] * force[j, a] if j >= 0 else 0.0)
            jwf += G[k, a] * accel
        lam[k] = -jdot - jwf - k_s * c - k_d * c_dot
    return solve_jwjt(G, model, band, lam)


@llvm_inlined
def acceleration(q, v, model, k_s, k_d, G, band, lam, acc):
    """acc = W (f + Jᵀλ), m/s²; False when J W Jᵀ is singular."""
    inverse_mass, force = model[0], model[1]
    ok = multipliers(q, v, model, k_s, k_d, G, band, lam)
    dim = _dim(q)
    for p in range(_particles(q)):
        for a in range(dim):
            acc[p, a] = inverse_mass[p] * force[p, a]
    add_constraint_term(acc, 1.0, inverse_mass, model[2], G, lam)
    return ok


@llvm_inlined
def violations(q, model, G, out):
    """out[k] = C_k at q (G receives the gradients); returns max_k |C_k| / scale_k (≈ relative length error)."""
    ends, scale = model[2], model[6]
    worst = 0.0
    for k in range(_constraints(out)):
        c = constraint_value(k, q, ends, model[3], model[4], model[5], G)
        out[k] = c
        worst = max(worst, abs(c) / scale[k])
    return worst


@llvm_inlined
def project_velocities(q, v, model, G, band, mu):
    """v ← v − W Jᵀ (J W Jᵀ)⁻¹ J v: the nearest velocity (in the mass metric) with J v = 0."""
    velocity_rates(q, v, model, G, mu)
    if not solve_jwjt(G, model, band, mu):
        return False
    add_constraint_term(v, -1.0, model[0], model[2], G, mu)
    return True


@inlined
def velocity_rates(q, v, model, G, mu):
    """mu[k] = Ċ_k = J v (G receives the gradients at q)."""
    ends = model[2]
    for k in range(_constraints(ends)):
        constraint_value(k, q, ends, model[3], model[4], model[5], G)
        mu[k] = constraint_rate(k, v, ends, model[4], model[5], G)[1]


@compiled
def project_positions(q, model, tolerance, max_iterations, G, band, delta):
    """Newton in the mass-weighted metric: q ← q − W Jᵀ (J W Jᵀ)⁻¹ C until max|C|/scale ≤ tolerance.

    Returns OK, SINGULAR or NOT_CONVERGED.
    """
    inverse_mass, ends = model[0], model[2]
    for _ in range(max_iterations + 1):
        if violations(q, model, G, delta) <= tolerance:
            return OK
        if not solve_jwjt(G, model, band, delta):
            return SINGULAR
        add_constraint_term(q, -1.0, inverse_mass, ends, G, delta)
    return NOT_CONVERGED


@llvm_inlined
def rattle_step(q, v, h, model, tolerance, max_iterations, work):
    """One RATTLE step (order 2, symplectic) in place; returns OK, SINGULAR or NOT_CONVERGED.

    Half kick with the old constraint directions, drift, and Λ chosen so that
    C(q_{n+1}) = 0 (SHAKE: a Newton-like iteration with J_n W J_nᵀ, factored once
    per step; it contracts by O((hω)²) per iteration). Then the second half kick
    and v projected so that J(q_{n+1}) v_{n+1} = 0.
    """
    G, band, delta, q_new = work[1], work[2], work[4], work[5]
    if not rattle_begin(q, v, h, model, work):
        return SINGULAR
    converged = False
    for _ in range(max_iterations + 1):
        if violations(q_new, model, G, delta) <= tolerance:
            converged = True
            break
        shake_update(model, work)
    if not converged:
        return NOT_CONVERGED
    rattle_kick(q, v, h, model, work)
    if not project_velocities(q, v, model, G, band, delta):
        return SINGULAR
    return OK


@inlined
def rattle_begin(q, v, h, model, work):
    """RATTLE's start: G0 = the gradients at q_n, J_n W J_nᵀ factored (Cholesky) in the band, the drift
    q_new = q + h v + ½h² W f, Λ = 0; False when J_n W J_nᵀ is not positive definite."""
    inverse_mass, force, ends = model[0], model[1], model[2]
    G0, band, Lam, q_new = work[0], work[2], work[3], work[5]
    C = _constraints(ends)
    for k in range(C):
        constraint_value(k, q, ends, model[3], model[4], model[5], G0)
    assemble(G0, model[7], model[8], model[9], band)
    if not cholesky_banded(band, C, _band_columns(band) - 1):
        return False
    for p in range(_particles(q)):
        for a in range(_dim(q)):
            q_new[p, a] = q[p, a] + h * v[p, a] + 0.5 * h * h * inverse_mass[p] * force[p, a]
    for k in range(C):
        Lam[k] = 0.0
    return True


@inlined
def shake_update(model, work):
    """One SHAKE iteration after :func:`violations` left C(q_new) in delta: delta ← −(J_n W J_nᵀ)⁻¹ C by the
    factor, Λ += delta, q_new += W J_nᵀ delta."""
    G0, band, Lam, delta, q_new = work[0], work[2], work[3], work[4], work[5]
    C = _constraints(model[2])
    for k in range(C):
        delta[k] = -delta[k]
    solve_banded(band, C, _band_columns(band) - 1, delta)
    for k in range(C):
        Lam[k] += delta[k]
    add_constraint_term(q_new, 1.0, model[0], model[2], G0, delta)


@inlined
def rattle_kick(q, v, h, model, work):
    """v_{n+1/2} = v_n + h/2 W f + W J_nᵀ Λ / h, then the second half kick with f; q ← q_new."""
    inverse_mass, force = model[0], model[1]
    G0, Lam, q_new = work[0], work[3], work[5]
    for p in range(_particles(q)):
        for a in range(_dim(q)):
            v[p, a] += h * inverse_mass[p] * force[p, a]
    add_constraint_term(v, 1.0 / h, inverse_mass, model[2], G0, Lam)
    _copy(q, q_new)


@compiled
def _copy(y, x):
    """y[...] = x for (P, dim) arrays (slice assignment may allocate a temporary)."""
    dim = _dim(y)
    for p in range(_particles(y)):
        for a in range(dim):
            y[p, a] = x[p, a]


@compiled
def _finite(x):
    """True when every entry of the (P, dim) array is finite."""
    dim = _dim(x)
    for p in range(_particles(x)):
        for a in range(dim):
            if not math.isfinite(x[p, a]):
                return False
    return True


@compiled
def _record(q, v, model, k_s, k_d, G, band, sample_q, sample_v, sample_lam):
    """One sample: q, v into sample_q, sample_v (P, dim) and λ into sample_lam (C,) (NaN when singular).

    Given the sample's rows rather than their index: a call with a constant index (the first
    sample's 0) made numba compile a copy of this function, multipliers and all, for each constant.
    """
    dim = _dim(q)
    for p in range(_particles(q)):
        for a in range(dim):
            sample_q[p, a] = q[p, a]
            sample_v[p, a] = v[p, a]
    if not multipliers(q, v, model, k_s, k_d, G, band, sample_lam):
        for k in range(sample_lam.shape[0]):
            sample_lam[k] = np.nan


@compiled
def _axpy(y, x, alpha, s):
    """y = x + alpha · s (all (P, dim))."""
    dim = _dim(y)
    for p in range(_particles(y)):
        for a in range(dim):
            y[p, a] = x[p, a] + alpha * s[p, a]


@compiled
def rk_step(A, b, h, q, v, model, ks, kd, G, band, lam, Kq, Kv, qs, vs):
    """One explicit Runge–Kutta step with the table (A, b) in place; False when J W Jᵀ was singular.

    Stage i: qs = q + h Σ_j A_ij Kq_j, vs = v + h Σ_j A_ij Kv_j (terms added in
    order of j, zero entries skipped), Kq_i = vs, Kv_i = acceleration(qs, vs).
    Then q += h Σ_i b_i Kq_i and v += h Σ_i b_i Kv_i.
    """
    ok = True
    for i in range(b.shape[0]):
        rk_stage(A, h, i, q, v, Kq, Kv, qs, vs)
        if not acceleration(qs, vs, model, ks, kd, G, band, lam, Kv[i]):
            ok = False
    rk_combine(b, h, q, v, Kq, Kv)
    return ok


@inlined
def rk_stage(A, h, i, q, v, Kq, Kv, qs, vs):
    """Stage i's state: qs = q + h Σ_j A_ij Kq_j, vs = v + h Σ_j A_ij Kv_j (terms added in order of j, zero
    entries skipped), and Kq_i = vs."""
    _copy(qs, q)
    _copy(vs, v)
    for j in range(i):
        if A[i, j] != 0.0:
            _axpy(qs, qs, h * A[i, j], Kq[j])
            _axpy(vs, vs, h * A[i, j], Kv[j])
    _copy(Kq[i], vs)


@inlined
def rk_combine(b, h, q, v, Kq, Kv):
    """q += h Σ_i b_i Kq_i and v += h Σ_i b_i Kv_i (in order of i, zero weights skipped)."""
    for i in range(b.shape[0]):
        if b[i] != 0.0:
            _axpy(q, q, h * b[i], Kq[i])
            _axpy(v, v, h * b[i], Kv[i])


@llvm_inlined
def _feedback(method, k_s, k_d):
    """(k_s, k_d) the step applies: only baumgarte feeds C and Ċ back (its λ at a sample includes the
    feedback it applied); 0 for the other methods."""
    if method == _BAUMGARTE:
        return k_s, k_d
    return 0.0, 0.0


@llvm_inlined
def step_once(method, integrator, A, b, h, q, v, model, work, ks, kd, tolerance, max_iterations):
    """One step of the integrator and the cure in place (ks, kd: the Baumgarte gains, 0 for other methods);
    returns OK, SINGULAR or NOT_CONVERGED."""
    G, band, lam, Kq, Kv, qs, vs, rattle_work = work
    status = OK
    if integrator == _RATTLE:
        status = rattle_step(q, v, h, model, tolerance, max_iterations, rattle_work)
    elif integrator == _SYMPLECTIC_EULER:
        if not acceleration(q, v, model, ks, kd, G, band, lam, Kv[0]):
            status = SINGULAR
        for p in range(_particles(q)):
            for a in range(_dim(q)):
                v[p, a] = v[p, a] + h * Kv[0, p, a]
                q[p, a] = q[p, a] + h * v[p, a]
    elif not rk_step(A, b, h, q, v, model, ks, kd, G, band, lam, Kq, Kv, qs, vs):
        status = SINGULAR
    if status == OK and method == _PROJECTION:
        status = project_positions(q, model, tolerance, max_iterations, G, band, lam)
        if status == OK and not project_velocities(q, v, model, G, band, lam):
            status = SINGULAR
    return status


@compiled
def run(method, integrator, A, b, q, v, model, work, k_s, k_d, dt, n_steps, stride, tolerance, max_iterations,
        out_q, out_v, out_lam):
    """Step the system ``n_steps`` times from (q, v) (modified in place), recording every ``stride`` steps
    and the last one into out_q / out_v (S, P, dim) and out_lam (S, C).

    method, integrator : codes from ours.method / ours.integrator. A (s, s), b (s,) : Butcher table.
    work : the arrays of :func:`workspace`. Returns (samples written, steps taken, status).
    """
    G, band = work[0], work[1]
    ks, kd = _feedback(method, k_s, k_d)
    h = dt

    _record(q, v, model, ks, kd, G, band, out_q[0], out_v[0], out_lam[0])
    n = 1
    status = OK
    step = 0
    while step < n_steps:
        status = step_once(method, integrator, A, b, h, q, v, model, work, ks, kd, tolerance, max_iterations)
        step += 1
        if status != OK:
            if not (_finite(q) and _finite(v)):
                status = NON_FINITE
            break
        if step % stride == 0 or step == n_steps:
            if not (_finite(q) and _finite(v)):
                status = NON_FINITE
                break
            _record(q, v, model, ks, kd, G, band, out_q[n], out_v[n], out_lam[n])
            n += 1
    return n, step, status


@compiled
def run_perturbed(method, integrator, A, b, q, v, model, work, k_s, k_d, dt, n_steps, tolerance, max_iterations):
    """:func:`run`'s steps without its samples, on complex (q, v) (P, dim) in place, for a complex step
    (ours.sensitivity): the same step functions, whose real parts are the real run's bit for bit, so every
    branch (a singular matrix, a Newton iteration's stop) goes as it does there. ``work`` : :func:`workspace`
    in complex128. Returns (steps taken, status); a non-finite state is left to the caller to find.
    """
    ks, kd = _feedback(method, k_s, k_d)
    for step in range(n_steps):
        status = step_once(method, integrator, A, b, dt, q, v, model, work, ks, kd, tolerance, max_iterations)
        if status != OK:
            return step + 1, status
    return n_steps, OK


@compiled
def sample_gradients(out_q, model, out_G):
    """out_G[s, k] = ∂C_k/∂d at the sample out_q[s] (S, P, dim) → (S, C, dim); the force on the first
    particle of constraint k is λ_k g_k."""
    for s in range(out_q.shape[0]):
        for k in range(out_G.shape[1]):
            constraint_value(k, out_q[s], model[2], model[3], model[4], model[5], out_G[s])


@compiled
def sample_multipliers(out_q, out_v, model, G, band, out_lam):
    """out_lam[s] = λ at the sample (out_q[s], out_v[s]) with no Baumgarte feedback (NaN where
    J W Jᵀ is singular): the constraint forces of a motion stepped elsewhere (``ours.lagrangian``)."""
    for s in range(out_q.shape[0]):
        if not multipliers(out_q[s], out_v[s], model, 0.0, 0.0, G, band, out_lam[s]):
            for k in range(out_lam.shape[1]):
                out_lam[s, k] = np.nan
