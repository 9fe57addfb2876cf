"""The reference's compiled right-hand side (numba), in its own module so that importing
``engines.reference.reference`` (as ``xval engines`` does) neither imports numba nor compiles anything."""

from __future__ import annotations

from ours.cache import configure_numba

configure_numba()  # numba's cache in the user cache directory, before numba is imported

import numba  # noqa: E402
import numpy as np  # noqa: E402


@numba.njit(cache=True)
def chain_accelerations(theta, theta_dot, inertia, weight, gx, gz):  # pragma: no cover - compiled
    """θ̈ (n,) solving M θ̈ = G − S θ̇² by Cholesky (M is symmetric positive definite).

    Compiled because DOP853 at 1e-12 calls it ~10⁵ times per scene and numpy's
    per-call overhead on 2×2 arrays is ~15× the arithmetic.
    """
    n = theta.shape[0]
    m = np.empty((n, n))
    b = np.empty(n)
    for i in range(n):
        r = weight[i] * (gx * np.cos(theta[i]) + gz * np.sin(theta[i]))
        for j in range(n):
            d = theta[i] - theta[j]
            m[i, j] = inertia[i, j] * np.cos(d)
            r -= inertia[i, j] * np.sin(d) * theta_dot[j] ** 2
        b[i] = r
    # In-place Cholesky M = L Lᵀ (lower triangle), then two triangular solves.
    for j in range(n):
        s = m[j, j]
        for k in range(j):
            s -= m[j, k] * m[j, k]
        m[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = m[i, j]
            for k in range(j):
                s -= m[i, k] * m[j, k]
            m[i, j] = s / m[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= m[i, k] * b[k]
        b[i] = s / m[i, i]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, n):
            s -= m[k, i] * b[k]
        b[i] = s / m[i, i]
    return b


@numba.njit(cache=True)
def chain_rhs(y, inertia, weight, gx, gz):  # pragma: no cover - compiled
    """dy/dt (2n,) for y = (θ, θ̇) (2n,)."""
    n = y.shape[0] // 2
    out = np.empty(2 * n)
    theta_ddot = chain_accelerations(y[:n], y[n:], inertia, weight, gx, gz)
    # Element by element: a slice assignment (out[:n] = y[n:]) made numba compile its general array
    # copy, most of this function's compile time (part of bench/bench_ours.py's cold compile).
    for i in range(n):
        out[i] = y[n + i]
        out[n + i] = theta_ddot[i]
    return out
