"""The tangent-linear rigid step: ``ours.rigid.kernel``'s step with n directions of the state carried beside it.

The real step is the kernel's own (``derivative``, ``kick_drift``, the Runge–Kutta stages, in its order), so its
state is ``kernel.run``'s; each direction pays only for its derivative. The tree solve is not differentiated:
[[M, Jᵀ], [J, 0]] x = b gives dx = K⁻¹ (db − dK x), one more solve (two sweeps) through the factor the real
stage left in the work arrays. The rest (rotations, the joints' rows, the forces, the rates, the exponential-map
drift) is differentiated by hand, term for term, and projection's iterations iterate by iterate (each correction's
solve through the factor of the state the step arrived at, which the chord method keeps). Every method and integrator;
``ours.rigid.sensitivity``'s complex step is its independent check.

Shapes: n directions, nb bodies, nj joints, nn = nb + nj nodes. dy (n, 13 nb); the tangent scratch ``tw`` is
:func:`tangent_workspace`'s: dR (n, nb, 3, 3), dC (n, nj, 6), dJA / dJB (n, nj, 6, 6), dgam (n, nj, 6),
rhs (n, nn, 1, 6), dK (stages, n, 13 nb), dys (n, 13 nb), dtheta (n, 3), and the projection's factored state:
R0 (nb, 3, 3), dR0 (n, nb, 3, 3), dJA0 / dJB0 (n, nj, 6, 6).
"""

from __future__ import annotations

import numpy as np

from ours.banded import compiled_fma as compiled, inlined_fma as inlined, llvm_inlined_fma as llvm_inlined
from ours.rigid.kernel import (
    FIXED, PRISMATIC, PROJECTION, REVOLUTE, SMALL_HALF_ANGLE_SQUARED, SYMPLECTIC_EULER, _axis, _body, _correction,
    _cross, _rot, _rotate_quaternion, derivative, joint_rows, kick_drift, rotations, tree_factor, tree_solve,
)
from ours.status import NON_FINITE, NOT_CONVERGED, OK, SINGULAR

#: sha256 of ours/rigid/kernel.py, which ``python -m ours.rigid.generate`` writes: this module's compiled step inlines
#: the kernel's, and numba's on-disk cache of it is checked against this file's stamp alone, so a changed kernel
#: must change this file too (tests/test_gradients_ours_rigid.py checks it).
KERNEL_DIGEST = "3965197138c6adb3355ea15630a92bf96fc0ed19f0a45b2cf2997f6c1acdd7d2"


def tangent_workspace(n: int, nb: int, nj: int, stages: int) -> tuple:
    """Scratch of :func:`run` for n directions (the compiled code allocates nothing). The entries of dJA and dJB
    that the real rows keep constant (a point row's ±e, a torque row's zeros) stay zero: nothing writes them."""

    def z(*shape):
        return np.zeros(shape)

    return (z(n, nb, 3, 3), z(n, nj, 6), z(n, nj, 6, 6), z(n, nj, 6, 6), z(n, nj, 6), z(n, nb + nj, 1, 6),
            z(max(stages, 1), n, 13 * nb), z(n, 13 * nb), z(n, 3), z(nb, 3, 3), z(n, nb, 3, 3), z(n, nj, 6, 6),
            z(n, nj, 6, 6))


@inlined
def _copy(source, target):
    """target ← source, both (m, r, c)."""
    for i in range(source.shape[0]):
        for j in range(source.shape[1]):
            for k in range(source.shape[2]):
                target[i, j, k] = source[i, j, k]


@inlined
def _dcross(a, da, b, db):
    """d (a × b) = da × b + a × db."""
    x = _cross(da[0], da[1], da[2], b[0], b[1], b[2])
    y = _cross(a[0], a[1], a[2], db[0], db[1], db[2])
    return x[0] + y[0], x[1] + y[1], x[2] + y[2]


@inlined
def _twice(w, dw, v, dv):
    """(w × v, w × (w × v)) and their directions (d (w × v), d (w × (w × v))): the first and second rates of a
    vector v carried by a body turning at w."""
    t = _cross(w[0], w[1], w[2], v[0], v[1], v[2])
    dt = _dcross(w, dw, v, dv)
    return t, _cross(w[0], w[1], w[2], t[0], t[1], t[2]), dt, _dcross(w, dw, t, dt)


