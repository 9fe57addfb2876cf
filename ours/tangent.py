"""The tangent-linear step: ``ours.kernel``'s step with n directions carried beside it.

The real step is computed once, with the kernel's own functions (its state is ``run``'s bit for bit); each
direction pays only for its derivative, every solve with J W Jᵀ reusing the step's factorisation:
dλ = (J W Jᵀ)⁻¹ (dr − d(J W Jᵀ) λ). A direction moves the state (dq, dv) and, for g, masses and lengths, the
model's arrays (``dmodel``). Not run as it stands: ``ours.specialize.tangent_for`` appends what follows the
TANGENT line to a specialised copy of the kernel; the imports are for reading and checking.

Shapes: n directions, P particles, C constraints, N band entries. dq, dv : (n, P, dim); dmodel :
(d_inverse_mass (n, P), d_force (n, P, dim), d_anchor (n, C, dim), d_param (n, C, m), d_pair_w (n, N)).

Details: docs/ours.md, "Module notes", ``ours/tangent.py``.
"""

from __future__ import annotations

import numpy as np

from ours.banded import cholesky_banded, compiled, llvm_inlined, solve_banded
from ours.constraint import DISTANCE, ELLIPSE, LINE
from ours.kernel import (rk_stage, velocity_rates, _PROJECTION, _RATTLE, _SYMPLECTIC_EULER, _axpy, _band_columns, _closed_form, _constraints,
                         _copy, _entry, _dim, _feedback, _pairs, _particles, acceleration, add_constraint_term, assemble,
                         constraint_value, solve_jwjt, violations)
from ours.status import NOT_CONVERGED, OK, SINGULAR

# ---- TANGENT (ours.specialize appends what follows to the kernel's text) ----


def tangent_workspace(n: int, P: int, C: int, dim: int, stages: int) -> tuple:
    """Scratch of :func:`run_tangent` for n directions (allocated here: the compiled code has no allocator)."""

    def z(shape):
        return np.zeros(shape)

    # The inverse of J W Jᵀ where the kernel solves it in closed form (at most 3 constraints), else the
    # reciprocals of its Cholesky factor's diagonal (one column): ``prepare_solves``.
    inverse = z((C, C if C <= 3 else 1))
    return (z((n, C, dim)), z((n, C)), z((stages, n, P, dim)), z((stages, n, P, dim)), z((P, dim)), z((P, dim)),
            z((n, C, dim)), z((n, P, dim)), z((n, C)), inverse)


@llvm_inlined
def constraint_value_tangent(k, q, dq, ends, anchor, kind, param, d_anchor, d_param, G, dG):
    """dC_k along one direction (dq (P, dim), d_anchor, d_param); writes dg into dG[k]. G[k] : g at q, set by
    :func:`constraint_value`. The derivative of each closed form there, term by term."""
    i, j = ends[k, 0], ends[k, 1]
    dim = _dim(q)
    if kind[k] == DISTANCE:  # dC = g·dd − ½ d(l²), dg = dd (d = xᵢ − the other end)
        s = -0.5 * d_param[k, 0]
        for a in range(dim):
            dG[k, a] = dq[i, a] - (dq[j, a] if j >= 0 else d_anchor[k, a])
            s += G[k, a] * dG[k, a]
        return s
    if kind[k] == LINE:
        s = 0.0
        for a in range(dim):
            dG[k, a] = d_param[k, a]
            s += d_param[k, a] * (q[i, a] - anchor[k, a]) + param[k, a] * (dq[i, a] - d_anchor[k, a])
        return s
    if kind[k] == ELLIPSE:
        s = 0.0
        for a in range(dim):
            d = q[i, a] - anchor[k, a]
            dd = dq[i, a] - d_anchor[k, a]
            dG[k, a] = dd * param[k, a] + d * d_param[k, a]
            s += d * dd * param[k, a] + 0.5 * d * d * d_param[k, a]
        return s
    return np.nan


