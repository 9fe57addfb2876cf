"""Linear stability theory of Baumgarte feedback under ours' integrators (derived in docs/ours.md).

Near the constraint manifold the constraint error x = (C, Ċ) obeys the
linear system ẋ = A x, A = [[0, 1], [−k_s, −k_d]] (eigenvalues
λ = (−k_d ± √(k_d² − 4 k_s))/2), plus forcing from the motion that does
not change stability. One step of an explicit Runge–Kutta method maps x to
R(hA) x, R the method's stability polynomial (R(z) = 1 + Σⱼ zʲ bᵀAʲ⁻¹𝟙 from
its Butcher table, so the theory uses exactly the table ours steps with);
symplectic Euler (kick, then drift with the new velocity) maps it to
M = [[1 − h²k_s, h(1 − h k_d)], [−h k_s, 1 − h k_d]]. The feedback is
stable when the spectral radius ρ of that step matrix is ≤ 1.

Details: docs/ours.md, "Module notes", ``ours/stability.py``.
"""

from __future__ import annotations

import math

import numpy as np

from ours.integrator import EXPLICIT_RK, get_integrator

#: Integrators the theory covers (RATTLE is not a Baumgarte integrator).
INTEGRATORS = ("euler", "symplectic-euler", "midpoint", "rk4")
#: ρ ≤ 1 + this counts as stable (round-off; small enough that undamped Euler, ρ = 1 + (ωh)²/2, is unstable at h = 1e-4/ω).
RHO_SLACK = 1e-12


# -- theory ----------------------------------------------------------------------------------


def stability_polynomial(integrator: str) -> np.ndarray:
    """Coefficients c₀..c_s (ascending powers of z) of R(z) for an explicit RK integrator of ours.

    R(z) = 1 + Σ_{j≥1} zʲ · bᵀ A^{j−1} 𝟙 (A strictly lower triangular, so the sum stops at j = stages).
    """
    scheme = get_integrator(integrator)
    if scheme.code != EXPLICIT_RK:
        raise ValueError(f"{integrator} is not an explicit Runge–Kutta method")
    ones = np.ones(scheme.stages)
    coefficients = [1.0]
    power = ones
    for _ in range(scheme.stages):
        coefficients.append(float(scheme.b @ power))
        power = scheme.A @ power
    return np.array(coefficients)


def step_matrix(integrator: str, h: float, k_s: float, k_d: float) -> np.ndarray:
    """(2, 2): one step of the linearized constraint error (C, Ċ) under ``integrator`` with step h (s).

    k_s : 1/s², k_d : 1/s.
    """
    if integrator == "symplectic-euler":
        return np.array([[1.0 - h * h * k_s, h * (1.0 - h * k_d)], [-h * k_s, 1.0 - h * k_d]])
    hA = h * np.array([[0.0, 1.0], [-k_s, -k_d]])
    result, power = np.zeros((2, 2)), np.eye(2)
    for c in stability_polynomial(integrator):
        result += c * power
        power = power @ hA
    return result


def spectral_radius(integrator: str, h: float, k_s: float, k_d: float) -> float:
    """ρ of :func:`step_matrix`: the factor the constraint error grows by per step (asymptotically)."""
    return float(np.abs(np.linalg.eigvals(step_matrix(integrator, h, k_s, k_d))).max())


def theory_stable(integrator: str, h: float, k_s: float, k_d: float) -> bool:
    return spectral_radius(integrator, h, k_s, k_d) <= 1.0 + RHO_SLACK


def largest_stable_dt(integrator: str, k_s: float, k_d: float, h_max: float = 10.0) -> float | None:
    """s: the largest h with ρ ≤ 1 (on the connected stable range from h → 0), to 1e-6 relative.

    None when even the smallest h is unstable (k_d = 0 with Euler: |1 + iωh| > 1 for every h).
    """
    if integrator not in INTEGRATORS:
        return None
    scale = 1.0 / max(math.sqrt(k_s), k_d, 1e-12)  # the feedback's own time scale
    h = 1e-4 * scale
    if not theory_stable(integrator, h, k_s, k_d):
        return None
    lo = h
    hi = lo
    while theory_stable(integrator, hi, k_s, k_d):
        lo, hi = hi, hi * 1.5
        if hi > h_max:
            return h_max
    while hi / lo > 1 + 1e-6:
        mid = math.sqrt(lo * hi)
        if theory_stable(integrator, mid, k_s, k_d):
            lo = mid
        else:
            hi = mid
    return lo


def critical_limit(integrator: str) -> float | None:
    """h·√k_s at the stability limit for critical damping (k_d = 2√k_s), from the theory (dimensionless);
    None for an integrator the theory does not cover."""
    return largest_stable_dt(integrator, 1.0, 2.0)
