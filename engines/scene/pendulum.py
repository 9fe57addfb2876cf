"""Pendulum angles <-> particle states, and constraint-force arrays with NaN for "not reported".

Most pendulum solvers work in angles; xval speaks particle positions and
velocities in the scene frame. :func:`planar_chain` reads a chain scene
(``bead``, ``double-pendulum``, ``chain``: a Pin on particle 0 and
``Rod(k−1, k)`` for each further link, in the x–z plane) and converts both
ways, for one state or many at once::

    chain = planar_chain(scene)
    theta, omega = chain.angles(q), chain.rates(q, v)      # (..., P) rad, rad/s
    q, v = chain.positions(theta), chain.velocities(theta, omega)

Details: docs/engines.md, "Adapter notes", ``engines/scene/pendulum.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from engines.errors import Unsupported
from engines.scene.scene import Pin, Rod, Scene


@dataclass(frozen=True)
class PlanarChain:
    """A chain hung from ``anchor``: link k joins particle k−1 (the anchor for k = 0) to particle k.

    anchor : (3,) m, with y = 0; lengths : (P,) m; masses : (P,) kg.
    """

    anchor: np.ndarray
    lengths: np.ndarray
    masses: np.ndarray

    @property
    def n_links(self) -> int:
        return len(self.lengths)

    def positions(self, angles: np.ndarray, *, relative: bool = False) -> np.ndarray:
        """(..., P, 3) m from link angles (..., P) rad."""
        theta = self._absolute(angles, relative)
        arms = self.lengths[:, None] * _arm(theta)
        return self.anchor + np.cumsum(arms, axis=-2)

    def velocities(self, angles: np.ndarray, rates: np.ndarray, *, relative: bool = False) -> np.ndarray:
        """(..., P, 3) m/s from link angles (..., P) rad and their rates (..., P) rad/s."""
        theta = self._absolute(angles, relative)
        omega = self._absolute(rates, relative)
        return np.cumsum(self.lengths[:, None] * omega[..., None] * _turn(theta), axis=-2)

    def angles(self, positions: np.ndarray, *, relative: bool = False) -> np.ndarray:
        """(..., P) rad in (−π, π] (absolute) from positions (..., P, 3) m."""
        d = self._links(positions)
        theta = np.arctan2(d[..., 0], -d[..., 2])
        return self._relative(theta) if relative else theta

    def rates(self, positions: np.ndarray, velocities: np.ndarray, *, relative: bool = False) -> np.ndarray:
        """(..., P) rad/s from positions (..., P, 3) m and velocities (..., P, 3) m/s (the in-plane part)."""
        d = self._links(positions)
        theta = np.arctan2(d[..., 0], -d[..., 2])
        dv = np.diff(np.asarray(velocities, dtype=np.float64), axis=-2, prepend=0.0)
        omega = np.einsum("...i,...i->...", dv, _turn(theta)) / self.lengths
        return self._relative(omega) if relative else omega

    def _links(self, positions: np.ndarray) -> np.ndarray:
        q = np.asarray(positions, dtype=np.float64)
        if q.shape[-2:] != (self.n_links, 3):
            raise ValueError(f"positions: expected shape (..., {self.n_links}, 3), got {q.shape}")
        return np.diff(q, axis=-2, prepend=np.broadcast_to(self.anchor, (*q.shape[:-2], 1, 3)))

    def _absolute(self, values: np.ndarray, relative: bool) -> np.ndarray:
        values = np.asarray(values, dtype=np.float64)
        if values.shape[-1:] != (self.n_links,):
            raise ValueError(f"expected one value per link, shape (..., {self.n_links}), got {values.shape}")
        return np.cumsum(values, axis=-1) if relative else values

    @staticmethod
    def _relative(values: np.ndarray) -> np.ndarray:
        return np.diff(values, axis=-1, prepend=0.0)


def _arm(theta: np.ndarray) -> np.ndarray:
    """(..., 3) unit vectors at angle theta from −z toward +x."""
    return np.stack([np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=-1)


def _turn(theta: np.ndarray) -> np.ndarray:
    """(..., 3) d arm / d theta."""
    return np.stack([np.cos(theta), np.zeros_like(theta), np.sin(theta)], axis=-1)


def planar_chain(scene: Scene) -> PlanarChain:
    """The chain of ``scene``; Unsupported naming what does not fit (a 3-D scene, another topology)."""
    if not scene.is_planar:
        raise Unsupported(f"{scene.name!r} is 3-D; angles in the x-z plane describe planar chains only")
    n = len(scene.particles)
    if len(scene.constraints) != n:
        raise Unsupported(f"{scene.name!r} has {n} particles and {len(scene.constraints)} constraints; a chain has "
                          f"one link per particle")
    first = scene.constraints[0]
    if not (isinstance(first, Pin) and first.particle == 0):
        raise Unsupported(f"{scene.name!r}: constraints[0] must be a pin on particle 0 to be a chain")
    lengths = [first.length]
    for k, c in enumerate(scene.constraints[1:], start=1):
        if not (isinstance(c, Rod) and {c.a, c.b} == {k - 1, k}):
            raise Unsupported(f"{scene.name!r}: constraints[{k}] must be a rod between particles {k - 1} and {k}")
        lengths.append(c.length)
    return PlanarChain(np.asarray(first.anchor, dtype=np.float64), np.array(lengths), scene.masses)


def force_array(n_constraints: int, reported: Mapping[int, np.ndarray] | None = None) -> np.ndarray:
    """(C, 3) N: the force on each constraint's first particle, NaN for a constraint not in ``reported``.

    reported : {constraint index: (3,) N}. xval compares only the reported
    constraints' forces with the reference; a row of NaN is "not reported",
    never "zero".
    """
    out = np.full((n_constraints, 3), np.nan)
    for k, force in (reported or {}).items():
        if not 0 <= k < n_constraints:
            raise IndexError(f"force_array: constraint {k} is out of range (the scene has 0..{n_constraints - 1})")
        out[k] = force
    return out