@llvm_inlined
def constraint_rate_tangent(k, v, dv, ends, kind, param, d_param, G, dG):
    """(d J̇q̇, d Ċ) of constraint k along one direction, with G[k], dG[k] set."""
    i, j = ends[k, 0], ends[k, 1]
    djdot, drate = 0.0, 0.0
    if kind[k] == DISTANCE:  # J̇q̇ = ‖ḋ‖², Ċ = g·ḋ: their derivatives along (dḋ, dg)
        for a in range(_dim(v)):
            rel = v[i, a] - (v[j, a] if j >= 0 else 0.0)
            d_rel = dv[i, a] - (dv[j, a] if j >= 0 else 0.0)
            djdot += 2.0 * rel * d_rel
            drate += dG[k, a] * rel + G[k, a] * d_rel
    elif kind[k] == LINE:
        for a in range(_dim(v)):
            drate += dG[k, a] * v[i, a] + G[k, a] * dv[i, a]
    elif kind[k] == ELLIPSE:
        for a in range(_dim(v)):
            djdot += d_param[k, a] * v[i, a] * v[i, a] + 2.0 * param[k, a] * v[i, a] * dv[i, a]
            drate += dG[k, a] * v[i, a] + G[k, a] * dv[i, a]
    return djdot, drate


@llvm_inlined
def subtract_matrix_tangent(G, dG, pair_k, pair_l, pair_w, d_pair_w, lam, out):
    """out −= d(J W Jᵀ) λ: the band's entries (k, l) = pair_w · g_k·g_l, differentiated along (dG, d_pair_w)."""
    dim = _dim(G)
    for n in range(_pairs(pair_k)):
        k, l = pair_k[n], pair_l[n]
        s = 0.0
        ds = 0.0
        for a in range(dim):
            s += G[k, a] * G[l, a]
            ds += dG[k, a] * G[l, a] + G[k, a] * dG[l, a]
        entry = pair_w[n] * ds + d_pair_w[n] * s
        out[k] -= entry * lam[l]
        if l != k:
            out[l] -= entry * lam[k]


@llvm_inlined
def reciprocals(band, n, inverse):
    """inverse[i, 0] ← 1 / L[i, i] of the Cholesky factor in ``band``: every direction's solve then multiplies."""
    for i in range(n):
        # A failed factorisation (the step then stops as singular) may leave a zero: no division by it.
        inverse[i, 0] = 1.0 / band[i, 0] if band[i, 0] != 0.0 else np.nan


@llvm_inlined
def solve_factored(band, n, b, inverse, x):
    """x ← (L Lᵀ)⁻¹ x with L in ``band`` (bandwidth b) and its diagonal's reciprocals in inverse[:, 0]
    (``ours.banded.solve_banded`` with the divisions done once per factorisation)."""
    for i in range(n):
        s = x[i]
        for k in range(max(0, i - b), i):
            s -= band[i, i - k] * x[k]
        x[i] = s * inverse[i, 0]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, min(n, i + b + 1)):
            s -= band[k, k - i] * x[k]
        x[i] = s * inverse[i, 0]


@llvm_inlined
def prepare_solves(band, inverse):
    """After :func:`solve_jwjt` left ``band``: what :func:`resolve_jwjt` needs, computed once for every direction:
    the inverse of J W Jᵀ (n ≤ 3, the closed form, which keeps the matrix in ``band``: inverse (n, n)), or the
    reciprocals of its Cholesky factor's diagonal (inverse[:, 0])."""
    n, bandwidth = _constraints(band), _band_columns(band) - 1
    if not _closed_form(band):
        reciprocals(band, n, inverse)
        return
    a00 = band[0, 0]
    if n == 1:
        inverse[0, 0] = 1.0 / a00 if a00 != 0.0 else np.nan
        return
    a10, a11 = _entry(band, bandwidth, 1, 0), band[1, 0]
    if n == 2:
        m2 = a00 * a11 - a10 * a10
        r = 1.0 / m2 if m2 != 0.0 else np.nan  # singular: the step stops there (solve_closed said so)
        inverse[0, 0], inverse[0, 1], inverse[1, 1] = a11 * r, -a10 * r, a00 * r
        inverse[1, 0] = inverse[0, 1]
        return
    a20, a21, a22 = _entry(band, bandwidth, 2, 0), _entry(band, bandwidth, 2, 1), band[2, 0]
    c00 = a11 * a22 - a21 * a21
    c10 = a21 * a20 - a10 * a22
    c20 = a10 * a21 - a11 * a20
    det = a00 * c00 + a10 * c10 + a20 * c20
    r = 1.0 / det if det != 0.0 else np.nan
    inverse[0, 0], inverse[1, 0], inverse[2, 0] = c00 * r, c10 * r, c20 * r
    inverse[1, 1], inverse[2, 1], inverse[2, 2] = (a00 * a22 - a20 * a20) * r, (a10 * a20 - a00 * a21) * r, \
        (a00 * a11 - a10 * a10) * r
    inverse[0, 1], inverse[0, 2], inverse[1, 2] = inverse[1, 0], inverse[2, 0], inverse[2, 1]


