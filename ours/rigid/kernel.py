"""Compiled rigid-body dynamics in maximal coordinates (Baraff 1996): rows, tree solve, steps.

State y, flat (13 per body): COM position x (3, m), unit quaternion Q = (w, x, y, z) of the body
frame, COM velocity v (3, m/s), angular velocity ω (3, rad/s, world frame). Newton–Euler:
M u̇ = f + Jᵀλ with f = (m g, −ω × I_w ω); the joints' rows satisfy J u̇ = −J̇u − k_s C − k_d J u.
The pair is solved as one symmetric system [[M, Jᵀ], [J, 0]] whose graph (bodies and joints as
nodes) is the mechanism's tree, factored leaves first without fill: O(n) (Baraff's elimination).
``model`` and ``work`` are the tuples ``ours.rigid.pack`` builds; nothing here allocates.

Every operation of a step is one complex numbers carry (numpy's square root, sine and cosine; the tests of
a pivot's sign, of a small angle and of convergence read real parts or magnitudes), so :func:`run` also
compiles for a complex128 state and scratch: ``ours.rigid.sensitivity``'s complex step.
"""

from __future__ import annotations

import numpy as np

from ours.banded import compiled_fma as compiled, inlined_fma as inlined, llvm_inlined_fma as llvm_inlined
from ours.rigid.blocks import (
    fold_sweep_ball, fold_sweep_ball_pair, fold_sweep_fixed, fold_sweep_fixed_pair, fold_sweep_prismatic,
    fold_sweep_prismatic_pair, fold_sweep_revolute, fold_sweep_revolute_pair,
    fold_ball, fold_fixed, fold_prismatic, fold_revolute, sweep_down_ball, sweep_down_fixed, sweep_down_prismatic,
    sweep_down_revolute, sweep_up_ball, sweep_up_fixed, sweep_up_prismatic, sweep_up_revolute, targets_ball,
    targets_fixed, targets_prismatic, targets_revolute,
)
from ours.status import NON_FINITE, NOT_CONVERGED, OK, SINGULAR

#: sha256 of ours/rigid/blocks.py, which ``python -m ours.rigid.generate`` writes along with it: numba's
#: on-disk cache of this module is checked against this file's stamp alone, so regenerating the blocks
#: must change this file too, or the compiled step would keep the old blocks.
BLOCKS_DIGEST = "b547b00d0ef62618e7c204faab93051c99b97af502af2ca12be96b400ee6425f"

BALL, REVOLUTE, PRISMATIC, FIXED = 0, 1, 2, 3
EXPLICIT_RK, SYMPLECTIC_EULER = 0, 1
#: Below this (|θ|/2)² (half-angles under 0.01 rad), exp(θ/2)'s cos and sin(x)/x come from their Taylor series
#: to x⁸: the first term left out is below 3e-27 of the sum, far under round-off.
SMALL_HALF_ANGLE_SQUARED = 1e-4
PLAIN, BAUMGARTE, PROJECTION = 0, 1, 2


@inlined
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@inlined
def _rot(R, b, v0, v1, v2):
    """R[b] @ v."""
    return (R[b, 0, 0] * v0 + R[b, 0, 1] * v1 + R[b, 0, 2] * v2,
            R[b, 1, 0] * v0 + R[b, 1, 1] * v1 + R[b, 1, 2] * v2,
            R[b, 2, 0] * v0 + R[b, 2, 1] * v1 + R[b, 2, 2] * v2)


@llvm_inlined
def rotations(y, nb, R):
    """R[b] (3, 3) from each body's quaternion, normalised on the fly (its norm does not matter)."""
    for b in range(nb):
        o = 13 * b + 3
        w, x, yy, z = y[o], y[o + 1], y[o + 2], y[o + 3]
        s = 2.0 / (w * w + x * x + yy * yy + z * z)
        R[b, 0, 0] = 1.0 - s * (yy * yy + z * z)
        R[b, 0, 1] = s * (x * yy - w * z)
        R[b, 0, 2] = s * (x * z + w * yy)
        R[b, 1, 0] = s * (x * yy + w * z)
        R[b, 1, 1] = 1.0 - s * (x * x + z * z)
        R[b, 1, 2] = s * (yy * z - w * x)
        R[b, 2, 0] = s * (x * z - w * yy)
        R[b, 2, 1] = s * (yy * z + w * x)
        R[b, 2, 2] = 1.0 - s * (x * x + yy * yy)


