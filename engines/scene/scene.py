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
from functools import cached_property
from typing import Any, ClassVar, Mapping, Protocol, Sequence

import numpy as np

from engines.scene import limits
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
    return components


#: Field name -> (largest |component|, unit); any other vector is a position (m).
_VECTOR_LIMITS = {"velocity": (limits.MAX_SPEED, "m/s"), "gravity": (limits.MAX_GRAVITY, "m/s^2")}
#: Field name -> (allowed range, unit) of a positive quantity (engines/scene/limits.py says why).
_POSITIVE_LIMITS = {
    "mass": (limits.MASS_RANGE, " kg"),
    "length": (limits.LENGTH_RANGE, " m"),
    "radius": (limits.LENGTH_RANGE, " m"),
    "duration": ((0.0, limits.MAX_DURATION), " s"),
    "semi_x": (limits.LENGTH_RANGE, " m"),
    "semi_z": (limits.LENGTH_RANGE, " m"),
}


def _nonzero_vector(value: Any, field_name: str) -> Vector:
    vector = _vector(value, field_name)
    if math.hypot(*vector) == 0.0:
        raise SceneError(f"{field_name}: must be a nonzero vector (it gives a direction), got {vector}")
    return vector


def _index(value: Any, field_name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise SceneError(f"{field_name}: must be a particle index (an integer), got {value!r}")
    return int(value)


def _positive(value: Any, field_name: str) -> float:
    # By the field's last name: "ellipse.semi_x" is a length like "length".
    (low, high), unit = _POSITIVE_LIMITS.get(field_name.rsplit(".", 1)[-1], ((0.0, math.inf), ""))
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

    @property
    def characteristic_length(self) -> float:
        """m: the length (it counts towards the scene's L)."""
        return self.length


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

    @property
    def characteristic_length(self) -> float:
        """m: the length (it counts towards the scene's L)."""
        return self.length


@dataclass(frozen=True)
class Line:
    """Particle ``particle`` held on the straight line through ``point`` (m) along ``direction``.

    ``direction`` is any nonzero vector (only its direction matters; it is
    kept as given so a scene round-trips exactly). The constraint force is
    the force on ``particle``; it is perpendicular to the line. A slider on a
    frictionless rail is a Line. It has no length: it adds nothing to the
    scene's characteristic length L.
    """

    particle: int
    point: Vector
    direction: Vector

    kind = "line"

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "line.particle"))
        object.__setattr__(self, "point", _vector(self.point, "line.point"))
        object.__setattr__(self, "direction", _nonzero_vector(self.direction, "line.direction"))

    @property
    def particles(self) -> tuple[int, ...]:
        return (self.particle,)

    @property
    def unit(self) -> np.ndarray:
        """(3,) the unit vector along the line."""
        d = np.asarray(self.direction, dtype=float)
        return d / np.linalg.norm(d)

    @property
    def characteristic_length(self) -> float:
        return 0.0

    def offsets(self, positions: np.ndarray) -> np.ndarray:
        """(..., 3) m: each position minus its foot on the line (the perpendicular offset)."""
        r = np.asarray(positions, dtype=float) - np.asarray(self.point)
        u = self.unit
        return r - (r @ u)[..., None] * u

    def distances(self, positions: np.ndarray) -> np.ndarray:
        """(...,) m: distance of each position (..., 3) from the line."""
        return np.linalg.norm(self.offsets(positions), axis=-1)


@dataclass(frozen=True)
class Ellipse:
    """Particle ``particle`` held on an elliptic wire in the x–z plane through ``centre`` (m).

    semi_x, semi_z : m, the semi-axes along x and along z. The wire is the
    curve ((x − cₓ)/semi_x)² + ((z − c_z)/semi_z)² = 1 at y = c_y: in a 3-D
    scene the particle is also held in that plane. With semi_x = semi_z = r
    it is a circular wire of radius r (the same system as a Pin of length r).
    The constraint force is the force on ``particle``, normal to the wire.
    Its characteristic length is the larger semi-axis.
    """

    particle: int
    centre: Vector
    semi_x: float
    semi_z: float

    kind = "ellipse"

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle", _index(self.particle, "ellipse.particle"))
        object.__setattr__(self, "centre", _vector(self.centre, "ellipse.centre"))
        object.__setattr__(self, "semi_x", _positive(self.semi_x, "ellipse.semi_x"))
        object.__setattr__(self, "semi_z", _positive(self.semi_z, "ellipse.semi_z"))

    @property
    def particles(self) -> tuple[int, ...]:
        return (self.particle,)

    @property
    def characteristic_length(self) -> float:
        return max(self.semi_x, self.semi_z)

    def distances(self, positions: np.ndarray) -> np.ndarray:
        """(...,) m: Euclidean distance of each position (..., 3) from the wire (exact, not |C|/‖∇C‖)."""
        r = np.asarray(positions, dtype=float) - np.asarray(self.centre)
        in_plane = ellipse_distance(r[..., 0], r[..., 2], self.semi_x, self.semi_z)
        return np.hypot(in_plane, r[..., 1])

    def normals(self, positions: np.ndarray) -> np.ndarray:
        """(..., 3) the unit normal of the level set through each position (in the x–z plane)."""
        r = np.asarray(positions, dtype=float) - np.asarray(self.centre)
        n = np.zeros(r.shape)
        n[..., 0] = r[..., 0] / self.semi_x**2
        n[..., 2] = r[..., 2] / self.semi_z**2
        return n / np.linalg.norm(n, axis=-1, keepdims=True)


