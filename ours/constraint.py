"""Constraint kinds: C(q), its Jacobian J = ∂C/∂q and J̇q̇, each in closed form.

Every constraint joins a particle i to an "other end" (a second particle j, or
a fixed point a) and depends only on the separation d = xᵢ − x_other, so its
Jacobian is g = ∂C/∂d on i and −g on j. The kinds here are all *distance*
constraints:

    C = ½(‖d‖² − l²)   (m²),   g = d   (m),   J̇q̇ = ‖ḋ‖² = ‖vᵢ − vⱼ‖²   (m²/s²)

so each class only says which ends it joins and its length.

The compiled loop (``ours.kernel``) reads the packed form from :meth:`encode`:
(i, j, anchor, kind, parameters, scale). To add a kind: a class here whose
``encode`` returns a new kind code and its parameters, and one branch for that
code in ``ours.kernel.constraint_value`` (C and g) and
``ours.kernel.constraint_rate`` (J̇q̇ and Ċ). The specialised copies of the
kernel (``ours.specialize``) pick the branch up with no other change. The
numpy methods here are the readable closed forms, used by tests and the dense
check against the compiled banded solve.

Indices are particle indices of the :class:`ours.system.System`; positions
``q`` and velocities ``v`` are (n_particles, dim) arrays in m and m/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ours.errors import ModelError

#: Kind codes of the compiled loop (``ours.kernel``); one per closed form.
DISTANCE = 0


def _point(value, field: str) -> tuple[float, ...]:
    try:
        point = tuple(float(c) for c in value)
    except (TypeError, ValueError):
        raise ModelError(f"{field}: must be a sequence of 2 or 3 numbers, got {value!r}") from None
    if len(point) not in (2, 3) or not all(np.isfinite(point)):
        raise ModelError(f"{field}: must be 2 or 3 finite numbers, got {value!r}")
    return point


def _length(value, field: str) -> float:
    length = float(value)
    if not np.isfinite(length) or length <= 0.0:
        raise ModelError(f"{field}: must be a positive length in m, got {value!r}")
    return length


def _index(value, field: str) -> int:
    if isinstance(value, bool) or int(value) != value or int(value) < 0:
        raise ModelError(f"{field}: must be a particle index (an integer ≥ 0), got {value!r}")
    return int(value)


@dataclass(frozen=True)
class DistanceConstraint:
    """Base of the distance family; subclasses set the ends and the length (m)."""

    def ends(self) -> tuple[int, int, tuple[float, ...] | None]:
        """(i, j, anchor): j = −1 and a fixed ``anchor`` point when the other end is fixed."""
        raise NotImplementedError

    @property
    def length(self) -> float:
        raise NotImplementedError

    @property
    def particles(self) -> tuple[int, ...]:
        i, j, _ = self.ends()
        return (i,) if j < 0 else (i, j)

    # -- closed forms (numpy, for reading and checking) -------------------------

    def _d(self, x: np.ndarray) -> np.ndarray:
        i, j, anchor = self.ends()
        return x[i] - (x[j] if j >= 0 else np.asarray(anchor[: x.shape[1]]))

    def value(self, q: np.ndarray) -> float:
        """C(q) = ½(‖d‖² − l²), m²."""
        d = self._d(q)
        return 0.5 * (float(d @ d) - self.length**2)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(n_particles, dim) m: ∂C/∂q, +d on the first particle, −d on the second."""
        i, j, _ = self.ends()
        row = np.zeros_like(q, dtype=float)
        d = self._d(q)
        row[i] += d
        if j >= 0:
            row[j] -= d
        return row

    def jdot_qdot(self, q: np.ndarray, v: np.ndarray) -> float:
        """J̇q̇ = ‖vᵢ − vⱼ‖² (m²/s²); the velocity of a fixed end is zero."""
        i, j, _ = self.ends()
        dv = v[i] - (v[j] if j >= 0 else 0.0)
        return float(dv @ dv)

    def encode(self, dim: int) -> tuple[int, int, tuple[float, ...], int, tuple[float, ...], float]:
        """One row of the compiled loop's constraint table: (i, j, anchor padded to ``dim``, kind,
        parameters, scale). For a distance: kind ``DISTANCE``, parameters (l²,), scale l² (the
        tolerance of projection and RATTLE applies to |C| / scale, about the relative length error)."""
        i, j, anchor = self.ends()
        point = tuple(anchor[:dim]) if anchor is not None else (0.0,) * dim
        return i, j, point, DISTANCE, (self.length**2,), self.length**2


@dataclass(frozen=True)
class Pin(DistanceConstraint):
    """Particle ``particle`` held at distance ``distance`` (m) from the fixed point ``anchor`` (m):
    C = ½(‖x − a‖² − l²)."""

    particle: int
    anchor: tuple[float, ...]
    distance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "Pin.particle"))
        object.__setattr__(self, "anchor", _point(self.anchor, "Pin.anchor"))
        object.__setattr__(self, "distance", _length(self.distance, "Pin.distance"))

    def ends(self):
        return self.particle, -1, self.anchor

    @property
    def length(self) -> float:
        return self.distance


@dataclass(frozen=True)
class Wire(DistanceConstraint):
    """A bead ``particle`` on a circular wire of ``radius`` (m) about ``centre`` (m), in a planar system:
    c(x) = ½(‖x − centre‖² − r²). (The Baraff–Witkin example; the same closed forms as a Pin.)"""

    particle: int
    centre: tuple[float, ...]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "Wire.particle"))
        object.__setattr__(self, "centre", _point(self.centre, "Wire.centre"))
        object.__setattr__(self, "radius", _length(self.radius, "Wire.radius"))

    def ends(self):
        return self.particle, -1, self.centre

    @property
    def length(self) -> float:
        return self.radius


@dataclass(frozen=True)
class Rod(DistanceConstraint):
    """Particles ``a`` and ``b`` held at distance ``distance`` (m): C = ½(‖xₐ − x_b‖² − l²).
    Its force Jᵀλ acts on ``a`` as +λd and on ``b`` as −λd."""

    a: int
    b: int
    distance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _index(self.a, "Rod.a"))
        object.__setattr__(self, "b", _index(self.b, "Rod.b"))
        object.__setattr__(self, "distance", _length(self.distance, "Rod.distance"))
        if self.a == self.b:
            raise ModelError(f"Rod: a and b must be different particles, both are {self.a}")

    def ends(self):
        return self.a, self.b, None

    @property
    def length(self) -> float:
        return self.distance
