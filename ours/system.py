"""A system of point masses with constraints, and its packed form for the compiled loop."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ours.constraint import CurveConstraint, DistanceConstraint, Pin, Rod, Wire
from ours.errors import ModelError


@dataclass(frozen=True)
class Packed:
    """Arrays the compiled loop reads (all C-contiguous, float64 / int64).

    inverse_mass : (P,) 1/kg.  force : (P, dim) N, the applied force m·g.
    ends : (C, 2) particle indices (i, j), j = −1 for a fixed end.
    anchor : (C, dim) m, the fixed end, or a curve's point / centre (unused for rods).
    kind : (C,) the constraint kind codes (``ours.constraint.DISTANCE``, ``LINE``, ``ELLIPSE``).
    param : (C, n) each constraint's parameters (l² in m² for a distance, ``ours.kernel``
        lists the others), zero-padded.
    scale : (C,) what |C_k| is divided by in the tolerance test (l² for a distance, 1 for a curve).
    pair_k, pair_l, pair_w : (N,) the nonzeros of the lower band of J W Jᵀ:
        entry (k, l), l ≤ k, gets pair_w · d_k·d_l (pair_w = ±1/mₚ for the shared particle p).
    bandwidth : largest k − l over those pairs (1 for a chain in order, so the
        matrix is tridiagonal and the solve is O(C)).
    """

    inverse_mass: np.ndarray
    force: np.ndarray
    ends: np.ndarray
    anchor: np.ndarray
    kind: np.ndarray
    param: np.ndarray
    scale: np.ndarray
    pair_k: np.ndarray
    pair_l: np.ndarray
    pair_w: np.ndarray
    bandwidth: int

    @property
    def model(self) -> tuple:
        """The fields in order, as the ``model`` tuple of the compiled functions (``ours.kernel``)."""
        return (self.inverse_mass, self.force, self.ends, self.anchor, self.kind, self.param, self.scale,
                self.pair_k, self.pair_l, self.pair_w, self.bandwidth)


@dataclass(frozen=True)
class System:
    """Point masses under uniform gravity with distance (and, in 2-D, curve) constraints.

    masses : (P,) kg.  gravity : (dim,) m/s², dim 2 or 3.
    constraints : Pin / Wire / Rod records (``ours.constraint``), and in 2-D Line / Ellipse.
    packed : the compiled loop's arrays.
    The Jacobian's band (and so the cost of a solve) follows the order of
    ``constraints``: list a chain's constraints from its root to its tip.
    """

    masses: tuple[float, ...]
    gravity: tuple[float, ...]
    constraints: tuple[DistanceConstraint, ...] = ()
    packed: Packed = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        masses = tuple(float(m) for m in np.atleast_1d(self.masses))
        if not masses:
            raise ModelError("masses: a system needs at least one particle")
        if not all(np.isfinite(m) and m > 0 for m in masses):
            raise ModelError(f"masses: every mass must be positive and finite (kg), got {masses}")
        gravity = tuple(float(g) for g in self.gravity)
        if len(gravity) not in (2, 3) or not all(np.isfinite(gravity)):
            raise ModelError(f"gravity: must be 2 or 3 finite numbers (m/s²), got {self.gravity!r}")
        object.__setattr__(self, "masses", masses)
        object.__setattr__(self, "gravity", gravity)
        object.__setattr__(self, "constraints", tuple(self.constraints))
        for k, c in enumerate(self.constraints):
            if not isinstance(c, (DistanceConstraint, CurveConstraint)):
                raise ModelError(
                    f"constraints[{k}]: expected Pin, Wire, Rod, Line or Ellipse, got {type(c).__name__}"
                )
            for p in c.particles:
                if p >= len(masses):
                    raise ModelError(
                        f"constraints[{k}]: particle {p} is out of range (the system has 0..{len(masses) - 1})"
                    )
            if isinstance(c, CurveConstraint):
                if len(gravity) != 2:
                    raise ModelError(
                        f"constraints[{k}]: {type(c).__name__} is a planar (2-D) constraint; this system is "
                        f"{len(gravity)}-D"
                    )
                continue
            _, j, anchor = c.ends()
            if j < 0 and anchor is not None and len(anchor) != len(gravity):
                raise ModelError(
                    f"constraints[{k}]: the fixed point has {len(anchor)} coordinates but the system is "
                    f"{len(gravity)}-D; give it {len(gravity)}"
                )
        object.__setattr__(self, "packed", _pack(self))

    @property
    def dim(self) -> int:
        return len(self.gravity)

    @property
    def n_particles(self) -> int:
        return len(self.masses)

    @property
    def n_constraints(self) -> int:
        return len(self.constraints)

    # -- dense closed forms (numpy; for checks, not for stepping) --------------

    def values(self, q: np.ndarray) -> np.ndarray:
        """(C,) m²: C(q)."""
        return np.array([c.value(q) for c in self.constraints])

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(C, P·dim) m: the dense J."""
        return np.array([c.jacobian(q).ravel() for c in self.constraints]).reshape(len(self.constraints), -1)

    def jdot_qdot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(C,) m²/s²."""
        return np.array([c.jdot_qdot(q, v) for c in self.constraints])

    def dense_multipliers(self, q, v, k_s: float = 0.0, k_d: float = 0.0) -> np.ndarray:
        """(C,) λ from a dense solve of J W Jᵀ λ = −J̇q̇ − J W f − k_s C − k_d Ċ (O(C³); for checking)."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        J = self.jacobian(q)
        w = np.repeat(1.0 / np.array(self.masses), self.dim)
        f = (np.array(self.masses)[:, None] * np.array(self.gravity)[None, :]).ravel()
        rhs = -self.jdot_qdot(q, v) - J @ (w * f) - k_s * self.values(q) - k_d * (J @ v.ravel())
        return np.linalg.solve((J * w) @ J.T, rhs)

    # -- structure -------------------------------------------------------------

    def why_not_a_chain(self) -> str | None:
        """None when this is a serial chain hung from a fixed point, else why not.

        A chain: constraint 0 fixes particle 0 to a point (Pin or Wire), and
        constraint k ≥ 1 is a Rod joining particles k − 1 and k, one per particle.
        """
        if not self.constraints:
            return "it has no constraints"
        if len(self.constraints) != self.n_particles:
            return f"it has {self.n_constraints} constraints for {self.n_particles} particles (a chain has one per particle)"
        first = self.constraints[0]
        if not isinstance(first, (Pin, Wire)) or first.particle != 0:
            return "constraint 0 must fix particle 0 to a point"
        for k, c in enumerate(self.constraints[1:], start=1):
            if not isinstance(c, Rod) or {c.a, c.b} != {k - 1, k}:
                return f"constraint {k} must be a Rod joining particles {k - 1} and {k}"
        return None