@inlined
def _ddot(a, da, b, db):
    """d (a · b)."""
    return da[0] * b[0] + da[1] * b[1] + da[2] * b[2] + a[0] * db[0] + a[1] * db[1] + a[2] * db[2]


@inlined
def _drot(dR, d, b, v0, v1, v2):
    """dR[d, b] @ v."""
    return (dR[d, b, 0, 0] * v0 + dR[d, b, 0, 1] * v1 + dR[d, b, 0, 2] * v2,
            dR[d, b, 1, 0] * v0 + dR[d, b, 1, 1] * v1 + dR[d, b, 1, 2] * v2,
            dR[d, b, 2, 0] * v0 + dR[d, b, 2, 1] * v1 + dR[d, b, 2, 2] * v2)


@inlined
def _dbody(dy, dR, d, b, l0, l1, l2):
    """Direction d of ``kernel._body``'s x, r, v, ω (the world's: zero)."""
    if b < 0:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    o = 13 * b
    return ((dy[d, o], dy[d, o + 1], dy[d, o + 2]), _drot(dR, d, b, l0, l1, l2),
            (dy[d, o + 7], dy[d, o + 8], dy[d, o + 9]), (dy[d, o + 10], dy[d, o + 11], dy[d, o + 12]))


@inlined
def _daxis(dR, d, b, F, k, col):
    """Direction d of ``kernel._axis`` (a frame fixed in the world: zero)."""
    if b < 0:
        return 0.0, 0.0, 0.0
    return _drot(dR, d, b, F[k, 0, col], F[k, 1, col], F[k, 2, col])


@llvm_inlined
def d_rotations(y, dy, n, nb, dR):
    """dR (n, nb, 3, 3) of ``kernel.rotations``' R (the quaternion normalised on the fly) along each direction."""
    for b in range(nb):
        o = 13 * b + 3
        w, x, yy, z = y[o], y[o + 1], y[o + 2], y[o + 3]
        s = 2.0 / (w * w + x * x + yy * yy + z * z)
        for d in range(n):
            dw, dx, dyy, dz = dy[d, o], dy[d, o + 1], dy[d, o + 2], dy[d, o + 3]
            ds = -s * s * (w * dw + x * dx + yy * dyy + z * dz)
            dR[d, b, 0, 0] = -(ds * (yy * yy + z * z) + 2.0 * s * (yy * dyy + z * dz))
            dR[d, b, 0, 1] = ds * (x * yy - w * z) + s * (dx * yy + x * dyy - dw * z - w * dz)
            dR[d, b, 0, 2] = ds * (x * z + w * yy) + s * (dx * z + x * dz + dw * yy + w * dyy)
            dR[d, b, 1, 0] = ds * (x * yy + w * z) + s * (dx * yy + x * dyy + dw * z + w * dz)
            dR[d, b, 1, 1] = -(ds * (x * x + z * z) + 2.0 * s * (x * dx + z * dz))
            dR[d, b, 1, 2] = ds * (yy * z - w * x) + s * (dyy * z + yy * dz - dw * x - w * dx)
            dR[d, b, 2, 0] = ds * (x * z - w * yy) + s * (dx * z + x * dz - dw * yy - w * dyy)
            dR[d, b, 2, 1] = ds * (yy * z + w * x) + s * (dyy * z + yy * dz + dw * x + w * dx)
            dR[d, b, 2, 2] = -(ds * (x * x + yy * yy) + 2.0 * s * (x * dx + yy * dyy))


@inlined
def _d_point_rows(d, k, r0, dxA, rA, drA, wA, dwA, dxB, rB, drB, wB, dwB, dC, dJA, dJB, dgam, rates):
    """Direction d of ``kernel._point_rows`` (gam's only with ``rates``)."""
    for i in range(3):
        e0, e1, e2 = 1.0 if i == 0 else 0.0, 1.0 if i == 1 else 0.0, 1.0 if i == 2 else 0.0
        ra = _cross(drA[0], drA[1], drA[2], e0, e1, e2)
        rb = _cross(drB[0], drB[1], drB[2], e0, e1, e2)
        for c in range(3):
            dJA[d, k, r0 + i, 3 + c] = ra[c]
            dJB[d, k, r0 + i, 3 + c] = -rb[c]
        dC[d, k, r0 + i] = dxA[i] + drA[i] - dxB[i] - drB[i]
    if rates:
        dcA = _twice(wA, dwA, rA, drA)[3]
        dcB = _twice(wB, dwB, rB, drB)[3]
        for i in range(3):
            dgam[d, k, r0 + i] = dcA[i] - dcB[i]


