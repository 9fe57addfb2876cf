"""Closed-form answers the numerical results are checked against.

Angles in radians here (the catalog's degrees are converted by callers).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import eigh
from scipy.special import ellipk


def pendulum_period(length: float, g: float, amplitude: float) -> float:
    """Exact period (s) of a simple pendulum of ``length`` (m) swinging to ``amplitude`` (rad) under ``g`` (m/s²).

    T = 4·sqrt(L/g)·K(k²) with k = sin(θ0/2) and K the complete elliptic
    integral of the first kind (scipy's ``ellipk`` takes the parameter m = k²).
    """
    if not 0 < abs(amplitude) < math.pi:
        raise ValueError(f"amplitude must be in (0, π) rad for an oscillation, got {amplitude}")
    return 4.0 * math.sqrt(length / g) * float(ellipk(math.sin(abs(amplitude) / 2.0) ** 2))


def chain_mass_matrix(masses, lengths) -> np.ndarray:
    """(n, n) kg·m²: the planar chain's mass matrix at rest, M_ij = μ_ij·l_i·l_j, μ_ij = Σ_{k ≥ max(i,j)} m_k.

    In absolute angles θ_i (each link measured from the downward vertical).
    """
    m = np.asarray(masses, dtype=float)
    l = np.asarray(lengths, dtype=float)
    tail = np.cumsum(m[::-1])[::-1]  # tail[i] = Σ_{k ≥ i} m_k
    mu = tail[np.maximum.outer(np.arange(len(m)), np.arange(len(m)))]
    return mu * np.outer(l, l)


def normal_modes(masses, lengths, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Small-oscillation normal modes of a planar chain of point masses hung from a fixed point.

    masses : (n,) kg; lengths : (n,) m (link i joins particle i−1, or the
    anchor, to particle i); g : m/s².
    Returns (omegas, shapes): omegas (n,) rad/s ascending; shapes (n, n), column
    j the mode's absolute link angles, scaled so its largest entry is +1.

    Linearized Lagrange equations M θ̈ + K θ = 0 with M from
    :func:`chain_mass_matrix` and K = diag(g·l_i·Σ_{k ≥ i} m_k); solved as the
    generalized symmetric eigenproblem K v = ω² M v.
    """
    m = np.asarray(masses, dtype=float)
    l = np.asarray(lengths, dtype=float)
    tail = np.cumsum(m[::-1])[::-1]
    stiffness = np.diag(g * l * tail)
    eigenvalues, vectors = eigh(stiffness, chain_mass_matrix(m, l))
    shapes = vectors / vectors[np.argmax(np.abs(vectors), axis=0), np.arange(len(m))]
    return np.sqrt(eigenvalues), shapes
