"""The engine-neutral scene language.

A :class:`Scene` is a set of point-mass particles, the constraints between
them, gravity and a duration, in the scene frame (right-handed, gravity along
−z, SI units). Planar scenes lie in the x–z plane (y ≡ 0). Every record is a
frozen dataclass validated on construction: a bad value raises
:class:`SceneError` naming the field and the rule.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from engines import limits
from engines.errors import SceneError

#: Largest |‖a − b‖ − l| (relative to l) accepted in a scene's initial state.
POSITION_TOLERANCE = 1e-9
#: Largest relative speed along a constraint (relative to a characteristic speed).
VELOCITY_TOLERANCE = 1e-9

Vector = tuple[float, float, float]


def _vector(value: Any, field_name: str) -> Vector:
    try:
        components = tuple(float(c) for c in value)
    except (TypeError, ValueError):
        raise SceneError(f"{field_name}: must be three numbers (x, y, z), got {value!r}") from None
    if len(components) != 3:
        raise SceneError(f"{field_name}: must be three numbers (x, y, z), got {len(components)}")
    if not all(math.isfinite(c) for c in components):
        raise SceneError(f"{field_name}: every component must be finite, got {components}")
    largest, unit = _VECTOR_LIMITS.get(field_name, (limits.MAX_COORDINATE, "m"))
    if max(abs(c) for c in components) > largest:
        raise SceneError(
            f"{field_name}: components must lie in [-{largest:g}, {largest:g}] {unit}, got {components}"
        )
    return components  # type: ignore[return-value]


#: Field name -> (largest |component|, unit); any other vector is a position (m).
_VECTOR_LIMITS = {"velocity": (limits.MAX_SPEED, "m/s"), "gravity": (limits.MAX_GRAVITY, "m/s^2")}
#: Field name -> (allowed range, unit) of a positive quantity (engines/limits.py says why).
_POSITIVE_LIMITS = {
    "mass": (limits.MASS_RANGE, " kg"),
    "length": (limits.LENGTH_RANGE, " m"),
    "radius": (limits.LENGTH_RANGE, " m"),
    "duration": ((0.0, limits.MAX_DURATION), " s"),
}


def _positive(value: Any, field_name: str) -> float:
    (low, high), unit = _POSITIVE_LIMITS.get(field_name, ((0.0, math.inf), ""))
    return limits.in_range(value, field_name, low, high, unit)


@dataclass(frozen=True)
class Particle:
    """A point mass.

    mass : kg; position : (3,) m; velocity : (3,) m/s, all in the scene frame.
    """

    mass: float
    position: Vector
    velocity: Vector = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", _positive(self.mass, "mass"))
        object.__setattr__(self, "position", _vector(self.position, "position"))
        object.__setattr__(self, "velocity", _vector(self.velocity, "velocity"))


@dataclass(frozen=True)
class Pin:
    """Particle ``particle`` held at distance ``length`` (m) from the fixed point ``anchor`` (m).

    A bead on a circular wire of radius ``length`` about ``anchor`` is a Pin in
    a planar scene. Its constraint force is the force on ``particle``.
    """

    particle: int
    anchor: Vector
    length: float

    kind = "pin"

    def __post_init__(self) -> None:
        object.__setattr__(self, "anchor", _vector(self.anchor, "anchor"))
        object.__setattr__(self, "length", _positive(self.length, "length"))

    @property
    def particles(self) -> tuple[int, ...]:
        return (self.particle,)


@dataclass(frozen=True)
class Rod:
    """Particles ``a`` and ``b`` held at distance ``length`` (m).

    Its constraint force is the force on particle ``a`` (the force on ``b`` is
    its negative).
    """

    a: int
    b: int
    length: float

    kind = "rod"

    def __post_init__(self) -> None:
        object.__setattr__(self, "length", _positive(self.length, "length"))
        if self.a == self.b:
            raise SceneError(f"rod: a and b must be different particles, both are {self.a}")

    @property
    def particles(self) -> tuple[int, ...]:
        return (self.a, self.b)


Constraint = Pin | Rod
CONSTRAINT_KINDS: dict[str, type] = {"pin": Pin, "rod": Rod}


@dataclass(frozen=True, eq=False)
class Scene:
    """A physical system every engine is asked to simulate.

    name : catalog name the scene was built from (or any label).
    particles : the point masses.
    constraints : Pin and Rod records; indices refer to ``particles``.
    gravity : (3,) m/s², along −z in the scene frame.
    duration : s, how long to simulate.
    parameters : the catalog parameters the scene was built from (for display
        and provenance; the physics is fully in the other fields).
    requires : capabilities an engine needs, derived on construction:
        ``"3d"`` when the motion can leave the x–z plane.
    """

    name: str
    particles: tuple[Particle, ...]
    constraints: tuple[Constraint, ...]
    gravity: Vector = (0.0, 0.0, -9.81)
    duration: float = 10.0
    parameters: Mapping[str, Any] = field(default_factory=dict)
    requires: frozenset[str] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "particles", tuple(self.particles))
        object.__setattr__(self, "constraints", tuple(self.constraints))
        object.__setattr__(self, "parameters", dict(self.parameters))
        object.__setattr__(self, "gravity", _vector(self.gravity, "gravity"))
        object.__setattr__(self, "duration", _positive(self.duration, "duration"))
        if not self.particles:
            raise SceneError("particles: a scene needs at least one particle")
        if len(self.particles) > limits.MAX_PARTICLES:
            raise SceneError(
                f"particles: {len(self.particles)} is more than the allowed {limits.MAX_PARTICLES} per scene"
            )
        n = len(self.particles)
        for k, constraint in enumerate(self.constraints):
            for index in constraint.particles:
                if not isinstance(index, (int, np.integer)) or not 0 <= index < n:
                    raise SceneError(
                        f"constraints[{k}]: particle index {index!r} is out of range "
                        f"(the scene has particles 0..{n - 1})"
                    )
        self._check_initial_state()
        object.__setattr__(self, "requires", frozenset() if self.is_planar else frozenset({"3d"}))

    # -- derived views -------------------------------------------------------

    @property
    def masses(self) -> np.ndarray:
        """(n_particles,) kg."""
        return np.array([p.mass for p in self.particles])

    @property
    def initial_positions(self) -> np.ndarray:
        """(n_particles, 3) m."""
        return np.array([p.position for p in self.particles])

    @property
    def initial_velocities(self) -> np.ndarray:
        """(n_particles, 3) m/s."""
        return np.array([p.velocity for p in self.particles])

    @property
    def is_planar(self) -> bool:
        """True when every position, velocity, anchor and gravity has y = 0 (motion stays in x–z)."""
        ys = [p.position[1] for p in self.particles] + [p.velocity[1] for p in self.particles]
        ys += [c.anchor[1] for c in self.constraints if isinstance(c, Pin)]
        ys.append(self.gravity[1])
        return all(y == 0.0 for y in ys)

    @property
    def characteristic_length(self) -> float:
        """L (m): the sum of constraint lengths (wire radius for a bead)."""
        return float(sum(c.length for c in self.constraints)) or 1.0

    @property
    def characteristic_energy(self) -> float:
        """E* = total mass · |g| · L (J); falls back to total mass · L when g = 0."""
        g = float(np.linalg.norm(self.gravity)) or 1.0
        return float(self.masses.sum()) * g * self.characteristic_length

    # -- validation ------------------------------------------------------------

    def _check_initial_state(self) -> None:
        q = self.initial_positions
        v = self.initial_velocities
        speed_scale = max(float(np.abs(v).max()), 1.0)
        for k, c in enumerate(self.constraints):
            if isinstance(c, Pin):
                d = q[c.particle] - np.array(c.anchor)
                dv = v[c.particle]
            else:
                d = q[c.a] - q[c.b]
                dv = v[c.a] - v[c.b]
            distance = float(np.linalg.norm(d))
            if abs(distance - c.length) > POSITION_TOLERANCE * max(c.length, 1.0):
                raise SceneError(
                    f"constraints[{k}] ({c.kind}): the initial distance is {distance:.12g} m but "
                    f"the length is {c.length:.12g} m; place the particles on the constraint"
                )
            if abs(float(d @ dv)) / distance > VELOCITY_TOLERANCE * speed_scale:
                raise SceneError(
                    f"constraints[{k}] ({c.kind}): the initial velocity has a component along "
                    f"the constraint; give velocities tangent to it"
                )

    # -- serialization -----------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict; ``Scene.from_dict`` inverts it."""
        return {
            "name": self.name,
            "particles": [
                {"mass": p.mass, "position": list(p.position), "velocity": list(p.velocity)}
                for p in self.particles
            ],
            "constraints": [_constraint_to_dict(c) for c in self.constraints],
            "gravity": list(self.gravity),
            "duration": self.duration,
            "parameters": dict(self.parameters),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Scene":
        try:
            constraints = []
            for k, c in enumerate(data["constraints"]):
                c = dict(c)
                kind = c.pop("kind")
                if kind not in CONSTRAINT_KINDS:
                    raise SceneError(
                        f"constraints[{k}].kind: unknown kind {kind!r}; use one of {sorted(CONSTRAINT_KINDS)}"
                    )
                constraints.append(CONSTRAINT_KINDS[kind](**c))
            return cls(
                name=data["name"],
                particles=tuple(Particle(**p) for p in data["particles"]),
                constraints=tuple(constraints),
                gravity=data.get("gravity", (0.0, 0.0, -9.81)),
                duration=data.get("duration", 10.0),
                parameters=data.get("parameters", {}),
            )
        except KeyError as missing:
            raise SceneError(f"scene: missing field {missing}") from None
        except TypeError as exc:
            raise SceneError(f"scene: {exc}") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @property
    def content_hash(self) -> str:
        """A stable 16-hex-digit hash of the physics (not the name or parameters).

        Two scenes with the same hash describe the same system, so results for
        them are comparable.
        """
        physics = self.to_dict()
        del physics["name"], physics["parameters"]
        text = json.dumps(physics, sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_duration(self, duration: float) -> "Scene":
        return Scene(
            self.name, self.particles, self.constraints, self.gravity, duration, self.parameters
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and self.to_json() == other.to_json()

    def __hash__(self) -> int:
        return hash(self.to_json())


def _constraint_to_dict(c: Constraint) -> dict[str, Any]:
    if isinstance(c, Pin):
        return {"kind": "pin", "particle": c.particle, "anchor": list(c.anchor), "length": c.length}
    return {"kind": "rod", "a": c.a, "b": c.b, "length": c.length}