@inlined
def _d_dot_row(d, k, r, p, dp, w, dw, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates):
    """Direction d of ``kernel._dot_row`` (gam's only with ``rates``)."""
    dn = _dcross(p, dp, w, dw)
    for c in range(3):
        dJA[d, k, r, 3 + c] = dn[c]
        dJB[d, k, r, 3 + c] = -dn[c]
    dC[d, k, r] = _ddot(p, dp, w, dw)
    if not rates:
        return
    pd, pdd, dpd, dpdd = _twice(wA, dwA, p, dp)
    wd, wdd, dwd, dwdd = _twice(wB, dwB, w, dw)
    g = 0.0
    for i in range(3):
        g += (dpdd[i] * w[i] + pdd[i] * dw[i] + 2.0 * (dpd[i] * wd[i] + pd[i] * dwd[i])
              + dp[i] * wdd[i] + p[i] * dwdd[i])
    dgam[d, k, r] = g


@inlined
def _d_slide_row(d, k, r, p, dp, xA, dxA, rA, drA, vA, dvA, wA, dwA, xB, dxB, rB, drB, vB, dvB, wB, dwB,
                 dC, dJA, dJB, dgam, rates):
    """Direction d of ``kernel._slide_row`` (gam's only with ``rates``)."""
    g_ = (xB[0] + rB[0] - xA[0] - rA[0], xB[1] + rB[1] - xA[1] - rA[1], xB[2] + rB[2] - xA[2] - rA[2])
    dg_ = (dxB[0] + drB[0] - dxA[0] - drA[0], dxB[1] + drB[1] - dxA[1] - drA[1], dxB[2] + drB[2] - dxA[2] - drA[2])
    da = _dcross(p, dp, (g_[0] + rA[0], g_[1] + rA[1], g_[2] + rA[2]),
                 (dg_[0] + drA[0], dg_[1] + drA[1], dg_[2] + drA[2]))
    db = _dcross(rB, drB, p, dp)
    for c in range(3):
        dJA[d, k, r, c] = -dp[c]
        dJA[d, k, r, 3 + c] = da[c]
        dJB[d, k, r, c] = dp[c]
        dJB[d, k, r, 3 + c] = db[c]
    dC[d, k, r] = _ddot(p, dp, g_, dg_)
    if not rates:
        return
    wrA, cA, dwrA, dcA = _twice(wA, dwA, rA, drA)
    wrB, cB, dwrB, dcB = _twice(wB, dwB, rB, drB)
    pd, pdd, dpd, dpdd = _twice(wA, dwA, p, dp)
    gd = (vB[0] + wrB[0] - vA[0] - wrA[0], vB[1] + wrB[1] - vA[1] - wrA[1], vB[2] + wrB[2] - vA[2] - wrA[2])
    dgd = (dvB[0] + dwrB[0] - dvA[0] - dwrA[0], dvB[1] + dwrB[1] - dvA[1] - dwrA[1],
           dvB[2] + dwrB[2] - dvA[2] - dwrA[2])
    g = 0.0
    for i in range(3):
        g += (dpdd[i] * g_[i] + pdd[i] * dg_[i] + 2.0 * (dpd[i] * gd[i] + pd[i] * dgd[i])
              + dp[i] * (cB[i] - cA[i]) + p[i] * (dcB[i] - dcA[i]))
    dgam[d, k, r] = g