@inlined
def _body(y, R, b, l0, l1, l2):
    """World data of body b (b < 0: the world): x, r = R l, v, ω, each as 3 floats."""
    if b < 0:
        return (0.0, 0.0, 0.0), (l0, l1, l2), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    o = 13 * b
    return ((y[o], y[o + 1], y[o + 2]), _rot(R, b, l0, l1, l2),
            (y[o + 7], y[o + 8], y[o + 9]), (y[o + 10], y[o + 11], y[o + 12]))


@inlined
def _axis(R, b, F, k, col):
    """Column ``col`` of joint k's frame F[k] (in body b's frame) in the world frame."""
    if b < 0:
        return F[k, 0, col], F[k, 1, col], F[k, 2, col]
    return _rot(R, b, F[k, 0, col], F[k, 1, col], F[k, 2, col])


@inlined
def _set_row(JA, JB, k, r, a, b):
    """Row r of joint k: JA (parent) = a (6 floats), JB (child) = b."""
    for c in range(6):
        JA[k, r, c] = a[c]
        JB[k, r, c] = b[c]


@inlined
def _set_moment(JA, JB, k, r, a, b):
    """The angular half (columns 3–5) of row r of joint k: JA = a, JB = b (3 floats each). The linear half
    of a point row (±e) and of a torque row (0) never changes: ``ours.rigid.workspace`` writes it once."""
    for c in range(3):
        JA[k, r, 3 + c] = a[c]
        JB[k, r, 3 + c] = b[c]


@llvm_inlined
def _point_rows(k, r0, xA, rA, vA, wA, xB, rB, vB, wB, C, JA, JB, gam):
    """Three rows C = (x_A + r_A) − (x_B + r_B): the anchors coincide (m)."""
    tA = _cross(wA[0], wA[1], wA[2], rA[0], rA[1], rA[2])
    tB = _cross(wB[0], wB[1], wB[2], rB[0], rB[1], rB[2])
    cA = _cross(wA[0], wA[1], wA[2], tA[0], tA[1], tA[2])
    cB = _cross(wB[0], wB[1], wB[2], tB[0], tB[1], tB[2])
    for i in range(3):
        e0, e1, e2 = 1.0 if i == 0 else 0.0, 1.0 if i == 1 else 0.0, 1.0 if i == 2 else 0.0
        ra = _cross(rA[0], rA[1], rA[2], e0, e1, e2)
        rb = _cross(rB[0], rB[1], rB[2], e0, e1, e2)
        _set_moment(JA, JB, k, r0 + i, (ra[0], ra[1], ra[2]), (-rb[0], -rb[1], -rb[2]))
        C[k, r0 + i] = xA[i] + rA[i] - xB[i] - rB[i]
        gam[k, r0 + i] = cA[i] - cB[i]


@llvm_inlined
def _dot_row(k, r, p, w, wA, wB, C, JA, JB, gam):
    """One row C = p · w, p fixed in the parent, w in the child (both world, unit): they stay perpendicular."""
    n = _cross(p[0], p[1], p[2], w[0], w[1], w[2])
    _set_moment(JA, JB, k, r, (n[0], n[1], n[2]), (-n[0], -n[1], -n[2]))
    C[k, r] = p[0] * w[0] + p[1] * w[1] + p[2] * w[2]
    pd = _cross(wA[0], wA[1], wA[2], p[0], p[1], p[2])
    wd = _cross(wB[0], wB[1], wB[2], w[0], w[1], w[2])
    pdd = _cross(wA[0], wA[1], wA[2], pd[0], pd[1], pd[2])
    wdd = _cross(wB[0], wB[1], wB[2], wd[0], wd[1], wd[2])
    g = 0.0
    for i in range(3):
        g += pdd[i] * w[i] + 2.0 * pd[i] * wd[i] + p[i] * wdd[i]
    gam[k, r] = g