def ellipse_distance(x: Any, z: Any, semi_x: float, semi_z: float) -> np.ndarray:
    """Distance (m) from points (x, z) (m, any matching shapes) to the ellipse (x/semi_x)² + (z/semi_z)² = 1.

    Exact to round-off, by Eberly's method ("Distance from a point to an
    ellipse", 2013): the closest point solves a monotone scalar equation in
    one unknown, bracketed and bisected (vectorized; 200 halvings reach the
    bracket's round-off). A circle (semi_x = semi_z) is |‖(x, z)‖ − r|.
    """
    x, z = np.broadcast_arrays(np.abs(np.asarray(x, dtype=float)), np.abs(np.asarray(z, dtype=float)))
    if semi_x == semi_z:
        return np.abs(np.hypot(x, z) - semi_x)
    # Put the major axis first: e0 > e1, point (y0, y1) in the first quadrant.
    (e0, y0), (e1, y1) = ((semi_x, x), (semi_z, z)) if semi_x > semi_z else ((semi_z, z), (semi_x, x))
    with np.errstate(divide="ignore", invalid="ignore"):
        z0, z1 = y0 / e0, y1 / e1
        g = z0 * z0 + z1 * z1 - 1.0
        r0 = (e0 / e1) ** 2
        n0 = r0 * z0
        lo = z1 - 1.0
        hi = np.where(g < 0.0, 0.0, np.hypot(n0, z1) - 1.0)
        for _ in range(200):
            s = 0.5 * (lo + hi)
            ratio0, ratio1 = n0 / (s + r0), z1 / (s + 1.0)
            f = ratio0 * ratio0 + ratio1 * ratio1 - 1.0
            lo = np.where(f > 0.0, s, lo)
            hi = np.where(f > 0.0, hi, s)
        s = 0.5 * (lo + hi)
        general = np.hypot(r0 * y0 / (s + r0) - y0, y1 / (s + 1.0) - y1)
        # On the minor axis (y0 = 0) the closest point is the co-vertex.
        minor = np.abs(y1 - e1)
        # On the major axis (y1 = 0): inside the evolute's cusp the closest point is off-axis.
        numer, denom = e0 * y0, e0 * e0 - e1 * e1
        x0 = e0 * numer / denom
        inside = numer < denom
        off_axis = np.hypot(x0 - y0, e1 * np.sqrt(np.clip(1.0 - (x0 / e0) ** 2, 0.0, None)))
        major = np.where(inside, off_axis, np.abs(y0 - e0))
    return np.where(y1 > 0.0, np.where(y0 > 0.0, general, minor), major)


Constraint = Pin | Rod | Line | Ellipse
CONSTRAINT_KINDS: dict[str, type] = {"pin": Pin, "rod": Rod, "line": Line, "ellipse": Ellipse}


class SceneLike(Protocol):
    """What the harness and every engine read of a scene, catalog (:class:`Scene`) or model file
    (engines.model.scene.ModelScene) alike.

    particles : the point masses (a model's: its link frames); constraints : empty for a model.
    requires : the capabilities an engine needs to run it; is_model : a model file, run through
    ``Engine._run_model``. Lengths in m, energies in J, speeds in m/s, duration in s.
    """

    @property
    def name(self) -> str: ...
    @property
    def duration(self) -> float: ...
    @property
    def particles(self) -> Sequence[Any]: ...
    @property
    def constraints(self) -> Sequence[Any]: ...
    @property
    def gravity(self) -> Vector: ...
    @property
    def requires(self) -> frozenset[str]: ...
    @property
    def is_model(self) -> bool: ...
    @property
    def is_planar(self) -> bool: ...
    @property
    def masses(self) -> np.ndarray: ...
    @property
    def initial_positions(self) -> np.ndarray: ...
    @property
    def initial_velocities(self) -> np.ndarray: ...
    @property
    def characteristic_length(self) -> float: ...
    @property
    def characteristic_energy(self) -> float: ...
    @property
    def characteristic_speed(self) -> float: ...
    @property
    def content_hash(self) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...
    def with_duration(self, duration: float) -> "SceneLike": ...


