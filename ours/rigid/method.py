"""Which drift cures and integrators rigid bodies offer, and why the others are refused.

Methods: plain (J u̇ = −J̇u), baumgarte (+ k_s C + k_d Ċ), projection (a step, then Newton on
C(q) = 0 in the mass metric with the quaternions renormalised, then u onto J u = 0).
Integrators: euler, midpoint, rk4 (explicit Runge–Kutta on (x, Q, v, ω), the quaternion's ODE
Q̇ = ½ (0, ω) ⊗ Q integrated in R⁴), symplectic-euler (kick, then drift on SO(3) by the exponential
map). RATTLE and the Lagrangian form of the particle solver are refused (``resolve``'s messages say why).
"""

from __future__ import annotations

from ours.errors import InvalidPair, OursError
from ours.integrator import EXPLICIT_RK, SYMPLECTIC_EULER, Integrator, get_integrator

PLAIN, BAUMGARTE, PROJECTION = 0, 1, 2
METHODS = {"plain": PLAIN, "baumgarte": BAUMGARTE, "projection": PROJECTION}
INTEGRATORS = ("euler", "symplectic-euler", "midpoint", "rk4")

WHY_NOT_RATTLE = (
    "RATTLE is not offered for rigid bodies: its drift step needs a constant mass matrix, and a "
    "body's world inertia R I Rᵀ turns with it (the kinetic energy is not separable in (x, Q)); "
    "use method='projection' with integrator='symplectic-euler' (kick, exponential-map drift, "
    "projection of positions and velocities) or 'rk4'"
)


def resolve(method: str, integrator: str | None) -> tuple[int, Integrator]:
    """(method code, integrator record); InvalidPair / OursError with the reason otherwise."""
    if method == "rattle" or integrator == "rattle":
        raise InvalidPair(WHY_NOT_RATTLE)
    if method == "lagrangian":
        raise InvalidPair("method 'lagrangian' (reduced coordinates of a planar particle chain) does not apply to "
                          "rigid bodies; ours' rigid bodies are in maximal coordinates: plain, baumgarte or projection")
    if method not in METHODS:
        raise OursError(f"method: unknown {method!r}; choose one of: {', '.join(METHODS)}")
    scheme = get_integrator(integrator or "rk4")
    assert scheme.code in (EXPLICIT_RK, SYMPLECTIC_EULER)
    return METHODS[method], scheme


def valid_pairs() -> list[tuple[str, str]]:
    """Every (method, integrator) pair rigid bodies accept: each method with each integrator."""
    return [(m, i) for m in METHODS for i in INTEGRATORS]