@llvm_inlined
def _slide_row(k, r, p, xA, rA, vA, wA, xB, rB, vB, wB, C, JA, JB, gam):
    """One row C = p · d, d = (x_B + r_B) − (x_A + r_A), p fixed in the parent: no slip across p (m)."""
    d = (xB[0] + rB[0] - xA[0] - rA[0], xB[1] + rB[1] - xA[1] - rA[1], xB[2] + rB[2] - xA[2] - rA[2])
    a = _cross(p[0], p[1], p[2], d[0] + rA[0], d[1] + rA[1], d[2] + rA[2])
    b = _cross(rB[0], rB[1], rB[2], p[0], p[1], p[2])
    _set_row(JA, JB, k, r, (-p[0], -p[1], -p[2], a[0], a[1], a[2]), (p[0], p[1], p[2], b[0], b[1], b[2]))
    C[k, r] = p[0] * d[0] + p[1] * d[1] + p[2] * d[2]
    wrA = _cross(wA[0], wA[1], wA[2], rA[0], rA[1], rA[2])
    wrB = _cross(wB[0], wB[1], wB[2], rB[0], rB[1], rB[2])
    dd = (vB[0] + wrB[0] - vA[0] - wrA[0], vB[1] + wrB[1] - vA[1] - wrA[1], vB[2] + wrB[2] - vA[2] - wrA[2])
    pd = _cross(wA[0], wA[1], wA[2], p[0], p[1], p[2])
    pdd = _cross(wA[0], wA[1], wA[2], pd[0], pd[1], pd[2])
    cA = _cross(wA[0], wA[1], wA[2], wrA[0], wrA[1], wrA[2])
    cB = _cross(wB[0], wB[1], wB[2], wrB[0], wrB[1], wrB[2])
    g = 0.0
    for i in range(3):
        g += pdd[i] * d[i] + 2.0 * pd[i] * dd[i] + p[i] * (cB[i] - cA[i])
    gam[k, r] = g


@llvm_inlined
def joint_rows(y, model, R, C, JA, JB, gam):
    """Every joint's rows at state y (R from :func:`rotations`): C (nj, 6), JA / JB (nj, 6, 6) the
    Jacobians on the parent's and the child's u = (v, ω), gam (nj, 6) = J̇u (the velocity product)."""
    kind, parent, child, la, lb, FA, FB = model[4], model[5], model[6], model[7], model[8], model[9], model[10]
    for k in range(kind.shape[0]):
        A, B = parent[k], child[k]
        xA, rA, vA, wA = _body(y, R, A, la[k, 0], la[k, 1], la[k, 2])
        xB, rB, vB, wB = _body(y, R, B, lb[k, 0], lb[k, 1], lb[k, 2])
        t = kind[k]
        if t == PRISMATIC:
            p1, p2, p3 = _axis(R, A, FA, k, 0), _axis(R, A, FA, k, 1), _axis(R, A, FA, k, 2)
            w1, w2, w3 = _axis(R, B, FB, k, 0), _axis(R, B, FB, k, 1), _axis(R, B, FB, k, 2)
            _dot_row(k, 0, p2, w3, wA, wB, C, JA, JB, gam)
            _dot_row(k, 1, p3, w1, wA, wB, C, JA, JB, gam)
            _dot_row(k, 2, p1, w2, wA, wB, C, JA, JB, gam)
            _slide_row(k, 3, p1, xA, rA, vA, wA, xB, rB, vB, wB, C, JA, JB, gam)
            _slide_row(k, 4, p2, xA, rA, vA, wA, xB, rB, vB, wB, C, JA, JB, gam)
            continue
        _point_rows(k, 0, xA, rA, vA, wA, xB, rB, vB, wB, C, JA, JB, gam)
        if t == REVOLUTE:
            w3 = _axis(R, B, FB, k, 2)
            _dot_row(k, 3, _axis(R, A, FA, k, 0), w3, wA, wB, C, JA, JB, gam)
            _dot_row(k, 4, _axis(R, A, FA, k, 1), w3, wA, wB, C, JA, JB, gam)
        elif t == FIXED:
            p1, p2, p3 = _axis(R, A, FA, k, 0), _axis(R, A, FA, k, 1), _axis(R, A, FA, k, 2)
            w1, w2, w3 = _axis(R, B, FB, k, 0), _axis(R, B, FB, k, 1), _axis(R, B, FB, k, 2)
            _dot_row(k, 3, p2, w3, wA, wB, C, JA, JB, gam)
            _dot_row(k, 4, p3, w1, wA, wB, C, JA, JB, gam)
            _dot_row(k, 5, p1, w2, wA, wB, C, JA, JB, gam)