def _pack(system: System) -> Packed:
    dim = system.dim
    inverse_mass = 1.0 / np.array(system.masses)
    force = np.array(system.masses)[:, None] * np.array(system.gravity)[None, :]
    n = len(system.constraints)
    ends = np.zeros((n, 2), dtype=np.int64)
    anchor = np.zeros((n, dim))
    rows = [c.encode(dim) for c in system.constraints]
    kind = np.array([row[3] for row in rows], dtype=np.int64)
    param = np.zeros((n, max((len(row[4]) for row in rows), default=1)))
    scale = np.array([row[5] for row in rows], dtype=np.float64)
    touching: dict[int, list[tuple[int, float]]] = {}
    for k, (i, j, point, _, parameters, _) in enumerate(rows):
        ends[k] = (i, j)
        anchor[k] = point
        param[k, : len(parameters)] = parameters
        touching.setdefault(i, []).append((k, 1.0))
        if j >= 0:
            touching.setdefault(j, []).append((k, -1.0))
    pairs: dict[tuple[int, int], float] = {}
    for p, entries in touching.items():
        for k, sk in entries:
            for l, sl in entries:
                if l <= k:
                    pairs[(k, l)] = pairs.get((k, l), 0.0) + sk * sl * inverse_mass[p]
    keys = sorted(pairs)
    return Packed(
        inverse_mass=np.ascontiguousarray(inverse_mass),
        force=np.ascontiguousarray(force),
        ends=ends,
        anchor=anchor,
        kind=kind,
        param=param,
        scale=scale,
        pair_k=np.array([k for k, _ in keys], dtype=np.int64),
        pair_l=np.array([l for _, l in keys], dtype=np.int64),
        pair_w=np.array([pairs[key] for key in keys], dtype=np.float64),
        bandwidth=max((k - l for k, l in keys), default=0),
    )
