"""The tangent-linear step of the reduced-coordinate chain (``ours.lagrangian``), k directions carried beside it.

Each step runs ``ours.lagrangian``'s stages (its state is ``run``'s bit for bit); each direction pays for its
derivative alone: dθ̈ = M⁻¹ (ds − dM θ̈) with the mass matrix's Cholesky factor of the stage. A direction moves
(θ, θ̇) and, for g, masses and lengths, the chain's arrays (tail, lengths, gravity, anchor). The maps between
Cartesian states and angles are differentiated in closed form (numpy).

Shapes: k directions, n links. dtheta, domega : (k, n); d_tail, d_lengths : (k, n); d_gravity : (k, 2).
"""

from __future__ import annotations

import math

import numpy as np

from ours.banded import compiled, llvm_inlined, solve_banded
from ours.lagrangian import _finite, angular_acceleration
from ours.status import NON_FINITE, OK, SINGULAR


@llvm_inlined
def acceleration_tangent(theta, omega, dtheta, domega, tail, lengths, gravity, d_tail, d_lengths, d_gravity, M,
                         alpha, dalpha):
    """dθ̈ (k-th direction's, (n,)) after :func:`angular_acceleration` at (θ, θ̇) left θ̈ in ``alpha`` and the
    mass matrix's Cholesky factor in M: the derivative of each term of its right side s and of M, then
    dθ̈ = M⁻¹ (ds − dM θ̈) by the factor."""
    n = theta.shape[0]
    for i in range(n):
        c, s = math.cos(theta[i]), math.sin(theta[i])
        weight = tail[i] * lengths[i]
        d_weight = d_tail[i] * lengths[i] + tail[i] * d_lengths[i]
        total = d_weight * (gravity[0] * c + gravity[1] * s) + weight * (
            d_gravity[0] * c + d_gravity[1] * s + (gravity[1] * c - gravity[0] * s) * dtheta[i])
        for j in range(n):
            m = max(i, j)
            mu = tail[m] * lengths[i] * lengths[j]
            d_mu = d_tail[m] * lengths[i] * lengths[j] + tail[m] * (d_lengths[i] * lengths[j]
                                                                    + lengths[i] * d_lengths[j])
            sd, cd = math.sin(theta[i] - theta[j]), math.cos(theta[i] - theta[j])
            d_angle = dtheta[i] - dtheta[j]
            total -= (d_mu * sd + mu * cd * d_angle) * omega[j] * omega[j] + 2.0 * mu * sd * omega[j] * domega[j]
            total -= (d_mu * cd - mu * sd * d_angle) * alpha[j]
        dalpha[i] = total
    solve_banded(M, n, n - 1, dalpha)


@llvm_inlined
def stage(A, h, i, theta, omega, Kt, Kw, ts, ws):
    """Stage i of ``ours.lagrangian.run`` on (θ, θ̇) or a direction's (dθ, dθ̇), element by element with run's
    arithmetic in run's order (bit for bit): ts = θ + h Σ_j A_ij Kt_j, ws likewise, Kt_i = ws."""
    for k in range(theta.shape[0]):
        angle, rate = theta[k], omega[k]
        for j in range(i):
            if A[i, j] != 0.0:
                angle += h * A[i, j] * Kt[j, k]
                rate += h * A[i, j] * Kw[j, k]
        ts[k], ws[k], Kt[i, k] = angle, rate, rate


@llvm_inlined
def combine(b, h, theta, omega, Kt, Kw):
    """θ += h Σ_i b_i Kt_i and θ̇ += h Σ_i b_i Kw_i, element by element in run's order of i."""
    for k in range(theta.shape[0]):
        for i in range(b.shape[0]):
            theta[k] += h * b[i] * Kt[i, k]
            omega[k] += h * b[i] * Kw[i, k]


