"""Constraint kinds: C(q), its Jacobian J = ∂C/∂q and J̇q̇, each in closed form.

Two families: distance constraints (Pin, Wire, Rod; below) and curve
constraints (Line, Ellipse: one particle on an implicit curve of a 2-D
system; at the end of the file). Both run in the same compiled loop.

Every distance constraint joins a particle i to an "other end" (a second
particle j, or a fixed point a) and depends only on the separation
d = xᵢ − x_other, so its Jacobian is g = ∂C/∂d on i and −g on j:

    C = ½(‖d‖² − l²)   (m²),   g = d   (m),   J̇q̇ = ‖ḋ‖² = ‖vᵢ − vⱼ‖²   (m²/s²)

Details: docs/ours.md, "Module notes", ``ours/constraint.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ours.errors import ModelError

#: Kind codes of the compiled loop (``ours.kernel``); one per closed form.
DISTANCE, LINE, ELLIPSE = 0, 1, 2


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
        if j >= 0:
            return x[i] - x[j]
        if anchor is None:
            raise ModelError(f"{type(self).__name__}: one end is fixed (j = -1) but it has no anchor point")
        return x[i] - np.asarray(anchor[: x.shape[1]])

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


# -- curve constraints: one particle on an implicit curve c(x) = 0 (planar) -------------------


@dataclass(frozen=True)
class CurveConstraint:
    """Base of the curve family: particle i held on the implicit curve c(x) = 0 in a 2-D system.

        C = c(xᵢ),   ∂C/∂xᵢ = ∇c(xᵢ),   J̇q̇ = vᵢᵀ H(xᵢ) vᵢ   (H the Hessian of c)

    so a subclass gives c, ∇c and H in closed form (numpy, for reading and
    checking) and its kind code and parameters for the compiled loop
    (``encode``; ``ours.kernel`` has the same closed forms, written on
    d = xᵢ − anchor). ``violation`` is |C| made relative (≈ the distance off
    the curve over the curve's size) for the projection and RATTLE stopping
    rule.
    """

    @property
    def particle_index(self) -> int:
        raise NotImplementedError

    @property
    def particles(self) -> tuple[int, ...]:
        return (self.particle_index,)

    def c(self, x: np.ndarray) -> float:
        raise NotImplementedError

    def gradient(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def hessian(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def violation(self, q: np.ndarray) -> float:
        raise NotImplementedError

    # -- the same closed-form interface as the distance family ---------------------

    def value(self, q: np.ndarray) -> float:
        """C(q) = c(xᵢ)."""
        return self.c(np.asarray(q[self.particle_index], dtype=float))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(n_particles, dim): ∇c(xᵢ) on particle i, zero elsewhere."""
        row = np.zeros_like(q, dtype=float)
        row[self.particle_index] = self.gradient(np.asarray(q[self.particle_index], dtype=float))
        return row

    def jdot_qdot(self, q: np.ndarray, v: np.ndarray) -> float:
        """J̇q̇ = vᵢᵀ H(xᵢ) vᵢ."""
        i = self.particle_index
        vi = np.asarray(v[i], dtype=float)
        return float(vi @ self.hessian(np.asarray(q[i], dtype=float)) @ vi)

    def ends(self) -> tuple[int, int, tuple[float, ...]]:
        """(i, −1, the curve's anchor point): one particle, the other end fixed."""
        raise NotImplementedError

    def encode(self, dim: int) -> tuple[int, int, tuple[float, ...], int, tuple[float, ...], float]:
        """One row of the compiled loop's constraint table, as :meth:`DistanceConstraint.encode`; scale 1
        (``violation`` is |C| itself)."""
        i, j, anchor = self.ends()
        kind, parameters = self._kind()
        return i, j, tuple(anchor), kind, parameters, 1.0

    def _kind(self) -> tuple[int, tuple[float, ...]]:
        raise NotImplementedError


def _planar_point(value, field: str) -> tuple[float, float]:
    point = _point(value, field)
    if len(point) != 2:
        raise ModelError(f"{field}: curve constraints are planar (2-D systems); give 2 numbers, got {value!r}")
    return point


@dataclass(frozen=True)
class Line(CurveConstraint):
    """Particle ``particle`` held on the straight line through ``point`` (m) along ``direction`` (2-D):
    C = n·(x − p) in m, n the unit normal (−d_y, d_x)/‖d‖; ∇C = n, H = 0 (so J̇q̇ = 0)."""

    particle: int
    point: tuple[float, ...]
    direction: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "Line.particle"))
        object.__setattr__(self, "point", _planar_point(self.point, "Line.point"))
        direction = _planar_point(self.direction, "Line.direction")
        if np.hypot(*direction) == 0.0:
            raise ModelError(f"Line.direction: must be a nonzero vector, got {self.direction!r}")
        object.__setattr__(self, "direction", direction)

    @property
    def particle_index(self) -> int:
        return self.particle

    @property
    def normal(self) -> np.ndarray:
        d = np.asarray(self.direction)
        return np.array([-d[1], d[0]]) / np.hypot(*d)

    def ends(self):
        return self.particle, -1, self.point

    def _kind(self):
        return LINE, tuple(float(n) for n in self.normal)

    def c(self, x):
        return float(self.normal @ (x - np.asarray(self.point)))

    def gradient(self, x):
        return self.normal

    def hessian(self, x):
        return np.zeros((2, 2))

    def violation(self, q):
        """|C| in m (relative to 1 m: a line has no length of its own)."""
        return abs(self.value(q))


@dataclass(frozen=True)
class Ellipse(CurveConstraint):
    """Particle ``particle`` on the ellipse about ``centre`` (m) with semi-axes ``semi_axes`` = (a, b) (m)
    along the system's two axes (2-D): C = ½((X/a)² + (Y/b)² − 1), (X, Y) = x − centre, dimensionless;
    ∇C = (X/a², Y/b²) (1/m), H = diag(1/a², 1/b²). With a = b = r it is the Wire of radius r scaled by 1/r²."""

    particle: int
    centre: tuple[float, ...]
    semi_axes: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "Ellipse.particle"))
        object.__setattr__(self, "centre", _planar_point(self.centre, "Ellipse.centre"))
        axes = _planar_point(self.semi_axes, "Ellipse.semi_axes")
        object.__setattr__(self, "semi_axes", (_length(axes[0], "Ellipse.semi_axes[0]"),
                                               _length(axes[1], "Ellipse.semi_axes[1]")))

    @property
    def particle_index(self) -> int:
        return self.particle

    def ends(self):
        return self.particle, -1, self.centre

    def _kind(self):
        return ELLIPSE, tuple(1.0 / s**2 for s in self.semi_axes)

    def c(self, x):
        X = (x - np.asarray(self.centre)) / np.asarray(self.semi_axes)
        return 0.5 * (float(X @ X) - 1.0)

    def gradient(self, x):
        return (x - np.asarray(self.centre)) / np.asarray(self.semi_axes) ** 2

    def hessian(self, x):
        return np.diag(1.0 / np.asarray(self.semi_axes) ** 2)

    def violation(self, q):
        """|C| ≈ the relative radial error (dimensionless)."""
        return abs(self.value(q))
