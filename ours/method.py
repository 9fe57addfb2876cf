"""Drift cures (methods), their default gains, and which integrators each pairs with.

Every method solves the same constrained dynamics; they differ in how they
keep the state on C(q) = 0:

plain       : enforce C̈ = 0 only; the error in C and Ċ integrates freely (drifts).
baumgarte   : enforce C̈ + k_d Ċ + k_s C = 0, so an error decays like a damped spring.
projection  : step as plain, then move q back onto C = 0 (Newton, mass-weighted)
              and q̇ onto J q̇ = 0.
rattle      : RATTLE is its own integrator: constraints are solved inside the step.
lagrangian  : reduced coordinates (link angles) of a planar chain; C = 0 by construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ours.errors import InvalidPair, OursError
from ours.integrator import INTEGRATORS, RATTLE, SYMPLECTIC_EULER, Integrator, get_integrator

#: Baumgarte stiffness k_s, 1/s². √k_s = 10 rad/s: a correction time constant of
#: 0.1 s, faster than the pendulum motions of the catalog (periods ≥ 1 s) yet
#: h·√k_s ≤ 0.1 for any dt ≤ 10 ms, so the feedback never limits the step.
DEFAULT_K_S = 100.0


def critical_damping(k_s: float) -> float:
    """The default Baumgarte damping k_d = 2·√k_s (1/s): critical damping, the fastest decay without overshoot."""
    return 2.0 * math.sqrt(k_s)


#: Newton / SHAKE stopping rule: |C_k| / l_k² ≤ tolerance (≈ relative length error).
DEFAULT_TOLERANCE = 1e-12
DEFAULT_MAX_ITERATIONS = 50

PLAIN, BAUMGARTE, PROJECTION, RATTLE_METHOD, LAGRANGIAN = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class Method:
    name: str
    code: int
    default_integrator: str
    doc: str


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("plain", PLAIN, "rk4", "C̈ = 0 only; drifts."),
        Method("baumgarte", BAUMGARTE, "rk4", "C̈ + k_d Ċ + k_s C = 0."),
        Method("projection", PROJECTION, "rk4", "plain step, then project q and q̇ onto the constraints."),
        Method("rattle", RATTLE_METHOD, "rattle", "the RATTLE scheme (its own integrator)."),
        Method("lagrangian", LAGRANGIAN, "rk4", "reduced coordinates of a planar chain."),
    )
}


def resolve_pair(method: str, integrator: str | None) -> tuple[Method, Integrator]:
    """The method and integrator records; InvalidPair when they do not go together (never a fallback)."""
    if method not in METHODS:
        raise OursError(f"method: unknown {method!r}; choose one of: {', '.join(METHODS)}")
    chosen = METHODS[method]
    scheme = get_integrator(integrator or chosen.default_integrator)
    if chosen.code == RATTLE_METHOD and scheme.code != RATTLE:
        raise InvalidPair(
            f"method 'rattle' is its own integrator (RATTLE: order 2, symplectic) and cannot use "
            f"{scheme.name!r}; pass integrator='rattle' or leave it out"
        )
    if chosen.code != RATTLE_METHOD and scheme.code == RATTLE:
        raise InvalidPair(
            f"integrator 'rattle' solves the constraints itself; use it with method='rattle', not {method!r}"
        )
    if chosen.code == LAGRANGIAN and scheme.code == SYMPLECTIC_EULER:
        raise InvalidPair(
            "method 'lagrangian' cannot use 'symplectic-euler': a chain's mass matrix depends on its angles, so "
            "the Hamiltonian is not separable and semi-implicit Euler would not be symplectic; "
            "use 'euler', 'midpoint' or 'rk4'"
        )
    return chosen, scheme


def valid_pairs() -> list[tuple[str, str]]:
    """Every (method, integrator) pair :func:`resolve_pair` accepts."""
    pairs = []
    for m in METHODS:
        for i in INTEGRATORS:
            try:
                resolve_pair(m, i)
            except InvalidPair:
                continue
            pairs.append((m, i))
    return pairs