@compiled
def run_tangent(A, b, theta, omega, tail, lengths, gravity, work, dt, n_steps, dtheta, domega, d_tail, d_lengths,
                d_gravity, tangent_work):
    """``ours.lagrangian.run``'s steps without its samples, on (θ, θ̇) in place, with the directions dθ, dθ̇
    (k, n) carried along in place. Returns (steps taken, status)."""
    M, Kt, Kw, ts, ws = work
    dKt, dKw, dts, dws = tangent_work
    h = dt
    for step in range(n_steps):
        status = OK
        for i in range(b.shape[0]):
            stage(A, h, i, theta, omega, Kt, Kw, ts, ws)
            if not angular_acceleration(ts, ws, tail, lengths, gravity, M, Kw[i]):
                status = SINGULAR
            for d in range(dtheta.shape[0]):
                stage(A, h, i, dtheta[d], domega[d], dKt[d], dKw[d], dts, dws)
                acceleration_tangent(ts, ws, dts, dws, tail, lengths, gravity, d_tail[d], d_lengths[d],
                                     d_gravity[d], M, Kw[i], dKw[d, i])
        combine(b, h, theta, omega, Kt, Kw)
        for d in range(dtheta.shape[0]):
            combine(b, h, dtheta[d], domega[d], dKt[d], dKw[d])
        if not (_finite(theta) and _finite(omega)):
            status = NON_FINITE
        if status != OK:
            return step + 1, status
    return n_steps, OK


def tangent_workspace(k: int, n: int, stages: int) -> tuple:
    """Scratch of :func:`run_tangent` for k directions."""
    return np.zeros((k, stages, n)), np.zeros((k, stages, n)), np.zeros(n), np.zeros(n)


def coordinates_tangent(q0, v0, dq0, dv0, anchor, d_anchor) -> tuple[np.ndarray, np.ndarray]:
    """(dθ, dθ̇) (k, n) of ``ours.lagrangian.chain_coordinates`` along (dq0, dv0) (k, n, 2) and d_anchor (k, 2):
    θ = atan2(d_x, −d_y), θ̇ = (d × ḋ) / ‖d‖², d the link's vector, differentiated."""
    base_q = np.concatenate([np.broadcast_to(anchor, (1, 2)), q0[:-1]])
    base_v = np.concatenate([np.zeros((1, 2)), v0[:-1]])
    d, dd = q0 - base_q, v0 - base_v  # (n, 2)
    d_d = dq0 - np.concatenate([d_anchor[:, None, :], dq0[:, :-1]], axis=1)  # (k, n, 2)
    d_dd = dv0 - np.concatenate([np.zeros_like(dv0[:, :1]), dv0[:, :-1]], axis=1)
    norm2 = (d * d).sum(axis=-1)
    cross = d[:, 0] * dd[:, 1] - d[:, 1] * dd[:, 0]
    dtheta = (d[:, 0] * d_d[..., 1] - d[:, 1] * d_d[..., 0]) / norm2
    d_cross = d_d[..., 0] * dd[:, 1] + d[:, 0] * d_dd[..., 1] - d_d[..., 1] * dd[:, 0] - d[:, 1] * d_dd[..., 0]
    domega = d_cross / norm2 - cross * 2.0 * (d * d_d).sum(axis=-1) / norm2**2
    return dtheta, domega


def cartesian_tangent(theta, omega, dtheta, domega, lengths, d_lengths, d_anchor) -> tuple[np.ndarray, np.ndarray]:
    """(dq, dv) (k, n, 2) of ``ours.lagrangian.to_cartesian`` along (dθ, dθ̇, d lengths, d anchor)."""
    s, c = np.sin(theta), np.cos(theta)
    dq = np.stack([d_lengths * s + lengths * c * dtheta, -d_lengths * c + lengths * s * dtheta], axis=-1)
    dv = np.stack([(d_lengths * omega + lengths * domega) * c - lengths * omega * s * dtheta,
                   (d_lengths * omega + lengths * domega) * s + lengths * omega * c * dtheta], axis=-1)
    return np.cumsum(dq, axis=1) + d_anchor[:, None, :], np.cumsum(dv, axis=1)