@llvm_inlined
def d_joint_rows(y, dy, n, model, R, dR, dC, dJA, dJB, dgam, rates):
    """Directions of ``kernel.joint_rows``' C, JA, JB and, with ``rates``, gam (R, dR at y; the projection uses no
    gam)."""
    kind, parent, child, la, lb, FA, FB = model[4], model[5], model[6], model[7], model[8], model[9], model[10]
    for k in range(kind.shape[0]):
        A, B = parent[k], child[k]
        xA, rA, vA, wA = _body(y, R, A, la[k, 0], la[k, 1], la[k, 2])
        xB, rB, vB, wB = _body(y, R, B, lb[k, 0], lb[k, 1], lb[k, 2])
        p1, p2, p3 = _axis(R, A, FA, k, 0), _axis(R, A, FA, k, 1), _axis(R, A, FA, k, 2)
        w1, w2, w3 = _axis(R, B, FB, k, 0), _axis(R, B, FB, k, 1), _axis(R, B, FB, k, 2)
        t = kind[k]
        for d in range(n):
            dxA, drA, dvA, dwA = _dbody(dy, dR, d, A, la[k, 0], la[k, 1], la[k, 2])
            dxB, drB, dvB, dwB = _dbody(dy, dR, d, B, lb[k, 0], lb[k, 1], lb[k, 2])
            dp1, dp2, dp3 = _daxis(dR, d, A, FA, k, 0), _daxis(dR, d, A, FA, k, 1), _daxis(dR, d, A, FA, k, 2)
            dw1, dw2, dw3 = _daxis(dR, d, B, FB, k, 0), _daxis(dR, d, B, FB, k, 1), _daxis(dR, d, B, FB, k, 2)
            if t == PRISMATIC:
                _d_dot_row(d, k, 0, p2, dp2, w3, dw3, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_dot_row(d, k, 1, p3, dp3, w1, dw1, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_dot_row(d, k, 2, p1, dp1, w2, dw2, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_slide_row(d, k, 3, p1, dp1, xA, dxA, rA, drA, vA, dvA, wA, dwA, xB, dxB, rB, drB, vB, dvB, wB,
                             dwB, dC, dJA, dJB, dgam, rates)
                _d_slide_row(d, k, 4, p2, dp2, xA, dxA, rA, drA, vA, dvA, wA, dwA, xB, dxB, rB, drB, vB, dvB, wB,
                             dwB, dC, dJA, dJB, dgam, rates)
                continue
            _d_point_rows(d, k, 0, dxA, rA, drA, wA, dwA, dxB, rB, drB, wB, dwB, dC, dJA, dJB, dgam, rates)
            if t == REVOLUTE:
                _d_dot_row(d, k, 3, p1, dp1, w3, dw3, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_dot_row(d, k, 4, p2, dp2, w3, dw3, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
            elif t == FIXED:
                _d_dot_row(d, k, 3, p2, dp2, w3, dw3, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_dot_row(d, k, 4, p3, dp3, w1, dw1, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)
                _d_dot_row(d, k, 5, p1, dp1, w2, dw2, wA, dwA, wB, dwB, dC, dJA, dJB, dgam, rates)


@inlined
def _in_body(R, b, Ib, a):
    """I_b Rᵀ a (3 floats): a world vector a (3 floats) into body b's frame, times its inertia."""
    k0 = R[b, 0, 0] * a[0] + R[b, 1, 0] * a[1] + R[b, 2, 0] * a[2]
    k1 = R[b, 0, 1] * a[0] + R[b, 1, 1] * a[1] + R[b, 2, 1] * a[2]
    k2 = R[b, 0, 2] * a[0] + R[b, 1, 2] * a[1] + R[b, 2, 2] * a[2]
    return (Ib[0, 0] * k0 + Ib[0, 1] * k1 + Ib[0, 2] * k2, Ib[1, 0] * k0 + Ib[1, 1] * k1 + Ib[1, 2] * k2,
            Ib[2, 0] * k0 + Ib[2, 1] * k1 + Ib[2, 2] * k2)


@inlined
def _d_inertia(R, dR, d, b, Ib, a, ma):
    """(dR I_b Rᵀ + R I_b dRᵀ) a: direction d of the world inertia I_w = R I_b Rᵀ, times a (3 floats held);
    ma = I_b Rᵀ a (:func:`_in_body`)."""
    f0 = dR[d, b, 0, 0] * a[0] + dR[d, b, 1, 0] * a[1] + dR[d, b, 2, 0] * a[2]
    f1 = dR[d, b, 0, 1] * a[0] + dR[d, b, 1, 1] * a[1] + dR[d, b, 2, 1] * a[2]
    f2 = dR[d, b, 0, 2] * a[0] + dR[d, b, 1, 2] * a[1] + dR[d, b, 2, 2] * a[2]
    n0 = Ib[0, 0] * f0 + Ib[0, 1] * f1 + Ib[0, 2] * f2
    n1 = Ib[1, 0] * f0 + Ib[1, 1] * f1 + Ib[1, 2] * f2
    n2 = Ib[2, 0] * f0 + Ib[2, 1] * f1 + Ib[2, 2] * f2
    x = _drot(dR, d, b, ma[0], ma[1], ma[2])
    r = _rot(R, b, n0, n1, n2)
    return x[0] + r[0], x[1] + r[1], x[2] + r[2]


@llvm_inlined
def d_bodies(y, dy, n, model, R, dR, sol, rhs):
    """rhs[d]'s body entries ← d f − dM u̇ along each direction: f = (m g, −ω × I_w ω), M = diag(m, I_w),
    I_w = R I_b Rᵀ, u̇ the real solution (sol's body entries)."""
    inertia, nb = model[1], model[0].shape[0]
    for b in range(nb):
        o = 13 * b
        Ib = inertia[b]
        w = (y[o + 10], y[o + 11], y[o + 12])
        m = _in_body(R, b, Ib, w)
        L = _rot(R, b, m[0], m[1], m[2])  # I_w ω
        a = (sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5])  # ω̇
        ma = _in_body(R, b, Ib, a)
        for d in range(n):
            dw = (dy[d, o + 10], dy[d, o + 11], dy[d, o + 12])
            held = _d_inertia(R, dR, d, b, Ib, w, m)
            mw = _in_body(R, b, Ib, dw)
            turned = _rot(R, b, mw[0], mw[1], mw[2])
            dg = _dcross(w, dw, L, (held[0] + turned[0], held[1] + turned[1], held[2] + turned[2]))
            dIa = _d_inertia(R, dR, d, b, Ib, a, ma)
            for i in range(3):
                rhs[d, b, 0, i] = 0.0
                rhs[d, b, 0, 3 + i] = -dg[i] - dIa[i]


@llvm_inlined
def d_joints(y, dy, n, model, work, dKA, dKB, dJA, dJB, dC, dgam, rhs, gain_gam, gain_C, gain_rate):
    """The joints' part of rhs[d] = db − dK x (x = [u̇; λ], the real solution in work[7]; dK's rows dKA, dKB):
    the bodies' entries −= dJ_Kᵀ λ, the joints' ← −gain_gam dgam − gain_C dC − gain_rate d(J u) − dJ_K u̇, with
    d(J u) = dJ u + J du at the current rows (work's J, dJA, dJB). The step's rows: (1, k_s, k_d) and dK = dJ."""
    nb, parent, child, rows = model[0].shape[0], model[5], model[6], model[11]
    JA, JB, sol = work[2], work[3], work[7]
    for k in range(rows.shape[0]):
        A, B = parent[k], child[k]
        a, b = 13 * A + 7, 13 * B + 7
        for d in range(n):
            for r in range(rows[k]):
                lam = sol[nb + k, 0, r]
                rate = 0.0
                acc = 0.0
                for c in range(6):
                    acc += dKB[d, k, r, c] * sol[B, 0, c]
                    rhs[d, B, 0, c] -= dKB[d, k, r, c] * lam
                if A >= 0:
                    for c in range(6):
                        acc += dKA[d, k, r, c] * sol[A, 0, c]
                        rhs[d, A, 0, c] -= dKA[d, k, r, c] * lam
                if gain_rate != 0.0:  # plain's k_d and the projection's positions: no J u
                    for c in range(6):
                        rate += dJB[d, k, r, c] * y[b + c] + JB[k, r, c] * dy[d, b + c]
                    if A >= 0:
                        for c in range(6):
                            rate += dJA[d, k, r, c] * y[a + c] + JA[k, r, c] * dy[d, a + c]
                rhs[d, nb + k, 0, r] = -gain_gam * dgam[d, k, r] - gain_C * dC[d, k, r] - gain_rate * rate - acc


@llvm_inlined
def d_rates(y, dy, n, nb, rhs, dydot):
    """dydot (n, 13 nb) of ``kernel.rates``' ydot, with du̇ solved into rhs."""
    for b in range(nb):
        o = 13 * b
        q = (y[o + 4], y[o + 5], y[o + 6])
        qw = y[o + 3]
        w = (y[o + 10], y[o + 11], y[o + 12])
        for d in range(n):
            dq = (dy[d, o + 4], dy[d, o + 5], dy[d, o + 6])
            dqw = dy[d, o + 3]
            dw = (dy[d, o + 10], dy[d, o + 11], dy[d, o + 12])
            dydot[d, o], dydot[d, o + 1], dydot[d, o + 2] = dy[d, o + 7], dy[d, o + 8], dy[d, o + 9]
            dydot[d, o + 3] = -0.5 * _ddot(w, dw, q, dq)
            dc = _dcross(w, dw, q, dq)
            for i in range(3):
                dydot[d, o + 4 + i] = 0.5 * (dqw * w[i] + qw * dw[i] + dc[i])
            for r in range(6):
                dydot[d, o + 7 + r] = rhs[d, b, 0, r]


@llvm_inlined
def d_derivative(y, dy, n, model, work, tw, ks, kd, dydot):
    """dydot (n, 13 nb) along dy (n, 13 nb), right after ``kernel.derivative`` at y returned OK (its rotations,
    rows, factor and solution still in work)."""
    nb, R = model[0].shape[0], work[0]
    dR, dC, dJA, dJB, dgam, rhs = tw[0], tw[1], tw[2], tw[3], tw[4], tw[5]
    d_rotations(y, dy, n, nb, dR)
    d_joint_rows(y, dy, n, model, R, dR, dC, dJA, dJB, dgam, True)
    d_bodies(y, dy, n, model, R, dR, work[7], rhs)
    d_joints(y, dy, n, model, work, dJA, dJB, dJA, dJB, dC, dgam, rhs, 1.0, ks, kd)
    for d in range(n):  # dx = K⁻¹ (db − dK x): the real factor, one more solve per direction
        tree_solve(model, work, rhs[d])
    d_rates(y, dy, n, nb, rhs, dydot)


@inlined
def _d_turn(y, dy, n, o, t, dtheta):
    """Directions of ``kernel._rotate_quaternion(y, o, θ)`` (called before it: y[o:o + 4] is the quaternion it
    turns): θ = t (3 floats), its direction d in dtheta[d] (n, 3)."""
    q = (y[o], y[o + 1], y[o + 2], y[o + 3])
    square = t[0] * t[0] + t[1] * t[1] + t[2] * t[2]
    rotates = square.real > 0.0
    s = a0 = ds_ = da0_ = 0.0
    p = q
    if rotates:
        x2 = 0.25 * square
        if x2.real < SMALL_HALF_ANGLE_SQUARED:  # the kernel's series, and its derivative in x2
            s = 0.5 * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))))
            a0 = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)))
            ds_ = 0.5 * (-1.0 / 6.0 + x2 * (2.0 / 120.0 - x2 * (3.0 / 5040.0 - x2 * (4.0 / 362880.0))))
            da0_ = -0.5 + x2 * (2.0 / 24.0 - x2 * (3.0 / 720.0 - x2 * (4.0 / 40320.0)))
        else:  # x2 = angle² / 4, so d/dx2 = (2 / angle) d/dangle
            angle = np.sqrt(square)
            s = np.sin(0.5 * angle) / angle
            a0 = np.cos(0.5 * angle)
            ds_ = (0.5 * a0 * angle - np.sin(0.5 * angle)) / (angle * angle) * 2.0 / angle
            da0_ = -0.5 * np.sin(0.5 * angle) * 2.0 / angle
        a = (s * t[0], s * t[1], s * t[2])
        c = _cross(a[0], a[1], a[2], q[1], q[2], q[3])
        p = (a0 * q[0] - a[0] * q[1] - a[1] * q[2] - a[2] * q[3], a0 * q[1] + q[0] * a[0] + c[0],
             a0 * q[2] + q[0] * a[1] + c[1], a0 * q[3] + q[0] * a[2] + c[2])
    inverse = 1.0 / np.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3])
    u = (p[0] * inverse, p[1] * inverse, p[2] * inverse, p[3] * inverse)
    for d in range(n):
        dq = (dy[d, o], dy[d, o + 1], dy[d, o + 2], dy[d, o + 3])
        dp = dq
        if rotates:
            dt = (dtheta[d, 0], dtheta[d, 1], dtheta[d, 2])
            dx2 = 0.5 * (t[0] * dt[0] + t[1] * dt[1] + t[2] * dt[2])
            ds, da0 = ds_ * dx2, da0_ * dx2
            a = (s * t[0], s * t[1], s * t[2])
            da = (ds * t[0] + s * dt[0], ds * t[1] + s * dt[1], ds * t[2] + s * dt[2])
            dc = _dcross(a, da, (q[1], q[2], q[3]), (dq[1], dq[2], dq[3]))
            dp = (da0 * q[0] + a0 * dq[0] - da[0] * q[1] - a[0] * dq[1] - da[1] * q[2] - a[1] * dq[2]
                  - da[2] * q[3] - a[2] * dq[3],
                  da0 * q[1] + a0 * dq[1] + dq[0] * a[0] + q[0] * da[0] + dc[0],
                  da0 * q[2] + a0 * dq[2] + dq[0] * a[1] + q[0] * da[1] + dc[1],
                  da0 * q[3] + a0 * dq[3] + dq[0] * a[2] + q[0] * da[2] + dc[2])
        radial = u[0] * dp[0] + u[1] * dp[1] + u[2] * dp[2] + u[3] * dp[3]
        for i in range(4):
            dy[d, o + i] = (dp[i] - u[i] * radial) * inverse


