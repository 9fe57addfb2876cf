"""Hand-fused yardsticks: ours' equations for one scene written as one loop over scalars.

These are what the machine can do for the same arithmetic; ``bench_ours.py``
times ours against them in the same run. Each kernel follows the operation
order of ``ours.kernel`` so that its trajectory matches ours' to round-off
(checked by the bench before it times anything).

* :func:`double_pendulum_rk4` — maximal coordinates (x₁, x₂ in the plane),
  Pin(0, a, l₁) and Rod(0, 1, l₂), multipliers from the 2×2 J W Jᵀ (Cholesky),
  Baumgarte feedback (k_s, k_d), classic RK4.
* :func:`double_pendulum_rattle` — the same system stepped by RATTLE (SHAKE
  iteration with J_n W J_nᵀ factored once per step, then the velocity
  projection), as ``ours.kernel.rattle_step`` does.

Both step ``n_steps`` times in place on q (2, 2), v (2, 2) and record nothing
(ours records a sample every ``stride`` steps; at dt 1e-4 and a 10 ms
interval that is one sample per 100 steps).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def _accel(x0, y0, x1, y1, u0, w0, u1, w1, ax, ay, w_0, w_1, fx0, fy0, fx1, fy1, L1sq, L2sq,
           b00w, b10w, b11w, ks, kd):
    """Accelerations (m/s²) of both particles under Pin(0, a) and Rod(0, 1)."""
    # constraint vectors and relative velocities
    d0x = x0 - ax
    d0y = y0 - ay
    d1x = x0 - x1
    d1y = y0 - y1
    v0x = u0
    v0y = w0
    v1x = u0 - u1
    v1y = w0 - w1
    # right-hand side
    jwf0 = d0x * (w_0 * fx0) + d0y * (w_0 * fy0)
    jwf1 = d1x * (w_0 * fx0 - w_1 * fx1) + d1y * (w_0 * fy0 - w_1 * fy1)
    c0 = 0.5 * ((d0x * d0x + d0y * d0y) - L1sq)
    c1 = 0.5 * ((d1x * d1x + d1y * d1y) - L2sq)
    cd0 = d0x * v0x + d0y * v0y
    cd1 = d1x * v1x + d1y * v1y
    r0 = -(v0x * v0x + v0y * v0y) - jwf0 - ks * c0 - kd * cd0
    r1 = -(v1x * v1x + v1y * v1y) - jwf1 - ks * c1 - kd * cd1
    # J W Jᵀ (lower band) and its Cholesky factor
    a00 = b00w * (d0x * d0x + d0y * d0y)
    a10 = b10w * (d1x * d0x + d1y * d0y)
    a11 = b11w * (d1x * d1x + d1y * d1y)
    l00 = math.sqrt(a00)
    l10 = a10 / l00
    l11 = math.sqrt(a11 - l10 * l10)
    z0 = r0 / l00
    z1 = (r1 - l10 * z0) / l11
    lam1 = z1 / l11
    lam0 = (z0 - l10 * lam1) / l00
    # W (f + Jᵀλ)
    a0x = w_0 * fx0 + w_0 * lam0 * d0x + w_0 * lam1 * d1x
    a0y = w_0 * fy0 + w_0 * lam0 * d0y + w_0 * lam1 * d1y
    a1x = w_1 * fx1 - w_1 * lam1 * d1x
    a1y = w_1 * fy1 - w_1 * lam1 * d1y
    return a0x, a0y, a1x, a1y


@njit(cache=True)
def double_pendulum_rk4(q, v, masses, gravity, anchor, lengths, ks, kd, h, n_steps):
    """Baumgarte + RK4 on the double pendulum, ``n_steps`` steps of ``h`` s, q and v (2, 2) in place."""
    w_0 = 1.0 / masses[0]
    w_1 = 1.0 / masses[1]
    fx0, fy0 = masses[0] * gravity[0], masses[0] * gravity[1]
    fx1, fy1 = masses[1] * gravity[0], masses[1] * gravity[1]
    ax, ay = anchor[0], anchor[1]
    L1sq, L2sq = lengths[0] ** 2, lengths[1] ** 2
    b00w, b10w, b11w = 0.0 + w_0, 0.0 + w_0, (0.0 + w_0) + w_1
    x0, y0, x1, y1 = q[0, 0], q[0, 1], q[1, 0], q[1, 1]
    u0, w0, u1, w1 = v[0, 0], v[0, 1], v[1, 0], v[1, 1]
    hh = 0.5 * h
    for _ in range(n_steps):
        k1a = _accel(x0, y0, x1, y1, u0, w0, u1, w1, ax, ay, w_0, w_1, fx0, fy0, fx1, fy1, L1sq, L2sq,
                     b00w, b10w, b11w, ks, kd)
        q2 = (x0 + hh * u0, y0 + hh * w0, x1 + hh * u1, y1 + hh * w1)
        v2 = (u0 + hh * k1a[0], w0 + hh * k1a[1], u1 + hh * k1a[2], w1 + hh * k1a[3])
        k2a = _accel(q2[0], q2[1], q2[2], q2[3], v2[0], v2[1], v2[2], v2[3], ax, ay, w_0, w_1, fx0, fy0,
                     fx1, fy1, L1sq, L2sq, b00w, b10w, b11w, ks, kd)
        q3 = (x0 + hh * v2[0], y0 + hh * v2[1], x1 + hh * v2[2], y1 + hh * v2[3])
        v3 = (u0 + hh * k2a[0], w0 + hh * k2a[1], u1 + hh * k2a[2], w1 + hh * k2a[3])
        k3a = _accel(q3[0], q3[1], q3[2], q3[3], v3[0], v3[1], v3[2], v3[3], ax, ay, w_0, w_1, fx0, fy0,
                     fx1, fy1, L1sq, L2sq, b00w, b10w, b11w, ks, kd)
        q4 = (x0 + h * v3[0], y0 + h * v3[1], x1 + h * v3[2], y1 + h * v3[3])
        v4 = (u0 + h * k3a[0], w0 + h * k3a[1], u1 + h * k3a[2], w1 + h * k3a[3])
        k4a = _accel(q4[0], q4[1], q4[2], q4[3], v4[0], v4[1], v4[2], v4[3], ax, ay, w_0, w_1, fx0, fy0,
                     fx1, fy1, L1sq, L2sq, b00w, b10w, b11w, ks, kd)
        b1, b2 = h * (1.0 / 6.0), h * (1.0 / 3.0)
        x0 = x0 + b1 * u0 + b2 * v2[0] + b2 * v3[0] + b1 * v4[0]
        y0 = y0 + b1 * w0 + b2 * v2[1] + b2 * v3[1] + b1 * v4[1]
        x1 = x1 + b1 * u1 + b2 * v2[2] + b2 * v3[2] + b1 * v4[2]
        y1 = y1 + b1 * w1 + b2 * v2[3] + b2 * v3[3] + b1 * v4[3]
        u0 = u0 + b1 * k1a[0] + b2 * k2a[0] + b2 * k3a[0] + b1 * k4a[0]
        w0 = w0 + b1 * k1a[1] + b2 * k2a[1] + b2 * k3a[1] + b1 * k4a[1]
        u1 = u1 + b1 * k1a[2] + b2 * k2a[2] + b2 * k3a[2] + b1 * k4a[2]
        w1 = w1 + b1 * k1a[3] + b2 * k2a[3] + b2 * k3a[3] + b1 * k4a[3]
    q[0, 0], q[0, 1], q[1, 0], q[1, 1] = x0, y0, x1, y1
    v[0, 0], v[0, 1], v[1, 0], v[1, 1] = u0, w0, u1, w1


@njit(cache=True)
def double_pendulum_rattle(q, v, masses, gravity, anchor, lengths, tolerance, max_iterations, h, n_steps):
    """RATTLE on the double pendulum, ``n_steps`` steps of ``h`` s, q and v (2, 2) in place.

    Returns the number of steps taken (fewer when the SHAKE iteration did not converge).
    """
    w_0 = 1.0 / masses[0]
    w_1 = 1.0 / masses[1]
    fx0, fy0 = masses[0] * gravity[0], masses[0] * gravity[1]
    fx1, fy1 = masses[1] * gravity[0], masses[1] * gravity[1]
    ax, ay = anchor[0], anchor[1]
    L1sq, L2sq = lengths[0] ** 2, lengths[1] ** 2
    b00w, b10w, b11w = 0.0 + w_0, 0.0 + w_0, (0.0 + w_0) + w_1
    x0, y0, x1, y1 = q[0, 0], q[0, 1], q[1, 0], q[1, 1]
    u0, w0, u1, w1 = v[0, 0], v[0, 1], v[1, 0], v[1, 1]
    hh2 = 0.5 * h * h
    for step in range(n_steps):
        # J_n W J_nᵀ from the old constraint directions, factored once
        e0x, e0y, e1x, e1y = x0 - ax, y0 - ay, x0 - x1, y0 - y1
        l00 = math.sqrt(b00w * (e0x * e0x + e0y * e0y))
        l10 = b10w * (e1x * e0x + e1y * e0y) / l00
        l11 = math.sqrt(b11w * (e1x * e1x + e1y * e1y) - l10 * l10)
        n0x = x0 + h * u0 + hh2 * w_0 * fx0
        n0y = y0 + h * w0 + hh2 * w_0 * fy0
        n1x = x1 + h * u1 + hh2 * w_1 * fx1
        n1y = y1 + h * w1 + hh2 * w_1 * fy1
        Lam0 = 0.0
        Lam1 = 0.0
        converged = False
        for _ in range(max_iterations + 1):
            d0x, d0y, d1x, d1y = n0x - ax, n0y - ay, n0x - n1x, n0y - n1y
            c0 = 0.5 * ((d0x * d0x + d0y * d0y) - L1sq)
            c1 = 0.5 * ((d1x * d1x + d1y * d1y) - L2sq)
            if max(0.0, abs(c0) / L1sq, abs(c1) / L2sq) <= tolerance:
                converged = True
                break
            z0 = -c0 / l00
            z1 = (-c1 - l10 * z0) / l11
            g1 = z1 / l11
            g0 = (z0 - l10 * g1) / l00
            Lam0 += g0
            Lam1 += g1
            n0x += w_0 * g0 * e0x + w_0 * g1 * e1x
            n0y += w_0 * g0 * e0y + w_0 * g1 * e1y
            n1x -= w_1 * g1 * e1x
            n1y -= w_1 * g1 * e1y
        if not converged:
            return step
        ih = 1.0 / h
        u0 += h * w_0 * fx0 + ih * w_0 * Lam0 * e0x + ih * w_0 * Lam1 * e1x
        w0 += h * w_0 * fy0 + ih * w_0 * Lam0 * e0y + ih * w_0 * Lam1 * e1y
        u1 += h * w_1 * fx1 - ih * w_1 * Lam1 * e1x
        w1 += h * w_1 * fy1 - ih * w_1 * Lam1 * e1y
        x0, y0, x1, y1 = n0x, n0y, n1x, n1y
        # project v onto J(q_{n+1}) v = 0
        d0x, d0y, d1x, d1y = x0 - ax, y0 - ay, x0 - x1, y0 - y1
        m00 = math.sqrt(b00w * (d0x * d0x + d0y * d0y))
        m10 = b10w * (d1x * d0x + d1y * d0y) / m00
        m11 = math.sqrt(b11w * (d1x * d1x + d1y * d1y) - m10 * m10)
        z0 = (d0x * u0 + d0y * w0) / m00
        z1 = ((d1x * (u0 - u1) + d1y * (w0 - w1)) - m10 * z0) / m11
        mu1 = z1 / m11
        mu0 = (z0 - m10 * mu1) / m00
        u0 -= w_0 * mu0 * d0x + w_0 * mu1 * d1x
        w0 -= w_0 * mu0 * d0y + w_0 * mu1 * d1y
        u1 += w_1 * mu1 * d1x
        w1 += w_1 * mu1 * d1y
    q[0, 0], q[0, 1], q[1, 0], q[1, 1] = x0, y0, x1, y1
    v[0, 0], v[0, 1], v[1, 0], v[1, 1] = u0, w0, u1, w1
    return n_steps
