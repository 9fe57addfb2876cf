"""The sizes and magnitudes xval accepts, each with its reason.

A scene or case outside these ranges is refused when it is read (SceneError /
UserError naming the field and the allowed range), before anything runs: values far
outside them (a 400-link chain, ``omega0 = 1e300``, ``duration = 1e12``,
``radius = 1e-300``) would hang the reference solver or overflow to nonsense
rather than fail.

The ranges are wide: every scene in suites/ and tests/ sits well inside them
(the largest is the 128-link chain of suites/stiff.toml; the smallest length
its 1 mm bead).
"""

from __future__ import annotations

import math
from typing import Any

from engines.errors import SceneError, UserError

#: kg. Below 1e-9 kg (a microgram) or above 1e9 kg, mass ratios and E* leave the
#: range where float64 solvers (and the tolerances in compare/) mean anything.
MASS_RANGE = (1e-9, 1e9)
#: m, a constraint's length. 1e-300 m squares to an underflow (0) in every engine.
LENGTH_RANGE = (1e-6, 1e6)
#: m, the largest |component| of a position or anchor.
MAX_COORDINATE = 1e9
#: m/s, the largest |component| of a velocity (``omega0 = 1e300`` asks for 1e300 m/s).
MAX_SPEED = 1e6
#: m/s², the largest |component| of gravity.
MAX_GRAVITY = 1e6
#: s, the longest simulated duration.
MAX_DURATION = 1e6
#: Particles in one scene (a chain's links): the reference's dense Jacobian grows as n³.
MAX_PARTICLES = 256
#: Time steps in one case (duration / dt): 1e8 steps is minutes for the fastest engine.
MAX_STEPS = 100_000_000
#: Samples stored for one case (duration / sample interval), and samples × particles
#: (positions and velocities of 1e7 particle-samples are 480 MB).
MAX_SAMPLES = 1_000_000
MAX_PARTICLE_SAMPLES = 10_000_000
#: Worker processes of one run; past this a machine stalls forking rather than runs faster.
MAX_JOBS = 64


def in_range(value: Any, field: str, low: float, high: float, unit: str = "") -> float:
    """``value`` as a float in [low, high]; SceneError naming ``field`` and the range otherwise."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"{field}: must be a number, got {value!r}") from None
    allowed = f"{low:g} to {high:g}{unit}" if low > 0 else f"at most {high:g}{unit}"
    if not math.isfinite(number) or number <= 0.0:
        raise SceneError(f"{field}: must be positive and finite, got {number!r}")
    if not low <= number <= high:
        raise SceneError(f"{field}: {number:g}{unit} is outside the allowed range ({allowed})")
    return number


def check_case_size(n_particles: int, duration: float, dt: float, sample_interval: float, where: str = "") -> None:
    """UserError when a case of this scene size, duration (s), dt (s) and sample interval (s) is too big to run.

    where : a prefix for the message (the suite file and scene), empty at the command line.
    """
    prefix = f"{where}: " if where else ""
    steps = duration / dt
    if steps > MAX_STEPS:
        raise UserError(
            f"{prefix}duration {duration:g} s at dt {dt:g} s is {steps:.3g} steps, more than the allowed "
            f"{MAX_STEPS:.0e} per case; use a larger dt or a shorter duration"
        )
    samples = duration / max(sample_interval, dt)
    if samples > MAX_SAMPLES or samples * n_particles > MAX_PARTICLE_SAMPLES:
        raise UserError(
            f"{prefix}duration {duration:g} s sampled every {max(sample_interval, dt):g} s is {samples:.3g} samples "
            f"of {n_particles} particles; the allowed range is at most {MAX_SAMPLES:.0e} samples and "
            f"{MAX_PARTICLE_SAMPLES:.0e} samples x particles per case; raise the sample interval"
        )
