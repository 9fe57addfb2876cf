"""Integrators: explicit Runge–Kutta methods as Butcher tables, symplectic Euler and RATTLE.

After scipy's ``_ivp/rk.py``: a Runge–Kutta method is data (A, b, c, order),
and one compiled loop steps any table. Each record states its order and
whether it is symplectic; ``code`` tells the compiled loop which update to use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ours.errors import OursError

#: How the compiled loop advances a step.
EXPLICIT_RK, SYMPLECTIC_EULER, RATTLE = 0, 1, 2


@dataclass(frozen=True, eq=False)
class Integrator:
    """One time-stepping scheme.

    name : as used in ``simulate(..., integrator=name)`` and variant ids.
    order : global order of accuracy.  symplectic : preserves the symplectic
        form (bounded energy error over long runs, no secular drift).
    code : update rule of the compiled loop.
    A (s, s), b (s,), c (s,) : the Butcher table (explicit RK only; else 1×1 zeros).
    """

    name: str
    order: int
    symplectic: bool
    code: int
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    doc: str

    def __post_init__(self) -> None:
        A, b, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (self.A, self.b, self.c))
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "c", c)
        if self.code == EXPLICIT_RK:
            if np.any(np.triu(A) != 0.0):
                raise OursError(f"{self.name}: A must be strictly lower triangular for an explicit method")
            if not np.allclose(A.sum(axis=1), c) or not np.isclose(b.sum(), 1.0):
                raise OursError(f"{self.name}: the table is inconsistent (need c = row sums of A and sum(b) = 1)")

    @property
    def stages(self) -> int:
        return len(self.b)


def _table(name, order, A, b, doc) -> Integrator:
    A = np.array(A, dtype=float)
    return Integrator(name, order, False, EXPLICIT_RK, A, np.array(b, float), A.sum(axis=1), doc)


_NO_TABLE = (np.zeros((1, 1)), np.ones(1), np.zeros(1))

EXPLICIT_EULER = _table(
    "euler", 1, [[0.0]], [1.0],
    "Order 1, not symplectic. Explicit (forward) Euler: q += h q̇, q̇ += h q̈, both from the old state.",
)
SYMPLECTIC = Integrator(
    "symplectic-euler", 1, True, SYMPLECTIC_EULER, *_NO_TABLE,
    "Order 1, symplectic (for separable Hamiltonians). Semi-implicit Euler: q̇ += h q̈(q, q̇), then q += h q̇ with the new q̇.",
)
MIDPOINT = _table(
    "midpoint", 2, [[0.0, 0.0], [0.5, 0.0]], [0.0, 1.0],
    "Order 2, not symplectic. Explicit midpoint (RK2): a half Euler step, then the full step with the midpoint slope.",
)
RK4 = _table(
    "rk4", 4,
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6],
    "Order 4, not symplectic. The classic Runge–Kutta method.",
)
RATTLE_SCHEME = Integrator(
    "rattle", 2, True, RATTLE, *_NO_TABLE,
    "Order 2, symplectic. RATTLE: Störmer–Verlet with position constraints solved each step "
    "(SHAKE) and velocities projected onto J q̇ = 0.",
)

INTEGRATORS: dict[str, Integrator] = {
    i.name: i for i in (EXPLICIT_EULER, SYMPLECTIC, MIDPOINT, RK4, RATTLE_SCHEME)
}


def get_integrator(name: str) -> Integrator:
    try:
        return INTEGRATORS[name]
    except KeyError:
        raise OursError(f"integrator: unknown {name!r}; choose one of: {', '.join(INTEGRATORS)}") from None
