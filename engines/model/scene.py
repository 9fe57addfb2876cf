"""A model file as a scene: what an engine steps and the reference solves, in the catalog scenes' terms.

A :class:`ModelScene` is a model file (``engines.model.source``), an initial
state by joint name (SI: rad, m, rad/s, m/s; every joint not named starts at
0), a duration and what to do with the file's joint damping, friction and
armature (``file_dynamics``: "neutral" sets them to 0, "keep" leaves them).
Contacts and joint limits are always off. What the catalog's particles are
to its metrics, a model's link frames are here: ``frames`` are the moving
links, whose origins (positions, velocities) every engine reports, computed
by one kinematics for all (Pinocchio's, from the file) from each engine's
joint trajectory. Energy includes the links' rotational kinetic energy.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from engines.model.description import ModelDescription, ModelError
from engines.model.loaded import GRAVITY
from engines.model.source import ModelSource, resolve

#: What a model scene does with the file's joint damping, friction and armature.
FILE_DYNAMICS = ("neutral", "keep")
#: Default simulated time of a model scene, s.
DEFAULT_DURATION = 2.0


def describe(source: ModelSource) -> ModelDescription:
    """The description of ``source`` (URDF or MJCF); ModelError naming what it cannot hold.

    A URDF's mimic joints are simulated as independent joints (their ``<mimic>`` dropped for every engine
    alike: the tree's dynamics, no coupling), so the Panda's second finger is a joint of its own.
    """
    if source.format == "urdf":
        from engines.model.urdf import read as read_urdf

        return read_urdf(source, mimic_independent=True)
    from engines.model.mjcf import read as read_mjcf

    return read_mjcf(source)


@dataclass(frozen=True, eq=False)
class ModelScene:
    """A model file with an initial state, simulated for ``duration`` s.

    name : the scene's id. model : MODEL as given (a path or ``pybullet_data:<path>``).
    path : the file, resolved. q0, v0 : ((joint, value), ...) in SI, moving joints in model order.
    file_dynamics : "neutral" (damping, friction, armature 0) or "keep" (the file's).
    """

    name: str
    model: str
    path: str
    q0: tuple[tuple[str, float], ...]
    v0: tuple[tuple[str, float], ...]
    duration: float = DEFAULT_DURATION
    file_dynamics: str = "neutral"
    parameters: Mapping[str, Any] = field(default_factory=dict)
    #: sha256 of the file's text when the scene was made: the key of what is read from it (a file edited
    #: since is a different model).
    digest: str = ""

    #: What tells a model scene from a catalog one (engines refuse it without the "model" capability).
    is_model = True
    is_planar = False
    requires = frozenset({"3d", "model"})
    constraints: tuple = ()

    # -- the file ----------------------------------------------------------------------------

    @property
    def source(self) -> ModelSource:
        return _source(self.model, self.path, self.digest)

    @property
    def description(self) -> ModelDescription:
        return _description(self.model, self.path, self.digest)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The moving joints, in the model's order: the order of q, v and the CSV's columns."""
        return tuple(j.name for j in self.description.moving_joints)

    @property
    def frames(self) -> tuple[str, ...]:
        """The moving links, whose frame origins are compared (model order)."""
        return self.description.moving_links

    @property
    def particles(self) -> tuple[str, ...]:
        """The link frames, standing where a catalog scene's particles do (their count sizes the arrays)."""
        return self.frames

    @property
    def initial_q(self) -> np.ndarray:
        return np.array([value for _, value in self.q0])

    @property
    def initial_v(self) -> np.ndarray:
        return np.array([value for _, value in self.v0])

    # -- scales --------------------------------------------------------------------------------

    @property
    def gravity(self) -> tuple[float, float, float]:
        return (0.0, 0.0, -GRAVITY)

    @property
    def masses(self) -> np.ndarray:
        """(L,) kg: each compared link's mass as the file gives it."""
        return np.array([self.description.body(name).inertial.mass for name in self.frames])

    @property
    def characteristic_length(self) -> float:
        """L, m: the arm's reach, the longest path from the root to a moving link's centre of mass
        (joint offsets along the tree, then the centre of mass's offset)."""
        return _reach(self.description)

    @property
    def characteristic_gravity(self) -> float:
        return GRAVITY

    @property
    def characteristic_energy(self) -> float:
        """E* = (total mass of the moving links) · g · L, J."""
        return float(self.masses.sum()) * GRAVITY * self.characteristic_length

    @property
    def characteristic_speed(self) -> float:
        return math.sqrt(GRAVITY * self.characteristic_length)

    # -- states ----------------------------------------------------------------------------------

    @property
    def initial_positions(self) -> np.ndarray:
        """(L, 3) m: the link frames' origins at q0."""
        return self.frame_states(self.initial_q[None], self.initial_v[None])[0][0]

    @property
    def initial_velocities(self) -> np.ndarray:
        """(L, 3) m/s: the link frames' origin velocities at (q0, v0)."""
        return self.frame_states(self.initial_q[None], self.initial_v[None])[1][0]

    def frame_states(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Link frame origins (n, L, 3) m and their velocities (n, L, 3) m/s at joint states q, v (n, nq)."""
        return _kinematics(self.model, self.path, self.digest).frames(q, v)

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(n,) J: kinetic (translational and rotational) plus gravitational energy at q, v (n, nq),
        with the file's mass properties (the reference's reading of them)."""
        return _kinematics(self.model, self.path, self.digest).energy(q, v)

    # -- stepping ----------------------------------------------------------------------------------

    def refuse_kept_dynamics(self, engine: str) -> None:
        """Unsupported when this scene keeps the file's joint damping and ``engine``'s import cannot."""
        if self.file_dynamics == "keep":
            from engines.errors import Unsupported

            raise Unsupported(f"{engine}: file_dynamics = \"keep\" is not supported here (its import sets joint "
                              f"damping to 0 before the model is finalised); use \"neutral\"")

    # -- identity ----------------------------------------------------------------------------------

    @property
    def content_hash(self) -> str:
        """The file's text, the initial state, the duration and file_dynamics: everything the physics depends on."""
        key = hashlib.sha256(self.digest.encode())
        key.update(json.dumps([self.q0, self.v0, self.duration, self.file_dynamics]).encode())
        return key.hexdigest()[:16]

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "model", "name": self.name, "model": self.model, "path": self.path,
                "q0": dict(self.q0), "v0": dict(self.v0), "duration": self.duration,
                "file_dynamics": self.file_dynamics, "digest": self.digest,
                "particles": [{"link": name, "mass": float(m)} for name, m in zip(self.frames, self.masses)],
                "frame_parents": self.frame_parents()}

    def frame_parents(self) -> list[int | None]:
        """For each compared link frame, the index of the nearest compared ancestor frame (None: the root,
        fixed at the world's origin): the segments a report draws between joint frames."""
        description, index = self.description, {name: k for k, name in enumerate(self.frames)}
        parent_link = {j.child: j.parent for j in description.joints}
        out: list[int | None] = []
        for name in self.frames:
            up = parent_link.get(name)
            while up is not None and up not in index:
                up = parent_link.get(up)
            out.append(None if up is None else index[up])
        return out

    def with_duration(self, duration: float) -> "ModelScene":
        return replace(self, duration=float(duration))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ModelScene) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(self.content_hash)


