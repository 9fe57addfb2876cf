"""A model file as a scene: what an engine steps and the reference solves, in the catalog scenes' terms.

A :class:`ModelScene` is a model file (``engines.model.source``), an initial
state by joint name (SI: rad, m, rad/s, m/s; every joint not named starts at
0), a duration and what to do with the file's joint damping, friction and
armature (``file_dynamics``: "neutral" sets them to 0, "keep" leaves them),
and gravity g along −z (9.81 m/s² unless the scene's parameter ``g`` says).
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
from typing import Any, Mapping, Sequence

import numpy as np

from engines.errors import Unsupported
from engines.model.description import BALL_CONFIG, BALL_VELOCITY, ModelDescription, ModelError
from engines.model.loaded import GRAVITY
from engines.model.source import ModelSource, resolve

#: What a model scene does with the file's joint damping, friction and armature.
FILE_DYNAMICS = ("neutral", "keep")
#: Default simulated time of a model scene, s.
DEFAULT_DURATION = 2.0


def describe(source: ModelSource, base: str = "fixed") -> ModelDescription:
    """The description of ``source`` (URDF or MJCF); ModelError naming what it cannot hold.

    A URDF's mimic joints are simulated as independent joints (their ``<mimic>`` dropped for every engine
    alike: the tree's dynamics, no coupling), so the Panda's second finger is a joint of its own. ``base`` :
    a URDF's root "fixed" to the world or "floating" (an MJCF says its own: a free joint).
    """
    if source.format == "urdf":
        from engines.model.urdf import read as read_urdf

        return read_urdf(source, mimic_independent=True, floating=base == "floating")
    # MJCF means what MuJoCo's compiler makes of it: the engine that declares the format reads it.
    from engines.registry import describer

    return describer(source.format)(source)


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
    #: m/s², the gravity along −z (the catalog's parameter g; 0 for a model in free fall or in space).
    g: float = GRAVITY
    #: ((joint, value), …): joints welded at their initial value (rad or m), in every engine's text.
    lock: tuple[tuple[str, float], ...] = ()
    #: A URDF's root "fixed" to the world or "floating" (an MJCF says its own: a free joint).
    root_joint: str = "fixed"

    #: What tells a model scene from a catalog one (engines refuse it without the "model" capability).
    is_model = True
    is_planar = False
    requires = frozenset({"3d", "model"})
    constraints: tuple = ()

    # -- the file ----------------------------------------------------------------------------

    @property
    def source(self) -> ModelSource:
        return _source(self.model, self.path, self.digest, self.lock)

    @property
    def description(self) -> ModelDescription:
        return _description(self.model, self.path, self.digest, self.lock, self.root_joint)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The moving joints, in the model's order."""
        return tuple(j.name for j in self.description.moving_joints)

    @property
    def kinematics(self) -> "FrameKinematics":
        """The frames, energy and momentum of this scene's file, lock and base (cached per file: :func:`_kinematics`)."""
        return _kinematics(self.model, self.path, self.digest, self.lock, self.root_joint)

    @property
    def floating_base(self) -> bool:
        """True when the model's base is free (an MJCF free joint, or a URDF's root with base = "floating")."""
        return self.description.floating is not None

    @property
    def ball_joints(self) -> tuple[str, ...]:
        """The model's ball joints (a quaternion in q, three velocities each), by name."""
        return tuple(j.name for j in self.description.balls)

    @property
    def file_format(self) -> str:
        """The model file's format: "urdf" or "mjcf"."""
        return self.description.format

    @property
    def config_names(self) -> tuple[str, ...]:
        """A name per configuration entry, the order of q and of the CSV's ``q_`` columns: with a floating
        base ``BASE.x``, ``.y``, ``.z`` (m) and ``BASE.qx``, ``.qy``, ``.qz``, ``.qw`` first, then the joints (a
        ball joint's quaternion ``J.qx`` … ``J.qw``)."""
        return (*_base_names(self.description, BASE_CONFIG), *self.description.joint_config_names)

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """A name per velocity entry, the order of v and of the CSV's ``v_`` columns: with a floating base
        ``BASE.vx`` … ``BASE.wz`` (m/s, rad/s, in the base frame) first, then the joints (a ball joint's
        ``J.wx``, ``J.wy``, ``J.wz``, rad/s in the child frame)."""
        return self.description.dof_names

    def split(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q (n, nconfig), v (n, nv)) of joint states (n, nconfig + nv)."""
        n = self.description.nconfig
        return states[:, :n], states[:, n:]

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
        return (0.0, 0.0, -self.g if self.g else 0.0)

    @property
    def _scale_gravity(self) -> float:
        """g for the scales (E*, the speed): Earth's when g = 0, so that they stay defined."""
        return self.g if self.g > 0 else GRAVITY

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
        return self._scale_gravity

    @property
    def characteristic_energy(self) -> float:
        """E* = (total mass of the moving links) · g · L, J."""
        return float(self.masses.sum()) * self._scale_gravity * self.characteristic_length

    @property
    def characteristic_speed(self) -> float:
        return math.sqrt(self._scale_gravity * self.characteristic_length)

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
        """Link frame origins (n, L, 3) m and their velocities (n, L, 3) m/s at states q (n, nconfig), v (n, nv)."""
        return self.kinematics.frames(q, v)

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(n,) J: kinetic (translational and rotational) plus gravitational energy at q, v (n, nq),
        with the file's mass properties (the reference's reading of them)."""
        return self.kinematics.energy(q, v, self.g)

    def conserved_momenta(self) -> tuple[str, ...]:
        """With a floating base, the components of the total momentum in the world that nothing changes: every
        one when g = 0, else the horizontal linear ones and the angular one about the vertical through the
        origin (gravity's torque about it vanishes); without one, :meth:`conserved_joints`."""
        if self.description.floating is None:
            return self.conserved_joints()
        return WORLD_MOMENTA if self.g == 0 else ("px", "py", "Lz")

    def conserved_joints(self) -> tuple[str, ...]:
        """The moving joints on the (fixed) root whose momentum nothing changes: (M v)_j is the momentum of
        everything joint j carries, about its axis (revolute, continuous) or along it (prismatic), and only
        gravity acts on that subtree beside the joint: conserved when g = 0, or when the axis is parallel
        (revolute) or perpendicular (prismatic) to gravity. A ball joint on the root: the angular momentum of
        what it carries about its centre, in the world (``J.Lx``, ``J.Ly``, ``J.Lz``): every component when
        g = 0, else the vertical one (gravity's torque about the centre is horizontal)."""
        description, out = self.description, list[str]()
        for joint in description.moving_joints:
            if joint.parent != description.root:
                continue
            if joint.type == "ball":
                out.extend(f"{joint.name}.L{a}" for a in ("xyz" if self.g == 0 else "z"))
                continue
            axis = _root_axis(description, joint)
            along = abs(axis[2])  # gravity is along −z
            if self.g == 0 or (joint.type == "prismatic" and along < 1e-12) or \
                    (joint.type != "prismatic" and along > 1 - 1e-12):
                out.append(joint.name)
        return tuple(out)

    def momentum_drift(self, q: np.ndarray, v: np.ndarray) -> float | None:
        """max over :meth:`conserved_momenta` and samples of |p_j(t) − p_j(0)| / scale at states q (n, nconfig),
        v (n, nv): p = M(q) v for a root joint (a root ball joint's rows turned into the world); with a floating base, the total linear momentum and the angular
        momentum about the world origin, in the world. Scale M·L·√(g·L) about an axis, M·√(g·L) along one (M
        the moving links' mass, L the reach, g Earth's when the scene's is 0). None when nothing qualifies; 0
        for one sample."""
        names = self.conserved_momenta()
        if not names:
            return None
        if len(q) < 2:
            return 0.0
        momentum = self.kinematics.momentum(q, v)
        speed = float(self.masses.sum()) * self.characteristic_speed
        worst = 0.0
        if self.description.floating is not None:
            for k, name in enumerate(WORLD_MOMENTA):
                if name in names:
                    scale = speed * (1.0 if name.startswith("p") else self.characteristic_length)
                    worst = max(worst, float(np.abs(momentum[:, k] - momentum[0, k]).max()) / scale)
            return worst
        description = self.description
        for name in names:
            if name in description.slots:
                series = momentum[:, description.slots[name][1].start]
                along = description.joint(name).type == "prismatic"
            else:  # a root ball joint's angular momentum, one world component
                joint, part = name.rsplit(".", 1)
                series, along = _ball_momentum(description, joint, q, momentum)[:, "xyz".index(part[-1])], False
            scale = speed * (1.0 if along else self.characteristic_length)
            worst = max(worst, float(np.abs(series - series[0]).max()) / scale)
        return worst

    # -- stepping ----------------------------------------------------------------------------------

    def refuse_kept_dynamics(self, engine: str) -> None:
        """Unsupported when this scene keeps the file's joint damping and ``engine``'s import cannot."""
        if self.file_dynamics == "keep":
            raise Unsupported(f"{engine}: file_dynamics = \"keep\" is not supported here (its import sets joint "
                              f"damping to 0 before the model is finalised); use \"neutral\"")

    # -- identity ----------------------------------------------------------------------------------

    @property
    def content_hash(self) -> str:
        """The file's text, the initial state, the duration and file_dynamics: everything the physics depends on."""
        key = hashlib.sha256(self.digest.encode())
        key.update(json.dumps([self.q0, self.v0, self.duration, self.file_dynamics]
                              + ([] if self.g == GRAVITY else [self.g]) + ([list(self.lock)] if self.lock else [])
                              + ([self.root_joint] if self.root_joint != "fixed" else [])).encode())
        return key.hexdigest()[:16]

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "model", "name": self.name, "model": self.model, "path": self.path,
                "q0": dict(self.q0), "v0": dict(self.v0), "duration": self.duration,
                "file_dynamics": self.file_dynamics, "digest": self.digest, "g": self.g, "lock": dict(self.lock),
                **({"base": self.root_joint} if self.root_joint != "fixed" else {}),
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
                file_dynamics: str = "neutral", g: Any = GRAVITY, lock: Sequence[str] = (),
                root_joint: str = "fixed") -> ModelScene:
    """A ModelScene from user units: q0 in degrees (revolute, continuous) or metres (prismatic), v0 in
    rad/s or m/s, by joint name; every moving joint not named starts at 0. ``root_joint`` : a URDF's root
    "fixed" to the world or "floating" (a suite's ``base``). ModelError naming the field."""
    source = resolve(model, base)
    if root_joint not in ("fixed", "floating"):
        raise ModelError(f"model {model}: base must be \"fixed\" or \"floating\", got {root_joint!r}")
    if root_joint == "floating" and source.format != "urdf":
        raise ModelError(f"model {model}: base = \"floating\" is for a URDF; an MJCF's base floats when its root "
                         f"body has a free joint")
    digest = _digest(source.text)
    description = _description(model, str(source.path), digest, (), root_joint)
    if lock:
        welded = _lock_values(model, description, q0 or {}, lock)
        description = _description(model, str(source.path), digest, welded, root_joint)
        q0 = {k: value for k, value in (q0 or {}).items() if k not in dict(welded)}
    else:
        welded = ()
    if description.nq == 0:
        raise ModelError(f"model {model}: it has no moving joints (revolute, continuous or prismatic); "
                         f"there is nothing to simulate")
    if file_dynamics not in FILE_DYNAMICS:
        raise ModelError(f"model {model}: file_dynamics must be one of {', '.join(FILE_DYNAMICS)}, "
                         f"got {file_dynamics!r}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ModelError(f"model {model}: duration must be a positive number of seconds, got {duration!r}")
    try:
        gravity = float(g)
    except (TypeError, ValueError):
        gravity = math.nan
    if not (math.isfinite(gravity) and gravity >= 0):
        raise ModelError(f"model {model}: g must be a finite number of m/s² ≥ 0 (along −z), got {g!r}")
    joints = description.moving_joints
    rubbing = [j.name for j in joints if j.friction]
    if file_dynamics == "keep" and rubbing:
        raise ModelError(f"model {model}: file_dynamics = \"keep\" with joint friction ({', '.join(rubbing)}): the "
                         f"reference has no Coulomb friction; use \"neutral\" (friction and damping set to 0)")
    angular = {j.name: j.type != "prismatic" for j in joints if j.type != "ball"}
    base_q, base_v = _base_state(model, description, q0 or {}, v0 or {})
    floating = () if description.floating is None else (description.floating.name,)
    whole = (*floating, *(j.name for j in description.balls))  # given as lists, checked apart
    given_q = _by_joint(model, "q0", {k: x for k, x in (q0 or {}).items() if k not in whole}, angular)
    given_v = _by_joint(model, "v0", {k: x for k, x in (v0 or {}).items() if k not in whole}, angular)
    q, v = base_q, base_v
    for j in joints:
        if j.type == "ball":
            ball_q, ball_v = _ball_state(model, j.name, q0 or {}, v0 or {})
            q, v = q + ball_q, v + ball_v
            continue
        q += ((j.name, math.radians(given_q[j.name]) if angular[j.name] else given_q[j.name]) if j.name in given_q
              else (j.name, 0.0),)
        v += ((j.name, given_v.get(j.name, 0.0)),)
    parameters = {"model": model, "q0": dict(q0 or {}), "v0": dict(v0 or {}), "file_dynamics": file_dynamics,
                  **({} if gravity == GRAVITY else {"g": gravity}), **({"lock": list(lock)} if lock else {}),
                  **({"base": root_joint} if root_joint != "fixed" else {})}
    return ModelScene(name, model, str(source.path), q, v, float(duration), file_dynamics, parameters, digest, gravity,
                      welded, root_joint)


#: A floating base's configuration entries (position m, quaternion x y z w) and velocity entries.
BASE_CONFIG = ("x", "y", "z", "qx", "qy", "qz", "qw")
BASE_VELOCITY = ("vx", "vy", "vz", "wx", "wy", "wz")
#: The total momentum of a free model in the world: linear (kg·m/s), angular about the origin (kg·m²/s).
WORLD_MOMENTA = ("px", "py", "pz", "Lx", "Ly", "Lz")


def _base_names(description: ModelDescription, parts: Sequence[str]) -> tuple[str, ...]:
    return () if description.floating is None else tuple(f"{description.floating.name}.{a}" for a in parts)


def _base_state(model: str, description: ModelDescription, q0: Mapping[str, Any],
                v0: Mapping[str, Any]) -> tuple[tuple[tuple[str, float], ...], tuple[tuple[str, float], ...]]:
    """The floating base's initial entries by name: q0.BASE = [x, y, z, qx, qy, qz, qw] (m; a quaternion,
    normalised here; default the origin, unturned), v0.BASE = [vx, vy, vz, wx, wy, wz] (m/s, rad/s, in the base
    frame; default at rest). ModelError naming the field."""
    if description.floating is None:
        return (), ()
    return _listed_state(model, description.floating.name, "the floating base", q0, v0, (BASE_CONFIG, BASE_VELOCITY),
                         ("[x, y, z, qx, qy, qz, qw] (m, a nonzero quaternion)",
                          "[vx, vy, vz, wx, wy, wz] (m/s, rad/s, in the base frame)"))


def _ball_state(model: str, name: str, q0: Mapping[str, Any],
                v0: Mapping[str, Any]) -> tuple[tuple[tuple[str, float], ...], tuple[tuple[str, float], ...]]:
    """A ball joint's initial entries by name: q0.J = [qx, qy, qz, qw] (a quaternion, normalised here; default
    the identity), v0.J = [wx, wy, wz] (rad/s, the child's angular velocity in its own frame; default 0)."""
    return _listed_state(model, name, "a ball joint", q0, v0, (BALL_CONFIG, BALL_VELOCITY),
                         ("[qx, qy, qz, qw] (a nonzero quaternion)", "[wx, wy, wz] (rad/s, in the child link's frame)"))


def _listed_state(model: str, name: str, what_it_is: str, q0: Mapping[str, Any], v0: Mapping[str, Any],
                  parts: tuple[Sequence[str], Sequence[str]],
                  forms: tuple[str, str]) -> tuple[tuple[tuple[str, float], ...], tuple[tuple[str, float], ...]]:
    """The initial entries of a joint given as lists (or as text, numbers apart by commas or spaces), q0.NAME and
    v0.NAME (``parts``: the names of their entries;
    the configuration ends with a quaternion x y z w, normalised here; defaults: zeros, the identity quaternion).
    ModelError naming the field and its ``forms``."""
    out = []
    for what, given, names, form in (("q0", q0, parts[0], forms[0]), ("v0", v0, parts[1], forms[1])):
        default = (0.0,) * (len(names) - 1) + (1.0,) if what == "q0" else (0.0,) * len(names)
        raw = given.get(name, default)
        # From the command line a list is text: "0.1,0.2,0.3,0.9" or "[0.1, 0.2, 0.3, 0.9]".
        listed = raw.strip("[]() ").replace(",", " ").split() if isinstance(raw, str) else raw
        try:
            values = np.array(listed, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            values = np.zeros(0)
        if len(values) != len(default) or not np.all(np.isfinite(values)) or \
                (what == "q0" and np.linalg.norm(values[-4:]) == 0):
            raise ModelError(f"model {model}: {what}.{name} ({what_it_is}) must be {form}, got {raw!r}")
        if what == "q0":
            values[-4:] /= np.linalg.norm(values[-4:])
        out.append(tuple((f"{name}.{a}", float(x)) for a, x in zip(names, values)))
    return out[0], out[1]


def _lock_values(model: str, description: ModelDescription, q0: Mapping[str, Any],
                 lock: Sequence[str]) -> tuple[tuple[str, float], ...]:
    """((joint, value in SI), …) for the joints to weld: each at its q0 (degrees or metres), else 0."""
    joints = {j.name: j for j in description.moving_joints}
    unknown = [name for name in lock if name not in joints]
    if unknown:
        raise ModelError(f"model {model}: lock names joint {unknown[0]!r}, which is not one of its moving joints: "
                         f"{', '.join(joints)}")
    balls = [name for name in lock if joints[name].type == "ball"]
    if balls:
        raise ModelError(f"model {model}: lock names ball joint {balls[0]!r}; only revolute, continuous and "
                         f"prismatic joints can be locked, so leave it out of lock")
    angular = {name: joints[name].type != "prismatic" for name in lock}
    given = _by_joint(model, "q0", {k: v for k, v in q0.items() if k in angular}, angular)
    return tuple((name, math.radians(given.get(name, 0.0)) if angular[name] else given.get(name, 0.0))
                 for name in lock)


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
def _source(model: str, path: str, digest: str, lock: tuple[tuple[str, float], ...] = ()) -> ModelSource:
    """The file as the scene was made from it, ``lock``'s joints welded; ModelError when it has been edited since."""
    source = replace(resolve(path), label=model, lock=lock)
    if digest and _digest(source.text) != digest:
        raise ModelError(f"model {model}: {path} changed after the scene was made from it; run again")
    return source


@functools.lru_cache(maxsize=16)
def _description(model: str, path: str, digest: str, lock: tuple[tuple[str, float], ...] = (),
                 root_joint: str = "fixed") -> ModelDescription:
    return describe(_source(model, path, digest, lock), root_joint)


def _ball_momentum(description: ModelDescription, name: str, q: np.ndarray, momentum: np.ndarray) -> np.ndarray:
    """(n, 3) kg·m²/s: a root ball joint's rows of M v (the angular momentum of what it carries about its
    centre, in the child frame) turned into the world by the joint frame and the joint's rotation."""
    from engines.model.kinematics import quaternion_rotation, rpy_matrix

    joint = description.joint(name)
    where_q, where_v = description.slots[name]
    frame = rpy_matrix(joint.rpy)
    return np.array([frame @ quaternion_rotation(qk[where_q]) @ mk[where_v] for qk, mk in zip(q, momentum)])


def _root_axis(description: ModelDescription, joint) -> np.ndarray:
    """(3,) a root joint's axis in the world (the root is the world frame; its joint frame turned by rpy)."""
    from engines.model.kinematics import rpy_matrix

    return rpy_matrix(joint.rpy) @ np.asarray(joint.axis, dtype=float)


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
def _kinematics(model: str, path: str, digest: str, lock: tuple[tuple[str, float], ...] = (),
                root_joint: str = "fixed") -> "FrameKinematics":
    return FrameKinematics(_source(model, path, digest, lock), _description(model, path, digest, lock, root_joint))


class FrameKinematics:
    """Pinocchio's model of the file (the reference's), for link frames and energy at given joint states."""

    def __init__(self, source: ModelSource, description: ModelDescription) -> None:
        import pinocchio as pin

        from engines.model import pinocchio as reference_import

        self.pin = pin
        self.loaded = reference_import.load(source, description)
        model = self.loaded.model
        # By name and type: URDF lets a link and a joint share a name, and each has a frame of that name.
        self.frame_ids = [model.getFrameId(name, pin.FrameType.BODY) for name in description.moving_links]

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

    def momentum(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The generalised momenta M(q) v (n, nv) at states q (n, nconfig), v (n, nv); with a floating base
        instead the total momentum in the world (n, 6): linear (kg·m/s), then angular about the origin
        (kg·m²/s). The base rows of M v are the whole model's linear momentum and its angular momentum about
        the base origin, in the base frame (tests/test_floating_base.py measures this)."""
        from engines.model.floating import rotation

        loaded = self.loaded
        momenta = np.array([loaded.mass_matrix(qk) @ vk for qk, vk in zip(q, v)])
        if loaded.description.floating is None:
            return momenta
        out = np.empty((len(q), 6))
        for k, (qk, h) in enumerate(zip(q, momenta)):
            r = rotation(qk[3:7])
            out[k, :3] = r @ h[:3]
            out[k, 3:] = r @ h[3:6] + np.cross(qk[:3], out[k, :3])
        return out

    def energy(self, q: np.ndarray, v: np.ndarray, g: float = GRAVITY) -> np.ndarray:
        """(n,) J: kinetic plus potential energy in gravity g (m/s², along −z)."""
        pin, loaded = self.pin, self.loaded
        model, data = loaded.model, loaded.data
        model.gravity.linear = np.array([0.0, 0.0, -g])
        out = np.empty(len(q))
        for s in range(len(q)):
            config, rates = loaded.configuration(q[s]), loaded._vector(v[s])
            out[s] = pin.computeKineticEnergy(model, data, config, rates) + pin.computePotentialEnergy(model, data, config)
        return out