# --- the tree solve -------------------------------------------------------------------------
#
# The system [[M, Jᵀ], [J, 0]] [u; λ] = [f; c] is eliminated one joint at a time, deepest first: joint k
# joins its child body B (whose block D_B already holds what B's own child joints folded into it) to its
# parent A. With D_B = L_B L_Bᵀ, Y_k = L_B⁻¹ J_Bᵀ (stored row by row, (r, 6), in X[B]) and
# S_k = J_B D_B⁻¹ J_Bᵀ = Y_kᵀ Y_k = L_k L_kᵀ (r × r, in D[nb + k]), eliminating u_B and then λ_k adds
# J_Aᵀ S_k⁻¹ J_A = Z_kᵀ Z_k to D_A, with Z_k = L_k⁻¹ J_A (stored column by column, (6, r), in X[nb + k]).
# Only forward substitutions build the factor (Y and Z, not D⁻¹ J), and every block is a constant
# size for the common joints, so the loops unroll.

@inlined
def _cholesky(D, i, n):
    """D[i] (n × n, lower part) = L Lᵀ in place, with 1/L_rr on the diagonal (the solves multiply
    instead of dividing); False when not positive definite."""
    for r in range(n):
        for c in range(r + 1):
            s = D[i, r, c]
            for m in range(c):
                s -= D[i, r, m] * D[i, c, m]
            if r == c:
                if not s.real > 0.0:
                    return False
                D[i, r, r] = 1.0 / np.sqrt(s)
            else:
                D[i, r, c] = s * D[i, c, c]
    return True


@inlined
def _forward(D, i, n, x, j, c):
    """x[j, c, :n] ← L⁻¹ x[j, c, :n] in place, with L in D[i]."""
    for r in range(n):
        s = x[j, c, r]
        for m in range(r):
            s -= D[i, r, m] * x[j, c, m]
        x[j, c, r] = s * D[i, r, r]


@inlined
def _backward(D, i, n, x, j, c):
    """x[j, c, :n] ← L⁻ᵀ x[j, c, :n] in place, with L in D[i]."""
    for r in range(n - 1, -1, -1):
        s = x[j, c, r]
        for m in range(r + 1, n):
            s -= D[i, m, r] * x[j, c, m]
        x[j, c, r] = s * D[i, r, r]


@llvm_inlined
def assemble(model, work):
    """D's body blocks ← [[m 1, 0], [0, I_w]] with I_w = R I_b Rᵀ (R in work[0]), lower triangles."""
    mass, inertia, nb = model[0], model[1], model[0].shape[0]
    R, D = work[0], work[5]
    for b in range(nb):
        for r in range(6):
            for c in range(r + 1):
                D[b, r, c] = 0.0
        for r in range(3):
            D[b, r, r] = mass[b]
        for r in range(3):  # I_w = R (I_b Rᵀ)
            for c in range(r + 1):
                s = 0.0
                for m in range(3):
                    s += R[b, r, m] * (inertia[b, m, 0] * R[b, c, 0] + inertia[b, m, 1] * R[b, c, 1]
                                       + inertia[b, m, 2] * R[b, c, 2])
                D[b, 3 + r, 3 + c] = s


@llvm_inlined
def eliminate(model, work):
    """Factor the assembled system (work[5], rows in work[2:4]) joint by joint, deepest first; False if singular."""
    nb, kind, parent, child, order, free = model[0].shape[0], model[4], model[5], model[6], model[12], model[13]
    JA, JB, D, X = work[2], work[3], work[5], work[6]
    for idx in range(order.shape[0]):
        k = order[idx]
        A, B = parent[k], child[k]
        t = kind[k]  # written out per kind, every block entry a local (ours.rigid.generate)
        if t == REVOLUTE:
            ok = fold_revolute(D, X, JA, JB, nb, k, A, B)
        elif t == PRISMATIC:
            ok = fold_prismatic(D, X, JA, JB, nb, k, A, B)
        elif t == BALL:
            ok = fold_ball(D, X, JA, JB, nb, k, A, B)
        else:
            ok = fold_fixed(D, X, JA, JB, nb, k, A, B)
        if not ok:
            return False
    for idx in range(free.shape[0]):  # bodies with no inbound joint: their block is the last to factor
        if not _cholesky(D, free[idx], 6):
            return False
    return True