class ModelSceneLike(SceneLike, Protocol):
    """A model scene (engines.model.scene.ModelScene) as an engine's ``_check_model`` / ``_run_model`` get it.

    file_dynamics : "neutral" (damping, friction, armature 0) or "keep" (the file's).
    """

    @property
    def file_dynamics(self) -> str: ...
    @property
    def floating_base(self) -> bool:
        """True when the model's base is free (a floating joint between the world and its root link)."""
        ...
    @property
    def ball_joints(self) -> tuple[str, ...]:
        """The model's ball joints (a quaternion in q, three velocities each), by name."""
        ...
    @property
    def file_format(self) -> str:
        """The model file's format: "urdf" or "mjcf"."""
        ...
    def refuse_kept_dynamics(self, engine: str) -> None:
        """Unsupported when the scene keeps the file's joint damping, which ``engine``'s import cannot."""


@dataclass(frozen=True, eq=False)
class Scene:
    """A physical system every engine is asked to simulate.

    name : catalog name the scene was built from (or any label).
    particles : the point masses.
    constraints : Pin, Rod, Line and Ellipse records; indices refer to ``particles``.
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
    #: False: particles and constraints. A model file (engines.model.scene.ModelScene) says True, and
    #: Engine.check / Engine.simulate route it to the adapter's _check_model / _run_model.
    is_model: ClassVar[bool] = False

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
        ys += [y for c in self.constraints if isinstance(c, Line) for y in (c.point[1], c.direction[1])]
        ys += [c.centre[1] for c in self.constraints if isinstance(c, Ellipse)]
        ys.append(self.gravity[1])
        return all(y == 0.0 for y in ys)

    # Cached (a Scene does not change after construction): a run's records read these for every case.
    @cached_property
    def characteristic_length(self) -> float:
        """L (m): the sum of constraint lengths (wire radius for a bead; a Line adds nothing,
        an Ellipse its larger semi-axis)."""
        return float(sum(c.characteristic_length for c in self.constraints)) or 1.0

    @cached_property
    def characteristic_gravity(self) -> float:
        """|g| m/s², or 1 m/s² when g = 0 (the fallback of a scene at rest; see characteristic_energy)."""
        return float(np.linalg.norm(self.gravity)) or 1.0

    @cached_property
    def initial_kinetic_energy(self) -> float:
        """T₀ = ½ Σ mᵢ ‖vᵢ(0)‖² (J)."""
        return 0.5 * float((self.masses * (self.initial_velocities**2).sum(axis=1)).sum())

    @cached_property
    def characteristic_energy(self) -> float:
        """E* (J) = total mass · |g| · L; when g = 0, the initial kinetic energy T₀ (no potential to
        measure against); when g = 0 and T₀ = 0 (a scene at rest), total mass · L · 1 m/s²."""
        if not np.any(self.gravity) and self.initial_kinetic_energy > 0:
            return self.initial_kinetic_energy
        return float(self.masses.sum()) * self.characteristic_gravity * self.characteristic_length

    @cached_property
    def characteristic_speed(self) -> float:
        """v* (m/s) = √(|g| L); when g = 0, √(2 T₀ / total mass), the speed at which the whole mass
        carries T₀; √(L · 1 m/s²) for a scene at rest."""
        if not np.any(self.gravity) and self.initial_kinetic_energy > 0:
            return float(np.sqrt(2.0 * self.initial_kinetic_energy / float(self.masses.sum())))
        return float(np.sqrt(self.characteristic_gravity * self.characteristic_length))

    # -- validation ------------------------------------------------------------

    def _check_initial_state(self) -> None:
        q = self.initial_positions
        v = self.initial_velocities
        speed_scale = max(float(np.abs(v).max()), 1.0)
        for k, c in enumerate(self.constraints):
            if isinstance(c, (Line, Ellipse)):
                self._check_on_curve(k, c, q[c.particle], v[c.particle], speed_scale)
                continue
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

    def _check_on_curve(self, k: int, c: "Line | Ellipse", q: np.ndarray, v: np.ndarray, speed_scale: float) -> None:
        """The particle starts on the line / wire, moving along it."""
        scale = max(c.characteristic_length, 1.0)
        distance = float(c.distances(q))
        if distance > POSITION_TOLERANCE * scale:
            raise SceneError(
                f"constraints[{k}] ({c.kind}): particle {c.particle} starts {distance:.3g} m off the {c.kind}; "
                f"place it on the {c.kind}"
            )
        if isinstance(c, Line):
            off = float(np.linalg.norm(v - (v @ c.unit) * c.unit))
        else:
            normal = c.normals(q)
            off = abs(float(normal @ v)) + abs(v[1])
        if off > VELOCITY_TOLERANCE * speed_scale:
            raise SceneError(
                f"constraints[{k}] ({c.kind}): the initial velocity of particle {c.particle} leaves the "
                f"{c.kind}; give it a velocity along the {c.kind}"
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

    @cached_property
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
    if isinstance(c, Line):
        return {"kind": "line", "particle": c.particle, "point": list(c.point), "direction": list(c.direction)}
    if isinstance(c, Ellipse):
        return {"kind": "ellipse", "particle": c.particle, "centre": list(c.centre),
                "semi_x": c.semi_x, "semi_z": c.semi_z}
    return {"kind": "rod", "a": c.a, "b": c.b, "length": c.length}