@llvm_inlined
def resolve_jwjt(band, inverse, x):
    """x ← (J W Jᵀ)⁻¹ x with ``band`` as :func:`solve_jwjt` left it and ``inverse`` from :func:`prepare_solves`:
    no second factorisation, and no division."""
    n, bandwidth = _constraints(band), _band_columns(band) - 1
    if not _closed_form(band):
        solve_factored(band, n, bandwidth, inverse, x)
    elif n == 1:
        x[0] = inverse[0, 0] * x[0]
    elif n == 2:
        r0, r1 = x[0], x[1]
        x[0] = inverse[0, 0] * r0 + inverse[0, 1] * r1
        x[1] = inverse[1, 0] * r0 + inverse[1, 1] * r1
    else:
        r0, r1, r2 = x[0], x[1], x[2]
        x[0] = inverse[0, 0] * r0 + inverse[0, 1] * r1 + inverse[0, 2] * r2
        x[1] = inverse[1, 0] * r0 + inverse[1, 1] * r1 + inverse[1, 2] * r2
        x[2] = inverse[2, 0] * r0 + inverse[2, 1] * r1 + inverse[2, 2] * r2


@llvm_inlined
def add_constraint_term_tangent(x, scale, inverse_mass, d_inverse_mass, ends, G, dG, lam, dlam):
    """x += scale · d(W Jᵀ λ) along one direction (the derivative of :func:`add_constraint_term`)."""
    dim = _dim(x)
    for k in range(_constraints(ends)):
        i, j = ends[k, 0], ends[k, 1]
        wi = scale * inverse_mass[i]
        dwi = scale * (d_inverse_mass[i] * lam[k] + inverse_mass[i] * dlam[k])
        for a in range(dim):
            x[i, a] += dwi * G[k, a] + wi * lam[k] * dG[k, a]
        if j >= 0:
            wj = scale * inverse_mass[j]
            dwj = scale * (d_inverse_mass[j] * lam[k] + inverse_mass[j] * dlam[k])
            for a in range(dim):
                x[j, a] -= dwj * G[k, a] + wj * lam[k] * dG[k, a]


@llvm_inlined
def acceleration_tangent(q, v, dq, dv, model, dmodel, moving, d, k_s, k_d, G, band, inverse, lam, dG, dlam, dacc):
    """dacc (P, dim) = d[W (f + Jᵀλ)] along direction d, after :func:`acceleration` at (q, v) left G, λ and
    the factor of J W Jᵀ (``inverse`` from :func:`prepare_solves`); dG (C, dim), dlam (C,) : this direction's
    scratch. ``moving`` : whether the model moves along any direction (else its terms, all zero, are skipped)."""
    inverse_mass, force, ends, anchor, kind, param = model[0], model[1], model[2], model[3], model[4], model[5]
    d_inverse_mass, d_force, d_anchor, d_param = dmodel[0][d], dmodel[1][d], dmodel[2][d], dmodel[3][d]
    dim = _dim(q)
    for k in range(_constraints(ends)):
        dc = constraint_value_tangent(k, q, dq, ends, anchor, kind, param, d_anchor, d_param, G, dG)
        djdot, dc_dot = constraint_rate_tangent(k, v, dv, ends, kind, param, d_param, G, dG)
        i, j = ends[k, 0], ends[k, 1]
        djwf = 0.0
        for a in range(dim):
            accel = inverse_mass[i] * force[i, a] - (inverse_mass[j] * force[j, a] if j >= 0 else 0.0)
            djwf += dG[k, a] * accel
            if moving:
                daccel = d_inverse_mass[i] * force[i, a] + inverse_mass[i] * d_force[i, a]
                if j >= 0:
                    daccel -= d_inverse_mass[j] * force[j, a] + inverse_mass[j] * d_force[j, a]
                djwf += G[k, a] * daccel
        dlam[k] = -djdot - djwf - k_s * dc - k_d * dc_dot
    subtract_matrix_tangent(G, dG, model[7], model[8], model[9], dmodel[4][d], lam, dlam)
    resolve_jwjt(band, inverse, dlam)
    for p in range(_particles(q)):
        for a in range(dim):
            dacc[p, a] = d_inverse_mass[p] * force[p, a] + inverse_mass[p] * d_force[p, a] if moving else 0.0
    add_constraint_term_tangent(dacc, 1.0, inverse_mass, d_inverse_mass, ends, G, dG, lam, dlam)