@llvm_inlined
def tree_factor(y, model, work):
    """Assemble [[M, Jᵀ], [J, 0]] at y (rows already in work) and factor it; False if singular."""
    assemble(model, work)
    return eliminate(model, work)


@llvm_inlined
def factor_and_sweep(model, work, x):
    """:func:`eliminate` and the forward half of :func:`tree_solve` of the right side x in one pass (each joint's
    blocks are swept while still in registers); :func:`sweep_up` finishes the solve. False if singular."""
    nb, kind, parent, child, order, free = model[0].shape[0], model[4], model[5], model[6], model[12], model[13]
    JA, JB, D, X = work[2], work[3], work[5], work[6]
    n, idx = order.shape[0], 0
    while idx < n:
        k = order[idx]
        A, B, t = parent[k], child[k], kind[k]
        idx += 1
        if idx < n:  # the next joint of the same kind, and neither folds into the body the other eliminates:
            p_k = order[idx]  # the two folds are independent, done at once (ours.rigid.generate's fold_pair)
            p_A, p_B = parent[p_k], child[p_k]
            if kind[p_k] == t and A != p_B and p_A != B:
                idx += 1
                if t == REVOLUTE:
                    ok = fold_sweep_revolute_pair(D, X, JA, JB, x, nb, k, A, B, p_k, p_A, p_B)
                elif t == PRISMATIC:
                    ok = fold_sweep_prismatic_pair(D, X, JA, JB, x, nb, k, A, B, p_k, p_A, p_B)
                elif t == BALL:
                    ok = fold_sweep_ball_pair(D, X, JA, JB, x, nb, k, A, B, p_k, p_A, p_B)
                else:
                    ok = fold_sweep_fixed_pair(D, X, JA, JB, x, nb, k, A, B, p_k, p_A, p_B)
                if not ok:
                    return False
                continue
        if t == REVOLUTE:
            ok = fold_sweep_revolute(D, X, JA, JB, x, nb, k, A, B)
        elif t == PRISMATIC:
            ok = fold_sweep_prismatic(D, X, JA, JB, x, nb, k, A, B)
        elif t == BALL:
            ok = fold_sweep_ball(D, X, JA, JB, x, nb, k, A, B)
        else:
            ok = fold_sweep_fixed(D, X, JA, JB, x, nb, k, A, B)
        if not ok:
            return False
    for idx in range(free.shape[0]):
        b = free[idx]
        if not _cholesky(D, b, 6):
            return False
        _forward(D, b, 6, x, b, 0)
        _backward(D, b, 6, x, b, 0)
    return True


@llvm_inlined
def sweep_down(model, work, x):
    """The forward half of the tree solve (children first), and the bodies no joint holds solved."""
    nb, kind, parent, child, order, free = model[0].shape[0], model[4], model[5], model[6], model[12], model[13]
    D, X = work[5], work[6]
    for idx in range(order.shape[0]):
        k = order[idx]
        A, B, t = parent[k], child[k], kind[k]
        if t == REVOLUTE:
            sweep_down_revolute(D, X, x, nb, k, A, B)
        elif t == PRISMATIC:
            sweep_down_prismatic(D, X, x, nb, k, A, B)
        elif t == BALL:
            sweep_down_ball(D, X, x, nb, k, A, B)
        else:
            sweep_down_fixed(D, X, x, nb, k, A, B)
    for idx in range(free.shape[0]):
        b = free[idx]
        _forward(D, b, 6, x, b, 0)
        _backward(D, b, 6, x, b, 0)


