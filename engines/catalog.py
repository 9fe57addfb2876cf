"""Named scene builders with typed, documented parameters.

Angles are in degrees, measured from the downward vertical (−z) toward +x;
angular velocities are in rad/s; lengths in m, masses in kg, g in m/s².
``build(name, overrides)`` is the single entry point; an unknown scene or
parameter raises :class:`SceneError` naming the valid ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from engines import limits
from engines.errors import SceneError
from engines.scene import Particle, Pin, Rod, Scene


@dataclass(frozen=True)
class Parameter:
    """One parameter of a scene builder: its default, unit and meaning."""

    name: str
    default: float
    unit: str
    doc: str
    integer: bool = False
    positive: bool = False
    minimum: float | None = None
    maximum: float | None = None

    def parse(self, raw: Any, scene: str) -> float | int:
        """Convert a CLI string or a number; raise SceneError naming the parameter."""
        kind = "an integer" if self.integer else "a number"
        try:
            value = float(raw)
            if self.integer:
                if value != int(value):
                    raise ValueError
                value = int(value)
        except (TypeError, ValueError):
            raise SceneError(f"{scene}: parameter {self.name} must be {kind}, got {raw!r}") from None
        if not math.isfinite(value):
            raise SceneError(f"{scene}: parameter {self.name} must be finite, got {raw!r}")
        if self.positive and value <= 0:
            raise SceneError(f"{scene}: parameter {self.name} must be positive, got {raw!r}")
        if self.minimum is not None and value < self.minimum:
            raise SceneError(f"{scene}: parameter {self.name} must be at least {self.minimum:g}, got {raw!r}")
        low, high = _UNIT_RANGES.get(self.unit, (-math.inf, math.inf))
        if self.maximum is not None:
            high = min(high, self.maximum)
        if self.positive and not low <= value <= high:
            unit = f" {self.unit}" if self.unit else ""
            raise SceneError(
                f"{scene}: parameter {self.name} = {value:g}{unit} is outside the allowed range "
                f"({low:g} to {high:g}{unit})" if low > 0 else
                f"{scene}: parameter {self.name} = {value:g}{unit} is more than the allowed {high:g}{unit}"
            )
        return value


#: Allowed ranges of positive parameters by unit (engines/limits.py says why).
_UNIT_RANGES = {"kg": limits.MASS_RANGE, "m": limits.LENGTH_RANGE, "s": (0.0, limits.MAX_DURATION)}


@dataclass(frozen=True)
class SceneBuilder:
    """A catalog entry: a function of typed parameters that returns a Scene."""

    name: str
    doc: str
    parameters: tuple[Parameter, ...]
    build: Callable[..., Scene]


def _common(duration: float) -> tuple[Parameter, ...]:
    return (
        Parameter("g", 9.81, "m/s^2", "gravitational acceleration (along -z)", minimum=0.0),
        Parameter("duration", duration, "s", "simulated time", positive=True),
    )


def _direction(theta_deg: float) -> tuple[float, float, float]:
    """Unit vector at angle theta (degrees) from the downward vertical, in the x–z plane."""
    t = math.radians(theta_deg)
    return (math.sin(t), 0.0, -math.cos(t))


def _tangent(theta_deg: float) -> tuple[float, float, float]:
    """d(direction)/dθ: the velocity of a unit arm turning at 1 rad/s."""
    t = math.radians(theta_deg)
    return (math.cos(t), 0.0, math.sin(t))


def _planar_chain(name: str, masses, lengths, thetas, omegas, g, duration, parameters=None) -> Scene:
    """Serial chain hung from the origin: Pin on particle 0, Rod(k−1, k) for each further link."""
    particles, constraints = [], []
    position = [0.0, 0.0, 0.0]
    velocity = [0.0, 0.0, 0.0]
    for k, (m, length, theta, omega) in enumerate(zip(masses, lengths, thetas, omegas)):
        d, t = _direction(theta), _tangent(theta)
        position = [position[i] + length * d[i] for i in range(3)]
        velocity = [velocity[i] + length * omega * t[i] for i in range(3)]
        particles.append(Particle(m, tuple(position), tuple(velocity)))
        constraints.append(Pin(0, (0.0, 0.0, 0.0), length) if k == 0 else Rod(k - 1, k, length))
    return Scene(name, tuple(particles), tuple(constraints), (0.0, 0.0, -g), duration, parameters or {})


def bead(m, radius, theta0, omega0, g, duration, parameters=None) -> Scene:
    return _planar_chain("bead", [m], [radius], [theta0], [omega0], g, duration, parameters)


def double_pendulum(m1, m2, l1, l2, theta1, theta2, omega1, omega2, g, duration, parameters=None) -> Scene:
    return _planar_chain(
        "double-pendulum", [m1, m2], [l1, l2], [theta1, theta2], [omega1, omega2], g, duration, parameters
    )


def chain(n, length, mass, theta0, g, duration, parameters=None) -> Scene:
    return _planar_chain("chain", [mass] * n, [length] * n, [theta0] * n, [0.0] * n, g, duration, parameters)


def spherical_pendulum(m, radius, theta0, phi_dot0, g, duration, parameters=None) -> Scene:
    """Released at azimuth 0 (in the x–z plane) moving in +y at azimuthal rate phi_dot0."""
    d = _direction(theta0)
    position = tuple(radius * c for c in d)
    velocity = (0.0, radius * math.sin(math.radians(theta0)) * phi_dot0, 0.0)
    return Scene(
        "spherical-pendulum",
        (Particle(m, position, velocity),),
        (Pin(0, (0.0, 0.0, 0.0), radius),),
        (0.0, 0.0, -g),
        duration,
        parameters or {},
    )


CATALOG: dict[str, SceneBuilder] = {
    b.name: b
    for b in (
        SceneBuilder(
            "bead",
            "A bead on a circular wire about the origin in the x–z plane (a simple pendulum).",
            (
                Parameter("m", 1.0, "kg", "bead mass", positive=True),
                Parameter("radius", 1.0, "m", "wire radius", positive=True),
                Parameter("theta0", 60.0, "deg", "release angle from the downward vertical"),
                Parameter("omega0", 0.0, "rad/s", "initial angular velocity"),
            )
            + _common(10.0),
            bead,
        ),
        SceneBuilder(
            "double-pendulum",
            "Two point masses on massless rods hung from the origin, in the x–z plane.",
            (
                Parameter("m1", 1.0, "kg", "upper mass", positive=True),
                Parameter("m2", 1.0, "kg", "lower mass", positive=True),
                Parameter("l1", 1.0, "m", "upper rod length", positive=True),
                Parameter("l2", 1.0, "m", "lower rod length", positive=True),
                Parameter("theta1", 120.0, "deg", "upper rod angle from the downward vertical"),
                Parameter("theta2", -10.0, "deg", "lower rod angle from the downward vertical (absolute)"),
                Parameter("omega1", 0.0, "rad/s", "upper rod angular velocity"),
                Parameter("omega2", 0.0, "rad/s", "lower rod angular velocity (absolute)"),
            )
            + _common(10.0),
            double_pendulum,
        ),
        SceneBuilder(
            "chain",
            "n equal links hung from the origin, released straight at theta0, in the x–z plane.",
            (
                Parameter("n", 4, "", "number of links (and particles)", integer=True, positive=True,
                          maximum=limits.MAX_PARTICLES),
                Parameter("length", 0.25, "m", "length of each link", positive=True),
                Parameter("mass", 0.25, "kg", "mass of each particle", positive=True),
                Parameter("theta0", 90.0, "deg", "release angle of the straight chain (90 = horizontal)"),
            )
            + _common(5.0),
            chain,
        ),
        SceneBuilder(
            "spherical-pendulum",
            "A bead on a sphere about the origin, released at azimuth 0 with azimuthal speed (3-D).",
            (
                Parameter("m", 1.0, "kg", "bead mass", positive=True),
                Parameter("radius", 1.0, "m", "sphere radius", positive=True),
                Parameter("theta0", 60.0, "deg", "polar angle from the downward vertical"),
                Parameter("phi_dot0", 3.0, "rad/s", "initial azimuthal angular velocity"),
            )
            + _common(10.0),
            spherical_pendulum,
        ),
    )
}


def scene_names() -> list[str]:
    return list(CATALOG)


def builder(name: str) -> SceneBuilder:
    try:
        return CATALOG[name]
    except KeyError:
        raise SceneError(f"unknown scene {name!r}; choose one of: {', '.join(CATALOG)}") from None


def build(name: str, overrides: Mapping[str, Any] | None = None) -> Scene:
    """Build catalog scene ``name`` with ``overrides`` (strings or numbers) on top of the defaults.

    The Scene's ``parameters`` records every parameter value used.
    """
    entry = builder(name)
    known = {p.name: p for p in entry.parameters}
    values: dict[str, Any] = {p.name: p.default for p in entry.parameters}
    for key, raw in (overrides or {}).items():
        if key not in known:
            raise SceneError(
                f"{name}: unknown parameter {key!r}; its parameters are: {', '.join(known)}"
            )
        values[key] = known[key].parse(raw, name)
    try:
        return entry.build(**values, parameters=values)
    except SceneError as exc:  # a rule only the built scene can check (a speed from omega0 and radius)
        given = ", ".join(f"{k} = {values[k]:g}" for k in (overrides or {}))
        raise SceneError(f"{name}: {exc}" + (f" (from {given})" if given else "")) from None