@llvm_inlined
def rk_step_tangent(A, b, h, q, v, model, ks, kd, G, band, lam, Kq, Kv, qs, vs, dq, dv, dmodel, moving, tangent_work):
    """:func:`rk_step` (the same operations in the same order) and its derivative along every direction."""
    dG, dlam, dKq, dKv, dqs, dvs = (tangent_work[0], tangent_work[1], tangent_work[2], tangent_work[3],
                                    tangent_work[4], tangent_work[5])
    inverse = tangent_work[9]
    ok = True
    for i in range(b.shape[0]):
        rk_stage(A, h, i, q, v, Kq, Kv, qs, vs)
        if not acceleration(qs, vs, model, ks, kd, G, band, lam, Kv[i]):
            ok = False
        prepare_solves(band, inverse)
        for d in range(dq.shape[0]):
            _copy(dqs, dq[d])
            _copy(dvs, dv[d])
            for j in range(i):
                if A[i, j] != 0.0:
                    _axpy(dqs, dqs, h * A[i, j], dKq[j, d])
                    _axpy(dvs, dvs, h * A[i, j], dKv[j, d])
            _copy(dKq[i, d], dvs)
            acceleration_tangent(qs, vs, dqs, dvs, model, dmodel, moving, d, ks, kd, G, band, inverse, lam, dG[d],
                                 dlam[d], dKv[i, d])
    for i in range(b.shape[0]):
        if b[i] != 0.0:
            _axpy(q, q, h * b[i], Kq[i])
            _axpy(v, v, h * b[i], Kv[i])
            for d in range(dq.shape[0]):
                _axpy(dq[d], dq[d], h * b[i], dKq[i, d])
                _axpy(dv[d], dv[d], h * b[i], dKv[i, d])
    return ok


@llvm_inlined
def correct_directions(model, dmodel, G, dG, band, inverse, x, dx, target):
    """After x ← (J W Jᵀ)⁻¹ x (its right side's derivative in dx (n, C)): dx ← its solution's derivative, by the
    same factor, and target (n, P, dim) −= d(W Jᵀ x) along every direction."""
    prepare_solves(band, inverse)
    for d in range(dx.shape[0]):
        subtract_matrix_tangent(G, dG[d], model[7], model[8], model[9], dmodel[4][d], x, dx[d])
        resolve_jwjt(band, inverse, dx[d])
        add_constraint_term_tangent(target[d], -1.0, model[0], dmodel[0][d], model[2], G, dG[d], x, dx[d])


@llvm_inlined
def project_positions_tangent(q, model, tolerance, max_iterations, G, band, delta, dq, dmodel, dG, ddelta, inverse):
    """:func:`project_positions` and the derivative of each Newton iterate along every direction."""
    inverse_mass, ends = model[0], model[2]
    for _ in range(max_iterations + 1):
        if violations(q, model, G, delta) <= tolerance:
            return OK
        for d in range(dq.shape[0]):
            for k in range(_constraints(ends)):
                ddelta[d, k] = constraint_value_tangent(k, q, dq[d], ends, model[3], model[4], model[5],
                                                        dmodel[2][d], dmodel[3][d], G, dG[d])
        if not solve_jwjt(G, model, band, delta):
            return SINGULAR
        correct_directions(model, dmodel, G, dG, band, inverse, delta, ddelta, dq)
        add_constraint_term(q, -1.0, inverse_mass, ends, G, delta)
    return NOT_CONVERGED


