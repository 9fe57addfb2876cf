"""The chaotic estimates as estimates: the Lyapunov exponent and the reference horizon from ensembles.

One Benettin run over one orbit gives an estimate that moves by ±15 % with anything that changes
round-off (the separation, the renormalisation interval, the machine). So the exponent here is
the median of an ensemble of Benettin runs that differ in separation, direction, renormalisation
interval and start time, and its interval is the range of the members. The reference horizon's
interval (engines.reference.reference.bound) is where it falls when the reference's own error is
halved or doubled. docs/metrics.md describes both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from engines.reference.reference import ReferenceSolution
    from engines.scene.scene import Scene

#: Benettin's separations (relative to |y|), renormalisation intervals (s) and start times (fractions of
#: the scene's duration, on the reference's own orbit) the members take in turn; each has its own direction.
SEPARATIONS = (0.5e-8, 1e-8, 2e-8)
INTERVALS = (0.09, 0.1, 0.11)
STARTS = (0.0, 0.25, 0.5, 0.75)


@dataclass(frozen=True)
class Estimate:
    """A figure from an ensemble: ``value`` (the members' median) and ``low``, ``high`` (their range)."""

    value: float
    low: float
    high: float
    members: tuple[float, ...]

    @classmethod
    def of(cls, members: list[float]) -> "Estimate":
        return cls(float(np.median(members)), float(min(members)), float(max(members)), tuple(members))

    @property
    def interval(self) -> list[float]:
        return [self.low, self.high]

    def __str__(self) -> str:
        return f"{self.value:.2g} [{self.low:.2g}, {self.high:.2g}]"


def members() -> list[tuple[float, float, float, int]]:
    """The ensemble's design: (separation, interval s, start fraction, direction seed), one per member:
    each start time with each separation, the intervals cycled across them (12 members)."""
    return [(SEPARATIONS[k % len(SEPARATIONS)], INTERVALS[(k + k // len(SEPARATIONS)) % len(INTERVALS)],
             STARTS[k // len(SEPARATIONS)], k)
            for k in range(len(SEPARATIONS) * len(STARTS))]


def lyapunov_ensemble(scene: Scene, solution: ReferenceSolution | None = None,
                      duration: float | None = None) -> Estimate:
    """The largest Lyapunov exponent (1/s) of ``scene`` from the ensemble of :func:`members`.

    Each member is Benettin's estimate (engines.reference.reference.lyapunov_exponent) over ``duration``
    s (default the scene's) from the state the reference ``solution`` (solved here when None) reaches at
    its start time, along a direction drawn from its seed.
    """
    from engines.reference.reference import lyapunov_exponent, solve

    duration = scene.duration if duration is None else float(duration)
    if solution is None:
        solution = solve(scene)
    out = []
    for separation, interval, start, seed in members():
        y0 = np.asarray(solution.ode(np.array([start * scene.duration])), dtype=float).reshape(-1)
        direction = np.random.default_rng(seed).standard_normal(len(y0))
        out.append(lyapunov_exponent(scene, duration, interval, separation, start=y0,
                                     direction=direction / np.linalg.norm(direction)))
    return Estimate.of(out)
