"""The bead on a circular wire in closed form (Baraff & Witkin's worked example)."""

from __future__ import annotations

import numpy as np


def bead_multiplier(x, v, mass: float, force) -> float:
    """λ (N/m) of a bead on c(x) = ½(x·x − r²), x measured from the wire's centre.

    λ = (−f·x − m ẋ·ẋ) / (x·x), with f the applied force (N; m·g under gravity).
    The constraint force is λ x (N). x, v, force : (dim,) m, m/s, N.
    """
    x, v, force = (np.asarray(a, dtype=float) for a in (x, v, force))
    return float((-force @ x - mass * (v @ v)) / (x @ x))