@llvm_inlined
def project_velocities_tangent(q, v, model, G, band, mu, dq, dv, dmodel, dG, dmu, inverse):
    """:func:`project_velocities` and its derivative along every direction."""
    inverse_mass, ends = model[0], model[2]
    velocity_rates(q, v, model, G, mu)
    for d in range(dq.shape[0]):
        for k in range(_constraints(ends)):
            constraint_value_tangent(k, q, dq[d], ends, model[3], model[4], model[5], dmodel[2][d], dmodel[3][d],
                                     G, dG[d])
            dmu[d, k] = constraint_rate_tangent(k, v, dv[d], ends, model[4], model[5], dmodel[3][d], G, dG[d])[1]
    if solve_jwjt(G, model, band, mu):
        correct_directions(model, dmodel, G, dG, band, inverse, mu, dmu, dv)
        add_constraint_term(v, -1.0, inverse_mass, ends, G, mu)
        return True
    return False


@llvm_inlined
def rattle_step_tangent(q, v, h, model, tolerance, max_iterations, work, dq, dv, dmodel, moving, tangent_work):
    """:func:`rattle_step` and the derivative of its SHAKE iterates and projection along every direction; the
    Cholesky factor of J_n W J_nᵀ serves every direction's solve as it serves every iteration."""
    inverse_mass, force, ends = model[0], model[1], model[2]
    pair_k, pair_l, pair_w = model[7], model[8], model[9]
    G0, G, band, Lam, delta, q_new = work
    dG, ddelta, dG0, dq_new, dLam = tangent_work[0], tangent_work[1], tangent_work[6], tangent_work[7], tangent_work[8]
    inverse = tangent_work[9]
    n = dq.shape[0]
    P = _particles(q)
    dim = _dim(q)
    C = _constraints(ends)
    for k in range(C):
        constraint_value(k, q, ends, model[3], model[4], model[5], G0)
    for d in range(n):
        for k in range(C):
            constraint_value_tangent(k, q, dq[d], ends, model[3], model[4], model[5], dmodel[2][d], dmodel[3][d],
                                     G0, dG0[d])
    bandwidth = _band_columns(band) - 1
    assemble(G0, pair_k, pair_l, pair_w, band)
    if not cholesky_banded(band, C, bandwidth):
        return SINGULAR
    reciprocals(band, C, inverse)
    for p in range(P):
        for a in range(dim):
            q_new[p, a] = q[p, a] + h * v[p, a] + 0.5 * h * h * inverse_mass[p] * force[p, a]
    for d in range(n):
        for p in range(P):
            for a in range(dim):
                dq_new[d, p, a] = dq[d, p, a] + h * dv[d, p, a]
                if moving:
                    dq_new[d, p, a] += 0.5 * h * h * (dmodel[0][d][p] * force[p, a] + inverse_mass[p] * dmodel[1][d][p, a])
        for k in range(C):
            dLam[d, k] = 0.0
    for k in range(C):
        Lam[k] = 0.0
    converged = False
    for _ in range(max_iterations + 1):
        if violations(q_new, model, G, delta) <= tolerance:
            converged = True
            break
        for d in range(n):
            for k in range(C):
                ddelta[d, k] = -constraint_value_tangent(k, q_new, dq_new[d], ends, model[3], model[4], model[5],
                                                         dmodel[2][d], dmodel[3][d], G, dG[d])
        for k in range(C):
            delta[k] = -delta[k]
        solve_banded(band, C, bandwidth, delta)
        for d in range(n):
            subtract_matrix_tangent(G0, dG0[d], pair_k, pair_l, pair_w, dmodel[4][d], delta, ddelta[d])
            solve_factored(band, C, bandwidth, inverse, ddelta[d])
            for k in range(C):
                dLam[d, k] += ddelta[d, k]
            add_constraint_term_tangent(dq_new[d], 1.0, inverse_mass, dmodel[0][d], ends, G0, dG0[d], delta,
                                        ddelta[d])
        for k in range(C):
            Lam[k] += delta[k]
        add_constraint_term(q_new, 1.0, inverse_mass, ends, G0, delta)
    if not converged:
        return NOT_CONVERGED
    for p in range(P):
        for a in range(dim):
            v[p, a] += h * inverse_mass[p] * force[p, a]
    add_constraint_term(v, 1.0 / h, inverse_mass, ends, G0, Lam)
    for d in range(n):
        if moving:
            for p in range(P):
                for a in range(dim):
                    dv[d, p, a] += h * (dmodel[0][d][p] * force[p, a] + inverse_mass[p] * dmodel[1][d][p, a])
        add_constraint_term_tangent(dv[d], 1.0 / h, inverse_mass, dmodel[0][d], ends, G0, dG0[d], Lam, dLam[d])
        _copy(dq[d], dq_new[d])
    _copy(q, q_new)
    if not project_velocities_tangent(q, v, model, G, band, delta, dq, dv, dmodel, dG, ddelta, inverse):
        return SINGULAR
    return OK