@llvm_inlined
def d_kick_drift(y, dy, n, nb, ydot, dydot, h, dtheta):
    """Directions of ``kernel.kick_drift`` (called before it: y is the state it starts from)."""
    for b in range(nb):
        o = 13 * b
        for d in range(n):
            for r in range(6):
                dy[d, o + 7 + r] += h * dydot[d, o + 7 + r]
            for r in range(3):
                dy[d, o + r] += h * dy[d, o + 7 + r]
                dtheta[d, r] = h * dy[d, o + 10 + r]  # the turn's, with ω after the kick
        t = (h * (y[o + 10] + h * ydot[o + 10]), h * (y[o + 11] + h * ydot[o + 11]),
             h * (y[o + 12] + h * ydot[o + 12]))  # θ = h ω after the kick
        _d_turn(y, dy, n, o + 3, t, dtheta)


@llvm_inlined
def _d_chord(y, dy, n, model, work, tw, velocity):
    """rhs[d] ← the direction d of :func:`kernel._correction`'s solve x = K₀⁻¹ [0; −e] (K₀ factored at the state
    the step arrived at, e = C, or J u with J at the projected positions): K₀⁻¹ (−de − dK₀ x), with dK₀ from the
    saved R₀, dR₀, dJ₀ and de from the current dC (positions) or dJ, J (velocities)."""
    inertia, nb, sol = model[1], model[0].shape[0], work[7]
    dC, dJA, dJB, rhs = tw[1], tw[2], tw[3], tw[5]
    R0, dR0, dJA0, dJB0 = tw[9], tw[10], tw[11], tw[12]
    for b in range(nb):  # −dM₀ x_b (only I_w = R₀ I_b R₀ᵀ moves)
        Ib = inertia[b]
        a = (sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5])
        ma = _in_body(R0, b, Ib, a)
        for d in range(n):
            dIa = _d_inertia(R0, dR0, d, b, Ib, a, ma)
            for i in range(3):
                rhs[d, b, 0, i] = 0.0
                rhs[d, b, 0, 3 + i] = -dIa[i]
    if velocity:  # e = J u
        d_joints(y, dy, n, model, work, dJA0, dJB0, dJA, dJB, dC, tw[4], rhs, 0.0, 0.0, 1.0)
    else:  # e = C
        d_joints(y, dy, n, model, work, dJA0, dJB0, dJA, dJB, dC, tw[4], rhs, 0.0, 1.0, 0.0)
    for d in range(n):
        tree_solve(model, work, rhs[d])


