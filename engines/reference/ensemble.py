"""The chaotic estimates as estimates: an ensemble's design and its :class:`Estimate`.

One Benettin run over one orbit gives an estimate that moves by ±15 % with anything that changes
round-off (the separation, the renormalisation interval, the machine). So the exponent here is
the median of an ensemble of Benettin runs that differ in separation, direction, renormalisation
interval and start time (engines.reference.reference.lyapunov_ensemble runs them), and its interval
is the range of the members. The reference horizon's interval (engines.reference.reference.bound)
is where it falls when the reference's own error is halved or doubled. docs/metrics.md describes both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
