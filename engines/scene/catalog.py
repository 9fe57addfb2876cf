"""Named scene builders with typed, documented parameters.

Angles are in degrees, measured from the downward vertical (−z) toward +x;
angular velocities are in rad/s; lengths in m, masses in kg, g in m/s².
``build(name, overrides)`` is the single entry point; an unknown scene or
parameter raises :class:`SceneError` naming the valid ones.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from engines.scene import limits
from engines.errors import SceneError
from engines.scene.scene import Ellipse, Line, Particle, Pin, Rod, Scene


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


#: Allowed ranges of positive parameters by unit (engines/scene/limits.py says why).
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
        particles.append(Particle(m, (position[0], position[1], position[2]), (velocity[0], velocity[1], velocity[2])))
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


def slider_pendulum(M, m, l, theta0, omega0, g, duration, parameters=None) -> Scene:
    """A slider (mass M) on the horizontal line z = 0 through the origin, starting at the origin at
    rest, and a pendulum (mass m) hung from it on a rod of length l at theta0, turning at omega0."""
    d, t = _direction(theta0), _tangent(theta0)
    return Scene(
        "slider-pendulum",
        (Particle(M, (0.0, 0.0, 0.0)), Particle(m, tuple(l * c for c in d), tuple(l * omega0 * c for c in t))),
        (Line(0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), Rod(0, 1, l)),
        (0.0, 0.0, -g),
        duration,
        parameters or {},
    )


#: The rule four_bar enforces, quoted in its refusal: the loop closes at theta0 (Grashof or not).
FOUR_BAR_RULE = (
    "the coupler b and the rocker c close the loop only when the crank tip's distance from the rocker "
    "pivot lies strictly between |b - c| and b + c"
)


def four_bar_joint(p0, pivot, b: float, c: float, branch: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """The coupler–rocker joint (x, z) m that closes the loop: where the coupler circle about p0 meets the
    rocker circle about the pivot.

    p0 : crank tip (x, z); pivot : ground pivot (x, z); b, c : coupler and rocker lengths (m).
    branch +1 puts the joint left of the directed line from p0 to the pivot, −1 right of it.
    Returns (joint, unit vector from p0 to the pivot).
    """
    dx, dz = pivot[0] - p0[0], pivot[1] - p0[1]
    delta = math.hypot(dx, dz)
    ux, uz = dx / delta, dz / delta
    along = (b * b - c * c + delta * delta) / (2.0 * delta)
    across = branch * math.sqrt(max(b * b - along * along, 0.0))
    return (p0[0] + along * ux - across * uz, p0[1] + along * uz + across * ux), (ux, uz)


def four_bar(a, b, c, d, m0, m1, theta0, omega0, branch, g, duration, parameters=None) -> Scene:
    """Crank a pinned at the origin, rocker c pinned at (d, 0, 0), coupler b between their tips."""
    if branch not in (1, -1):
        raise SceneError(f"four-bar: parameter branch must be +1 or -1 (which assembly), got {branch!r}")
    e, t = _direction(theta0), _tangent(theta0)
    p0 = (a * e[0], a * e[2])
    reach = math.hypot(d - p0[0], p0[1])
    if not abs(b - c) < reach < b + c:
        shown = ", ".join(f"{k}={v:g}" for k, v in {"a": a, "b": b, "c": c, "d": d}.items())
        raise SceneError(f"four-bar: lengths {shown} cannot close at theta0 = {theta0:g} deg (crank tip "
                         f"{reach:.4g} m from the rocker pivot): {FOUR_BAR_RULE}")
    v0 = (a * omega0 * t[0], a * omega0 * t[2])
    p1, _ = four_bar_joint(p0, (d, 0.0), b, c, branch)
    # The joint moves on the rocker circle, tangent r ⊥ (p1 − pivot); its rate follows from
    # (p1 − p0)·(v1 − v0) = 0, the time derivative of the coupler's length.
    rx, rz = p1[0] - d, p1[1]
    tx, tz = -rz / c, rx / c
    cx, cz = p1[0] - p0[0], p1[1] - p0[1]
    rate = (cx * v0[0] + cz * v0[1]) / (cx * tx + cz * tz)
    v1 = (rate * tx, rate * tz)
    return Scene(
        "four-bar",
        (Particle(m0, (p0[0], 0.0, p0[1]), (v0[0], 0.0, v0[1])), Particle(m1, (p1[0], 0.0, p1[1]), (v1[0], 0.0, v1[1]))),
        (Pin(0, (0.0, 0.0, 0.0), a), Rod(0, 1, b), Pin(1, (d, 0.0, 0.0), c)),
        (0.0, 0.0, -g),
        duration,
        parameters or {},
    )


def bead_ellipse(m, a, b, theta0, omega0, g, duration, parameters=None) -> Scene:
    """A bead on the ellipse (x/a)² + (z/b)² = 1 about the origin, at wire parameter theta0."""
    u = math.radians(theta0)
    position = (a * math.sin(u), 0.0, -b * math.cos(u))
    velocity = (a * math.cos(u) * omega0, 0.0, b * math.sin(u) * omega0)
    return Scene(
        "bead-ellipse",
        (Particle(m, position, velocity),),
        (Ellipse(0, (0.0, 0.0, 0.0), a, b),),
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
        SceneBuilder(
            "slider-pendulum",
            "A slider on a horizontal rail (a line kind) carrying a pendulum, in the x–z plane; "
            "horizontal momentum is conserved.",
            (
                Parameter("M", 1.0, "kg", "slider mass", positive=True),
                Parameter("m", 1.0, "kg", "pendulum mass", positive=True),
                Parameter("l", 1.0, "m", "rod length", positive=True),
                Parameter("theta0", 30.0, "deg", "release angle of the rod from the downward vertical"),
                Parameter("omega0", 0.0, "rad/s", "initial angular velocity of the rod (the slider starts at rest)"),
            )
            + _common(10.0),
            slider_pendulum,
        ),
        SceneBuilder(
            "four-bar",
            "A four-bar linkage: crank a pinned at the origin, rocker c pinned at (d, 0, 0), coupler b "
            "between the two moving masses; one closed loop, one degree of freedom, in the x–z plane.",
            (
                Parameter("a", 0.4, "m", "crank length (particle 0 from the origin)", positive=True),
                Parameter("b", 1.2, "m", "coupler length (particle 0 to particle 1)", positive=True),
                Parameter("c", 0.8, "m", "rocker length (particle 1 from the ground pivot)", positive=True),
                Parameter("d", 1.0, "m", "ground length: the rocker's pivot is at (d, 0, 0)", positive=True),
                Parameter("m0", 1.0, "kg", "mass at the crank tip", positive=True),
                Parameter("m1", 1.0, "kg", "mass at the rocker tip", positive=True),
                Parameter("theta0", 30.0, "deg", "crank angle from the downward vertical"),
                Parameter("omega0", 0.0, "rad/s", "crank angular velocity"),
                Parameter("branch", -1, "", "assembly: +1 puts the rocker tip left of the line from the crank "
                          "tip to the ground pivot (above it), -1 right of it (below)", integer=True),
            )
            + _common(10.0),
            four_bar,
        ),
        SceneBuilder(
            "bead-ellipse",
            "A bead on an elliptic wire about the origin with semi-axes a (x) and b (z), in the x–z plane.",
            (
                Parameter("m", 1.0, "kg", "bead mass", positive=True),
                Parameter("a", 1.0, "m", "semi-axis along x", positive=True),
                Parameter("b", 0.6, "m", "semi-axis along z", positive=True),
                Parameter("theta0", 60.0, "deg", "release point as the wire's parameter angle u: "
                          "(a sin u, 0, -b cos u); for a = b the angle from the downward vertical"),
                Parameter("omega0", 0.0, "rad/s", "initial rate of the parameter angle, du/dt"),
            )
            + _common(10.0),
            bead_ellipse,
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


def unit_warnings(name: str, overrides: Mapping[str, Any] | None = None) -> list[str]:
    """One line per angle of ``overrides`` whose magnitude is under 2π and not 0: angles here are in degrees,
    and such a value is more likely radians typed by habit (theta1 = 1.5708 is 1.57°, not 90°)."""
    known = {p.name: p for p in builder(name).parameters}
    lines = []
    for key, raw in (overrides or {}).items():
        parameter = known.get(key)
        if parameter is None or parameter.unit != "deg":
            continue
        try:
            value = float(raw)
        except (TypeError, ValueError):
            continue  # build() refuses it with the reason
        if 0 < abs(value) < 2 * math.pi:
            lines.append(f"{name}: {key} = {raw} is in degrees ({value:g}°); if you meant radians, give "
                         f"{math.degrees(value):.6g} (degrees)")
    return lines


#: The environment variable that moves every catalog scene's initial angles and rates by this many ulps
#: (an integer; unset or 0: not at all). The quote test's second pass sets it (tests/test_docs_figures.py):
#: a machine whose round-off differs gives figures that differ by about as much, so a figure that moves
#: past its declared tolerance here would on another machine too.
ROUNDOFF_ULPS = "XVAL_ROUNDOFF_ULPS"
#: The units of the parameters that set a scene's initial state (not its physics: masses, lengths, g).
_STATE_UNITS = ("deg", "rad/s")


def _perturbed(entry: SceneBuilder, values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with each nonzero initial angle and rate moved up by ``$XVAL_ROUNDOFF_ULPS`` ulps."""
    raw = os.environ.get(ROUNDOFF_ULPS, "").strip()
    try:
        ulps = int(raw or 0)
    except ValueError:
        raise SceneError(f"{ROUNDOFF_ULPS} must be an integer number of ulps, got {raw!r}") from None
    if not ulps:
        return values
    known = {p.name: p for p in entry.parameters}
    return {name: moved_by_ulps(value, ulps) if known[name].unit in _STATE_UNITS and not known[name].integer and value
            else value for name, value in values.items()}


def moved_by_ulps(value: float, ulps: int) -> float:
    """``value`` moved by ``ulps`` units in its last place (up for ulps > 0, down for ulps < 0)."""
    value = float(value)
    for _ in range(abs(ulps)):
        value = math.nextafter(value, math.copysign(math.inf, ulps))
    return value


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
    values = _perturbed(entry, values)
    try:
        return entry.build(**values, parameters=values)
    except SceneError as exc:  # a rule only the built scene can check (a speed from omega0 and radius)
        if str(exc).startswith(f"{name}: "):
            raise  # the builder's own message, already naming the scene and its parameters
        given = ", ".join(f"{k} = {values[k]:g}" for k in (overrides or {}))
        raise SceneError(f"{name}: {exc}" + (f" (from {given})" if given else "")) from None