@llvm_inlined
def step_once_tangent(method, integrator, A, b, h, q, v, model, work, ks, kd, tolerance, max_iterations, dq, dv,
                      dmodel, moving, tangent_work):
    """:func:`step_once` and its derivative along every direction; returns OK, SINGULAR or NOT_CONVERGED."""
    G, band, lam, Kq, Kv, qs, vs, rattle_work = work
    dG, dlam, dKv, inverse = tangent_work[0], tangent_work[1], tangent_work[3], tangent_work[9]
    status = OK
    if integrator == _RATTLE:
        status = rattle_step_tangent(q, v, h, model, tolerance, max_iterations, rattle_work, dq, dv, dmodel, moving,
                                     tangent_work)
    elif integrator == _SYMPLECTIC_EULER:
        if not acceleration(q, v, model, ks, kd, G, band, lam, Kv[0]):
            status = SINGULAR
        prepare_solves(band, inverse)
        for d in range(dq.shape[0]):
            acceleration_tangent(q, v, dq[d], dv[d], model, dmodel, moving, d, ks, kd, G, band, inverse, lam, dG[d],
                                 dlam[d], dKv[0, d])
        for p in range(_particles(q)):
            for a in range(_dim(q)):
                v[p, a] = v[p, a] + h * Kv[0, p, a]
                q[p, a] = q[p, a] + h * v[p, a]
        for d in range(dq.shape[0]):
            for p in range(_particles(q)):
                for a in range(_dim(q)):
                    dv[d, p, a] = dv[d, p, a] + h * dKv[0, d, p, a]
                    dq[d, p, a] = dq[d, p, a] + h * dv[d, p, a]
    elif not rk_step_tangent(A, b, h, q, v, model, ks, kd, G, band, lam, Kq, Kv, qs, vs, dq, dv, dmodel, moving,
                             tangent_work):
        status = SINGULAR
    if status == OK and method == _PROJECTION:
        status = project_positions_tangent(q, model, tolerance, max_iterations, G, band, lam, dq, dmodel, dG, dlam,
                                           inverse)
        if status == OK and not project_velocities_tangent(q, v, model, G, band, lam, dq, dv, dmodel, dG, dlam,
                                                           inverse):
            status = SINGULAR
    return status


@compiled
def run_tangent(method, integrator, A, b, q, v, model, work, k_s, k_d, dt, n_steps, tolerance, max_iterations,
                dq, dv, dmodel, moving, tangent_work):
    """:func:`run`'s steps without its samples on (q, v) (P, dim) in place, with the directions dq, dv
    (n, P, dim) carried along in place (``dmodel``: the model's derivative along each; ``moving``: whether it is
    anywhere nonzero). Returns (steps taken,
    status); a non-finite state is left to the caller to find."""
    ks, kd = _feedback(method, k_s, k_d)
    for step in range(n_steps):
        status = step_once_tangent(method, integrator, A, b, dt, q, v, model, work, ks, kd, tolerance,
                                   max_iterations, dq, dv, dmodel, moving, tangent_work)
        if status != OK:
            return step + 1, status
    return n_steps, OK