def model_scene(name: str, model: str, *, base: Path | None = None, q0: Mapping[str, Any] | None = None,
                v0: Mapping[str, Any] | None = None, duration: float = DEFAULT_DURATION,
                file_dynamics: str = "neutral") -> ModelScene:
    """A ModelScene from user units: q0 in degrees (revolute, continuous) or metres (prismatic), v0 in
    rad/s or m/s, by joint name; every moving joint not named starts at 0. ModelError naming the field."""
    source = resolve(model, base)
    digest = _digest(source.text)
    description = _description(model, str(source.path), digest)
    if description.nq == 0:
        raise ModelError(f"model {model}: it has no moving joints (revolute, continuous or prismatic); "
                         f"there is nothing to simulate")
    if file_dynamics not in FILE_DYNAMICS:
        raise ModelError(f"model {model}: file_dynamics must be one of {', '.join(FILE_DYNAMICS)}, "
                         f"got {file_dynamics!r}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ModelError(f"model {model}: duration must be a positive number of seconds, got {duration!r}")
    joints = description.moving_joints
    rubbing = [j.name for j in joints if j.friction]
    if file_dynamics == "keep" and rubbing:
        raise ModelError(f"model {model}: file_dynamics = \"keep\" with joint friction ({', '.join(rubbing)}): the "
                         f"reference has no Coulomb friction; use \"neutral\" (friction and damping set to 0)")
    angular = {j.name: j.type != "prismatic" for j in joints}
    given_q = _by_joint(model, "q0", q0 or {}, angular)
    given_v = _by_joint(model, "v0", v0 or {}, angular)
    q = tuple((j.name, math.radians(given_q[j.name]) if angular[j.name] else given_q[j.name])
              if j.name in given_q else (j.name, 0.0) for j in joints)
    v = tuple((j.name, given_v.get(j.name, 0.0)) for j in joints)
    parameters = {"model": model, "q0": dict(q0 or {}), "v0": dict(v0 or {}), "file_dynamics": file_dynamics}
    return ModelScene(name, model, str(source.path), q, v, float(duration), file_dynamics, parameters, digest)


def _by_joint(model: str, what: str, values: Mapping[str, Any], angular: Mapping[str, bool]) -> dict[str, float]:
    out = {}
    for joint, raw in values.items():
        if joint not in angular:
            raise ModelError(f"model {model}: {what} names joint {joint!r}, which is not one of its moving "
                             f"joints: {', '.join(angular)}")
        try:
            value = float(raw)
        except (TypeError, ValueError):
            value = math.nan
        if not math.isfinite(value):
            unit = ("degrees" if angular[joint] else "metres") if what == "q0" else \
                   ("rad/s" if angular[joint] else "m/s")
            raise ModelError(f"model {model}: {what}.{joint} must be a finite number of {unit}, got {raw!r}")
        out[joint] = value
    return out


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


@functools.lru_cache(maxsize=16)
def _source(model: str, path: str, digest: str) -> ModelSource:
    """The file as the scene was made from it; ModelError when it has been edited since."""
    source = replace(resolve(path), label=model)
    if digest and _digest(source.text) != digest:
        raise ModelError(f"model {model}: {path} changed after the scene was made from it; run again")
    return source


@functools.lru_cache(maxsize=16)
def _description(model: str, path: str, digest: str) -> ModelDescription:
    return describe(_source(model, path, digest))


def _reach(description: ModelDescription) -> float:
    length = {description.root: 0.0}
    reach = 0.0
    for joint in description.joints:  # depth-first: the parent's path length is known
        length[joint.child] = length[joint.parent] + float(np.linalg.norm(joint.xyz))
        if joint.child in description.moving_links:
            com = float(np.linalg.norm(description.body(joint.child).inertial.com))
            reach = max(reach, length[joint.child] + com)
    return reach if reach > 0 else 1.0


@functools.lru_cache(maxsize=16)
def _kinematics(model: str, path: str, digest: str) -> "FrameKinematics":
    return FrameKinematics(_source(model, path, digest), _description(model, path, digest))


class FrameKinematics:
    """Pinocchio's model of the file (the reference's), for link frames and energy at given joint states."""

    def __init__(self, source: ModelSource, description: ModelDescription) -> None:
        import pinocchio as pin

        from engines.model import pinocchio as reference_import

        self.pin = pin
        self.loaded = reference_import.load(source, description)
        model = self.loaded.model
        self.frame_ids = [model.getFrameId(name) for name in description.moving_links]

    def frames(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pin, loaded = self.pin, self.loaded
        model, data = loaded.model, loaded.data
        n = len(q)
        positions, velocities = np.empty((n, len(self.frame_ids), 3)), np.empty((n, len(self.frame_ids), 3))
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for s in range(n):
            pin.forwardKinematics(model, data, loaded.configuration(q[s]), loaded._vector(v[s]))
            pin.updateFramePlacements(model, data)
            for k, frame in enumerate(self.frame_ids):
                positions[s, k] = data.oMf[frame].translation
                velocities[s, k] = pin.getFrameVelocity(model, data, frame, world).linear
        return positions, velocities

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        pin, loaded = self.pin, self.loaded
        model, data = loaded.model, loaded.data
        out = np.empty(len(q))
        for s in range(len(q)):
            config, rates = loaded.configuration(q[s]), loaded._vector(v[s])
            out[s] = pin.computeKineticEnergy(model, data, config, rates) + pin.computePotentialEnergy(model, data, config)
        return out