@llvm_inlined
def project(y, dy, n, model, work, tw, tolerance, max_iterations):
    """``kernel.project`` (the same calls in the same order) and its directions, iterate by iterate: each
    iteration's correction differentiated through the factor at the arrival state. A status code."""
    nb, R, sol = model[0].shape[0], work[0], work[7]
    dR, dC, dJA, dJB, dgam, rhs, dtheta = tw[0], tw[1], tw[2], tw[3], tw[4], tw[5], tw[8]
    R0, dR0, dJA0, dJB0 = tw[9], tw[10], tw[11], tw[12]
    rotations(y, nb, R)
    joint_rows(y, model, R, work[1], work[2], work[3], work[4])
    if not tree_factor(y, model, work):
        return SINGULAR
    d_rotations(y, dy, n, nb, dR)
    d_joint_rows(y, dy, n, model, R, dR, dC, dJA, dJB, dgam, False)
    for b in range(nb):  # K₀'s data: the chord method keeps its factor through every iteration
        for i in range(3):
            for j in range(3):
                R0[b, i, j] = R[b, i, j]
    for d in range(n):
        _copy(dR[d], dR0[d])
        _copy(dJA[d], dJA0[d])
        _copy(dJB[d], dJB0[d])
    for velocity in (False, True):
        for it in range(max_iterations + 1):
            if it > 0 and not velocity:
                rotations(y, nb, R)
                joint_rows(y, model, R, work[1], work[2], work[3], work[4])
                d_rotations(y, dy, n, nb, dR)
                d_joint_rows(y, dy, n, model, R, dR, dC, dJA, dJB, dgam, False)
            worst = _correction(y, model, work, velocity, tolerance)
            if worst <= tolerance:
                break
            if it == max_iterations:
                return NOT_CONVERGED
            _d_chord(y, dy, n, model, work, tw, velocity)
            for b in range(nb):
                o = 13 * b
                if velocity:
                    for r in range(6):
                        y[o + 7 + r] += sol[b, 0, r]
                        for d in range(n):
                            dy[d, o + 7 + r] += rhs[d, b, 0, r]
                else:
                    for r in range(3):
                        y[o + r] += sol[b, 0, r]
                        for d in range(n):
                            dy[d, o + r] += rhs[d, b, 0, r]
                            dtheta[d, r] = rhs[d, b, 0, 3 + r]
                    _d_turn(y, dy, n, o + 3, (sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5]), dtheta)
                    _rotate_quaternion(y, o + 3, sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5])
    return OK