@llvm_inlined
def sweep_up(model, work, x):
    """The backward half of the tree solve (parents first): u and λ."""
    nb, kind, parent, child, order = model[0].shape[0], model[4], model[5], model[6], model[12]
    D, X = work[5], work[6]
    for idx in range(order.shape[0] - 1, -1, -1):
        k = order[idx]
        A, B, t = parent[k], child[k], kind[k]
        if t == REVOLUTE:
            sweep_up_revolute(D, X, x, nb, k, A, B)
        elif t == PRISMATIC:
            sweep_up_prismatic(D, X, x, nb, k, A, B)
        elif t == BALL:
            sweep_up_ball(D, X, x, nb, k, A, B)
        else:
            sweep_up_fixed(D, X, x, nb, k, A, B)


@llvm_inlined
def tree_solve(model, work, x):
    """Solve the factored system in place: x (nodes, 1, 6) holds the right side [f; c] on entry, [u; λ] on exit."""
    sweep_down(model, work, x)
    sweep_up(model, work, x)


# --- dynamics --------------------------------------------------------------------------------

@inlined
def _row_rate(y, model, JA, JB, k, r):
    """Ċ of row r of joint k: J u."""
    A, B = model[5][k], model[6][k]
    cdot = 0.0
    for c in range(6):
        if A >= 0:
            cdot += JA[k, r, c] * y[13 * A + 7 + c]
        cdot += JB[k, r, c] * y[13 * B + 7 + c]
    return cdot


@llvm_inlined
def forces(y, model, work):
    """work[7]'s body entries ← (m g, −ω × I_w ω) at y (R in work[0])."""
    mass, inertia, gravity, nb = model[0], model[1], model[2], model[0].shape[0]
    R, sol = work[0], work[7]
    for b in range(nb):
        o = 13 * b
        w0, w1, w2 = y[o + 10], y[o + 11], y[o + 12]
        # angular momentum I_w ω = R I_b Rᵀ ω (from R: D holds the factor once eliminated)
        l0 = R[b, 0, 0] * w0 + R[b, 1, 0] * w1 + R[b, 2, 0] * w2
        l1 = R[b, 0, 1] * w0 + R[b, 1, 1] * w1 + R[b, 2, 1] * w2
        l2 = R[b, 0, 2] * w0 + R[b, 1, 2] * w1 + R[b, 2, 2] * w2
        m0 = inertia[b, 0, 0] * l0 + inertia[b, 0, 1] * l1 + inertia[b, 0, 2] * l2
        m1 = inertia[b, 1, 0] * l0 + inertia[b, 1, 1] * l1 + inertia[b, 1, 2] * l2
        m2 = inertia[b, 2, 0] * l0 + inertia[b, 2, 1] * l1 + inertia[b, 2, 2] * l2
        L0, L1, L2 = _rot(R, b, m0, m1, m2)
        g0, g1, g2 = _cross(w0, w1, w2, L0, L1, L2)
        for r in range(3):
            sol[b, 0, r] = mass[b] * gravity[r]
        sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5] = -g0, -g1, -g2


@llvm_inlined
def row_targets(y, model, work, ks, kd):
    """work[7]'s joint entries ← −J̇u − k_s C − k_d J u (the rows' right side, Baumgarte's terms included)."""
    nb, kind, parent, child = model[0].shape[0], model[4], model[5], model[6]
    C, JA, JB, gam, sol = work[1], work[2], work[3], work[4], work[7]
    for k in range(kind.shape[0]):
        A, B, t = parent[k], child[k], kind[k]
        if t == REVOLUTE:  # written out per kind, J's zeros skipped (ours.rigid.generate)
            targets_revolute(y, C, JA, JB, gam, sol, nb, k, A, B, ks, kd)
        elif t == PRISMATIC:
            targets_prismatic(y, C, JA, JB, gam, sol, nb, k, A, B, ks, kd)
        elif t == BALL:
            targets_ball(y, C, JA, JB, gam, sol, nb, k, A, B, ks, kd)
        else:
            targets_fixed(y, C, JA, JB, gam, sol, nb, k, A, B, ks, kd)


