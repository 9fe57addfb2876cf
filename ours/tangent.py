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

from ours.banded import compiled, llvm_inlined, solve_banded
from ours.constraint import DISTANCE, ELLIPSE, LINE
from ours.kernel import (_PROJECTION, _RATTLE, _SYMPLECTIC_EULER, _axpy, _band_columns, _closed_form, _constraints,
                         _copy, _dim, _entry, _feedback, _pairs, _particles, acceleration, add_constraint_term,
                         rattle_begin, rattle_kick, rk_combine, rk_stage, shake_update, solve_jwjt,
                         velocity_rates, violations)
from ours.status import NOT_CONVERGED, OK, SINGULAR

# ---- TANGENT (ours.specialize appends what follows to the kernel's text) ----


def tangent_workspace(n: int, P: int, C: int, dim: int, stages: int) -> tuple:
    """Scratch of :func:`run_tangent` for n directions (allocated here: the compiled code has no allocator)."""

    def z(shape):
        return np.zeros(shape)

    # The inverse of J W Jᵀ where the kernel solves it in closed form (at most 3 constraints): ``prepare_solves``.
    inverse = z((C, C) if C <= 3 else (0, 0))
    return (z((n, C, dim)), z((n, C)), z((n, stages, P, dim)), z((n, stages, P, dim)), z((P, dim)), z((P, dim)),
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
def prepare_solves(band, inverse):
    """After :func:`solve_jwjt` left ``band``: for the closed form (n ≤ 3, which keeps the matrix in ``band``) its
    inverse (n, n), computed once for every direction; nothing for Cholesky, whose factor serves as it is."""
    n, bandwidth = _constraints(band), _band_columns(band) - 1
    if not _closed_form(band):
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
    no second factorisation."""
    n, bandwidth = _constraints(band), _band_columns(band) - 1
    if not _closed_form(band):
        solve_banded(band, n, bandwidth, x)
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
    """:func:`rk_step` (its stages, in its order) and its derivative along every direction."""
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
            rk_stage(A, h, i, dq[d], dv[d], dKq[d], dKv[d], dqs, dvs)
            acceleration_tangent(qs, vs, dqs, dvs, model, dmodel, moving, d, ks, kd, G, band, inverse, lam, dG[d],
                                 dlam[d], dKv[d, i])
    rk_combine(b, h, q, v, Kq, Kv)
    for d in range(dq.shape[0]):
        rk_combine(b, h, dq[d], dv[d], dKq[d], dKv[d])
    return ok


@llvm_inlined
def step_back(model, dmodel, G, dG, band, inverse, x, dx, y, dy):
    """y −= W Jᵀ (J W Jᵀ)⁻¹ x (x solved in place), and along every direction d, dy[d] −= its derivative, with
    dx (n, C) holding x's derivative (solved in place by the same factor); False when J W Jᵀ is singular.
    Projection's Newton iterate (x = C, y = q) and its velocity projection (x = J v, y = v)."""
    if not solve_jwjt(G, model, band, x):
        return False
    prepare_solves(band, inverse)
    for d in range(dx.shape[0]):
        subtract_matrix_tangent(G, dG[d], model[7], model[8], model[9], dmodel[4][d], x, dx[d])
        resolve_jwjt(band, inverse, dx[d])
        add_constraint_term_tangent(dy[d], -1.0, model[0], dmodel[0][d], model[2], G, dG[d], x, dx[d])
    add_constraint_term(y, -1.0, model[0], model[2], G, x)
    return True


@llvm_inlined
def constraint_tangents(q, dq, model, dmodel, G, dG, dc):
    """dc[d, k] = dC_k and dG[d, k] = dg_k along every direction d at q (G : the gradients at q, set)."""
    ends = model[2]
    for d in range(dq.shape[0]):
        for k in range(_constraints(ends)):
            dc[d, k] = constraint_value_tangent(k, q, dq[d], ends, model[3], model[4], model[5], dmodel[2][d],
                                                dmodel[3][d], G, dG[d])


@llvm_inlined
def project_positions_tangent(q, model, tolerance, max_iterations, G, band, delta, dq, dmodel, dG, ddelta, inverse):
    """:func:`project_positions` and the derivative of each Newton iterate along every direction."""
    for _ in range(max_iterations + 1):
        if violations(q, model, G, delta) <= tolerance:
            return OK
        constraint_tangents(q, dq, model, dmodel, G, dG, ddelta)
        if not step_back(model, dmodel, G, dG, band, inverse, delta, ddelta, q, dq):
            return SINGULAR
    return NOT_CONVERGED


@llvm_inlined
def project_velocities_tangent(q, v, model, G, band, mu, dq, dv, dmodel, dG, dmu, inverse):
    """:func:`project_velocities` and its derivative along every direction."""
    ends = model[2]
    velocity_rates(q, v, model, G, mu)
    constraint_tangents(q, dq, model, dmodel, G, dG, dmu)  # for dG; dmu is then the rates'
    for d in range(dq.shape[0]):
        for k in range(_constraints(ends)):
            dmu[d, k] = constraint_rate_tangent(k, v, dv[d], ends, model[4], model[5], dmodel[3][d], G, dG[d])[1]
    return step_back(model, dmodel, G, dG, band, inverse, mu, dmu, v, dv)


@llvm_inlined
def rattle_step_tangent(q, v, h, model, tolerance, max_iterations, work, dq, dv, dmodel, moving, tangent_work):
    """:func:`rattle_step` (its pieces, in its order) and the derivative of its SHAKE iterates and projection along
    every direction; the Cholesky factor of J_n W J_nᵀ serves every direction's solve as it serves every
    iteration."""
    inverse_mass, force, ends = model[0], model[1], model[2]
    G0, G, band, Lam, delta, q_new = work
    dG, ddelta, dG0, dq_new, dLam = tangent_work[0], tangent_work[1], tangent_work[6], tangent_work[7], tangent_work[8]
    n = dq.shape[0]
    C = _constraints(ends)
    bandwidth = _band_columns(band) - 1
    if not rattle_begin(q, v, h, model, work):
        return SINGULAR
    constraint_tangents(q, dq, model, dmodel, G0, dG0, dLam)  # for dG0
    for d in range(n):
        for k in range(C):
            dLam[d, k] = 0.0
        _axpy(dq_new[d], dq[d], h, dv[d])
        if moving:
            for p in range(_particles(q)):
                for a in range(_dim(q)):
                    dq_new[d, p, a] += 0.5 * h * h * (dmodel[0][d][p] * force[p, a]
                                                      + inverse_mass[p] * dmodel[1][d][p, a])
    converged = False
    for _ in range(max_iterations + 1):
        if violations(q_new, model, G, delta) <= tolerance:
            converged = True
            break
        constraint_tangents(q_new, dq_new, model, dmodel, G, dG, ddelta)
        shake_update(model, work)
        for d in range(n):
            for k in range(C):
                ddelta[d, k] = -ddelta[d, k]
            subtract_matrix_tangent(G0, dG0[d], model[7], model[8], model[9], dmodel[4][d], delta, ddelta[d])
            solve_banded(band, C, bandwidth, ddelta[d])
            for k in range(C):
                dLam[d, k] += ddelta[d, k]
            add_constraint_term_tangent(dq_new[d], 1.0, inverse_mass, dmodel[0][d], ends, G0, dG0[d], delta,
                                        ddelta[d])
    if not converged:
        return NOT_CONVERGED
    rattle_kick(q, v, h, model, work)
    for d in range(n):
        if moving:
            for p in range(_particles(q)):
                for a in range(_dim(q)):
                    dv[d, p, a] += h * (dmodel[0][d][p] * force[p, a] + inverse_mass[p] * dmodel[1][d][p, a])
        add_constraint_term_tangent(dv[d], 1.0 / h, inverse_mass, dmodel[0][d], ends, G0, dG0[d], Lam, dLam[d])
        _copy(dq[d], dq_new[d])
    if not project_velocities_tangent(q, v, model, G, band, delta, dq, dv, dmodel, dG, ddelta, tangent_work[9]):
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
                                 dlam[d], dKv[d, 0])
        for p in range(_particles(q)):
            for a in range(_dim(q)):
                v[p, a] = v[p, a] + h * Kv[0, p, a]
                q[p, a] = q[p, a] + h * v[p, a]
        for d in range(dq.shape[0]):
            for p in range(_particles(q)):
                for a in range(_dim(q)):
                    dv[d, p, a] = dv[d, p, a] + h * dKv[d, 0, p, a]
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