@llvm_inlined
def step(method, code, A, bw, y, dy, model, work, tw, ks, kd, h, tolerance, max_iterations):
    """``kernel.step`` and its directions dy (n, 13 nb), both in place; a status code."""
    nb, n = model[0].shape[0], dy.shape[0]
    K, ys = work[9], work[10]
    dK, dys = tw[6], tw[7]
    m = y.shape[0]
    if code == SYMPLECTIC_EULER:
        status = derivative(y, model, work, ks, kd, K[0])
        if status != OK:
            return status
        d_derivative(y, dy, n, model, work, tw, ks, kd, dK[0])
        d_kick_drift(y, dy, n, nb, K[0], dK[0], h, tw[8])
        kick_drift(y, nb, K[0], h)
    else:
        s = bw.shape[0]
        for i in range(s):
            for e in range(m):
                ys[e] = y[e]
            for d in range(n):
                for e in range(m):
                    dys[d, e] = dy[d, e]
            for j in range(i):
                a = h * A[i, j]
                if a != 0.0:
                    for e in range(m):
                        ys[e] += a * K[j, e]
                    for d in range(n):
                        for e in range(m):
                            dys[d, e] += a * dK[j, d, e]
            status = derivative(ys, model, work, ks, kd, K[i])
            if status != OK:
                return status
            d_derivative(ys, dys, n, model, work, tw, ks, kd, dK[i])
        for e in range(m):
            acc = 0.0
            for i in range(s):
                acc += bw[i] * K[i, e]
            y[e] += h * acc
        for d in range(n):
            for e in range(m):
                acc = 0.0
                for i in range(s):
                    acc += bw[i] * dK[i, d, e]
                dy[d, e] += h * acc
    if method == PROJECTION:
        status = project(y, dy, n, model, work, tw, tolerance, max_iterations)
        if status != OK:
            return status
    spread = 0.0
    for e in range(m):
        spread += y[e] - y[e]
    for d in range(n):
        for e in range(m):
            spread += dy[d, e] - dy[d, e]
    if spread != 0.0:
        return NON_FINITE
    return OK


@compiled
def run(method, code, A, bw, y, dy, model, work, tw, ks, kd, h, n_steps, stride, tolerance, max_iterations, out,
        dout):
    """Step n_steps times; out (samples, 13 nb) gets y and dout (samples, n, 13 nb) dy at
    step 0, every stride steps and the last. Returns (samples written, steps taken, status)."""
    m, n = y.shape[0], dy.shape[0]
    for e in range(m):
        out[0, e] = y[e]
    for d in range(n):
        for e in range(m):
            dout[0, d, e] = dy[d, e]
    written = 1
    for s in range(1, n_steps + 1):
        status = step(method, code, A, bw, y, dy, model, work, tw, ks, kd, h, tolerance, max_iterations)
        if status != OK:
            return written, s - 1, status
        if s % stride == 0 or s == n_steps:
            for e in range(m):
                out[written, e] = y[e]
            for d in range(n):
                for e in range(m):
                    dout[written, d, e] = dy[d, e]
            written += 1
    return written, n_steps, OK