@llvm_inlined
def rates(y, model, work, ydot):
    """ydot ← (v, ½ (0, ω) ⊗ Q, u̇) with u̇ from the solved work[7]; λ (nj, 6) into work[8]."""
    nb, rows, sol, lam = model[0].shape[0], model[11], work[7], work[8]
    for b in range(nb):
        o = 13 * b
        ydot[o], ydot[o + 1], ydot[o + 2] = y[o + 7], y[o + 8], y[o + 9]
        qw, qx, qy, qz = y[o + 3], y[o + 4], y[o + 5], y[o + 6]
        w0, w1, w2 = y[o + 10], y[o + 11], y[o + 12]
        ydot[o + 3] = -0.5 * (w0 * qx + w1 * qy + w2 * qz)
        c0, c1, c2 = _cross(w0, w1, w2, qx, qy, qz)
        ydot[o + 4] = 0.5 * (qw * w0 + c0)
        ydot[o + 5] = 0.5 * (qw * w1 + c1)
        ydot[o + 6] = 0.5 * (qw * w2 + c2)
        for r in range(6):
            ydot[o + 7 + r] = sol[b, 0, r]
    for k in range(rows.shape[0]):
        for r in range(rows[k]):
            lam[k, r] = -sol[nb + k, 0, r]


@llvm_inlined
def derivative(y, model, work, ks, kd, ydot):
    """ydot = (v, ½ (0, ω) ⊗ Q, u̇) at y; λ (nj, 6) in work[8]. Returns a status code."""
    nb, R = model[0].shape[0], work[0]
    rotations(y, nb, R)
    joint_rows(y, model, R, work[1], work[2], work[3], work[4])
    forces(y, model, work)
    row_targets(y, model, work, ks, kd)
    assemble(model, work)
    if not factor_and_sweep(model, work, work[7]):
        return SINGULAR
    sweep_up(model, work, work[7])
    rates(y, model, work, ydot)
    return OK


@inlined
def _rotate_quaternion(y, o, t0, t1, t2):
    """Q ← exp(θ/2) ⊗ Q for the world rotation vector θ = (t0, t1, t2), then Q normalised."""
    square = t0 * t0 + t1 * t1 + t2 * t2  # |θ|²
    if square.real > 0.0:
        x2 = 0.25 * square  # (|θ|/2)²
        if x2.real < SMALL_HALF_ANGLE_SQUARED:  # a step's turn: the series, exact to round-off, without sqrt, sin, cos
            s = 0.5 * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))))
            a0 = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)))
        else:
            angle = np.sqrt(square)
            s = np.sin(0.5 * angle) / angle
            a0 = np.cos(0.5 * angle)
        a1, a2, a3 = s * t0, s * t1, s * t2
        b0, b1, b2, b3 = y[o], y[o + 1], y[o + 2], y[o + 3]
        c1, c2, c3 = _cross(a1, a2, a3, b1, b2, b3)
        y[o] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3
        y[o + 1] = a0 * b1 + b0 * a1 + c1
        y[o + 2] = a0 * b2 + b0 * a2 + c2
        y[o + 3] = a0 * b3 + b0 * a3 + c3
    inverse = 1.0 / np.sqrt(y[o] ** 2 + y[o + 1] ** 2 + y[o + 2] ** 2 + y[o + 3] ** 2)
    for i in range(4):
        y[o + i] *= inverse


@llvm_inlined
def kick_drift(y, nb, ydot, h):
    """Symplectic Euler: u += h u̇, then x += h v and Q ← exp(h ω / 2) ⊗ Q, renormalised."""
    for b in range(nb):
        o = 13 * b
        for r in range(6):
            y[o + 7 + r] += h * ydot[o + 7 + r]
        for r in range(3):
            y[o + r] += h * y[o + 7 + r]
        _rotate_quaternion(y, o + 3, h * y[o + 10], h * y[o + 11], h * y[o + 12])


@llvm_inlined
def _correction(y, model, work, velocity, tolerance):
    """Returns max |e| with e = C (positions) or J u (velocity); when it exceeds ``tolerance``, also
    work[7] ← −W Jᵀ (J W Jᵀ)⁻¹ e for each body, through the factor in work (the tree system with no force
    and −e on the joints). A converged residual is not solved for: that solve would be thrown away."""
    nb, rows, C, JA, JB, sol = model[0].shape[0], model[11], work[1], work[2], work[3], work[7]
    for b in range(nb):
        for r in range(6):
            sol[b, 0, r] = 0.0
    worst = 0.0
    for k in range(rows.shape[0]):
        for r in range(rows[k]):
            e = _row_rate(y, model, JA, JB, k, r) if velocity else C[k, r]
            worst = max(worst, abs(e))
            sol[nb + k, 0, r] = -e
    if not worst <= tolerance:  # NaN too: solved, so it reaches the state and the step says non-finite
        tree_solve(model, work, sol)
    return worst


@llvm_inlined
def project(y, model, work, tolerance, max_iterations):
    """Positions onto C(q) = 0, then velocities onto J u = 0, both in the mass metric: Δ = −W Jᵀ (J W Jᵀ)⁻¹ e
    (e = C, rotations by the exponential map and quaternions renormalised; then e = J u), repeated until
    max |e| ≤ tolerance. J W Jᵀ is factored once, at the state the step arrived at (a chord method, as SHAKE
    does): the iterations cost a right-hand side and a solve each. Returns a status code."""
    nb, R, sol = model[0].shape[0], work[0], work[7]
    rotations(y, nb, R)
    joint_rows(y, model, R, work[1], work[2], work[3], work[4])
    if not tree_factor(y, model, work):
        return SINGULAR
    for velocity in (False, True):
        for it in range(max_iterations + 1):
            if it > 0 and not velocity:
                rotations(y, nb, R)
                joint_rows(y, model, R, work[1], work[2], work[3], work[4])
            worst = _correction(y, model, work, velocity, tolerance)
            if worst <= tolerance:
                break
            if it == max_iterations:
                return NOT_CONVERGED
            for b in range(nb):
                o = 13 * b
                if velocity:
                    for r in range(6):
                        y[o + 7 + r] += sol[b, 0, r]
                else:
                    for r in range(3):
                        y[o + r] += sol[b, 0, r]
                    _rotate_quaternion(y, o + 3, sol[b, 0, 3], sol[b, 0, 4], sol[b, 0, 5])
    return OK


@llvm_inlined
def step(method, code, A, bw, y, model, work, ks, kd, h, tolerance, max_iterations):
    """One step of h seconds in place; returns a status code. work[9] (stages, n), work[10] (n,) scratch."""
    nb = model[0].shape[0]
    K, ys = work[9], work[10]
    n = y.shape[0]
    if code == SYMPLECTIC_EULER:
        status = derivative(y, model, work, ks, kd, K[0])
        if status != OK:
            return status
        kick_drift(y, nb, K[0], h)
    else:
        s = bw.shape[0]
        for i in range(s):
            for e in range(n):
                ys[e] = y[e]
            for j in range(i):  # the tableau's zeros skipped (RK4's stages each read one K)
                a = h * A[i, j]
                if a != 0.0:
                    for e in range(n):
                        ys[e] += a * K[j, e]
            status = derivative(ys, model, work, ks, kd, K[i])
            if status != OK:
                return status
        for e in range(n):
            acc = 0.0
            for i in range(s):
                acc += bw[i] * K[i, e]
            y[e] += h * acc
    if method == PROJECTION:
        status = project(y, model, work, tolerance, max_iterations)
        if status != OK:
            return status
    spread = 0.0  # y − y is 0 for a finite number and NaN for inf or NaN: one reduction the compiler vectorises
    for e in range(n):
        spread += y[e] - y[e]
    if spread != 0.0:
        return NON_FINITE
    return OK


@compiled
def run(method, code, A, bw, y, model, work, ks, kd, h, n_steps, stride, tolerance, max_iterations, out):
    """Step n_steps times; out (samples, n) gets y at step 0, every stride steps and the last.
    Returns (samples written, steps taken, status)."""
    n = y.shape[0]
    for e in range(n):
        out[0, e] = y[e]
    written = 1
    for s in range(1, n_steps + 1):
        status = step(method, code, A, bw, y, model, work, ks, kd, h, tolerance, max_iterations)
        if status != OK:
            return written, s - 1, status
        if s % stride == 0 or s == n_steps:
            for e in range(n):
                out[written, e] = y[e]
            written += 1
    return written, n_steps, OK
