"""The engine-neutral model description: what a URDF or MJCF file says, validated on construction.

A :class:`ModelDescription` is a tree of :class:`Body` records joined by :class:`Joint` records, the root
welded to the world (fixed base), gravity along −z, depth-first from the root (children in file order); the
moving joints in that order are the coordinates q (a continuous joint one angle, a ball joint a unit quaternion
x y z w with three velocities: the child's angular velocity in its own frame, Pinocchio's JointModelSpherical).
SI units: kg, m, kg·m², rad.

Refused with a :class:`ModelError` naming the link or joint and the fix: on
a link that moves, a negative mass or an inertia not positive semidefinite
(within PSD_TOLERANCE of the model's largest moment); joint types other than
revolute / continuous / prismatic / ball / fixed; loops, several roots; mimic joints
unless read as independent. Accepted with a note: such mass properties on a
link welded to the root (it cannot move), a moment negative within tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from engines.errors import UserError

Vector = tuple[float, float, float]
Matrix = tuple[Vector, Vector, Vector]

#: Joint types a description holds; every other type is refused. "floating" (six degrees of freedom) only
#: between the world and the base.
JOINT_TYPES = ("revolute", "continuous", "prismatic", "ball", "fixed", "floating")
#: Joint types that add a coordinate.
MOVING = ("revolute", "continuous", "prismatic", "ball")
#: A ball joint's configuration entries (a unit quaternion) and velocity entries (the child's angular velocity
#: in the child's frame, rad/s), each name prefixed by the joint's.
BALL_CONFIG = ("qx", "qy", "qz", "qw")
BALL_VELOCITY = ("wx", "wy", "wz")
#: Most negative principal moment accepted, relative to the largest principal moment of any link of the model
#: (round-off in a file's decimals, such as a lone product of inertia of 1e-20): a tenth of the parity check's
#: tolerance, so what it accepts changes M by less than the check can see (compare/model/tolerance.py).
PSD_TOLERANCE = 1e-7


class ModelError(UserError):
    """A model file the description cannot hold; the message names the link or joint and the fix."""


@dataclass(frozen=True)
class Inertial:
    """A link's mass properties as the file states them.

    mass : kg (≥ 0). com : (3,) m, the centre of mass in the link frame.
    inertia : (3, 3) kg·m², about the centre of mass, axes of the link frame
    (the file's inertial rotation already applied). declared : False when
    the file gives the link no ``<inertial>`` (then mass 0, inertia 0, as
    the URDF specification and urdfdom read it). rotated : the inertial
    frame's rpy was not zero (kept for the diagnosis).
    """

    mass: float = 0.0
    com: Vector = (0.0, 0.0, 0.0)
    inertia: Matrix = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    declared: bool = True
    rotated: bool = False

    @property
    def inertia_matrix(self) -> np.ndarray:
        """(3, 3) kg·m² about the COM, link axes."""
        return np.array(self.inertia, dtype=float)

    def check(self, link: str, scale: float | None = None) -> str:
        """ModelError naming ``link`` unless the mass is finite ≥ 0 and the inertia symmetric PSD, negative
        principal moments allowed down to −PSD_TOLERANCE·``scale`` (kg·m², the model's largest principal
        moment; default this inertia's own). Returns a note when a negative moment was accepted, else ""."""
        if not math.isfinite(self.mass) or self.mass < 0:
            raise ModelError(f"link {link}: mass {self.mass:g} kg is negative or not finite; "
                             f"give <inertial><mass value=…> a value ≥ 0")
        if not all(math.isfinite(c) for c in self.com):
            raise ModelError(f"link {link}: the <inertial><origin xyz> is not finite; give three finite numbers")
        matrix = self.inertia_matrix
        if not np.all(np.isfinite(matrix)) or not np.allclose(matrix, matrix.T, rtol=0, atol=1e-12 * (1 + np.abs(matrix).max())):
            raise ModelError(f"link {link}: the inertia is not a finite symmetric matrix; "
                             f"check <inertia ixx… izz>")
        moments = np.linalg.eigvalsh(matrix)
        allowed = PSD_TOLERANCE * max(abs(moments[-1]) if scale is None else scale, 1e-300)
        if moments[0] < -allowed:
            raise ModelError(f"link {link}: the inertia is not positive semidefinite (principal moments "
                             f"{', '.join(f'{m:.4g}' for m in moments)} kg·m²); give <inertia> whose principal "
                             f"moments are ≥ 0 (e.g. ixx, iyy, izz ≥ 0 with small products)")
        if moments[0] < 0:
            return (f"link {link}: smallest principal moment of inertia {moments[0]:.3g} kg·m² is negative within "
                    f"the tolerance ({PSD_TOLERANCE:g} of the model's largest, {allowed / PSD_TOLERANCE:.3g} kg·m²): "
                    f"accepted as positive semidefinite")
        return ""


@dataclass(frozen=True)
class Body:
    """A rigid link. parent_joint : the joint whose child it is (None for the root). virtual : a massless
    link the reader added between two joints of one MJCF body (no engine need have it; never compared)."""

    name: str
    parent_joint: str | None
    inertial: Inertial = field(default_factory=Inertial)
    virtual: bool = False


@dataclass(frozen=True)
class Limits:
    """A joint's range: lower, upper (rad or m; None when unbounded), effort (N·m or N), velocity."""

    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None


@dataclass(frozen=True)
class Joint:
    """A joint: the child's frame is at ``xyz``/``rpy`` in the parent's frame at q = 0.

    type : one of JOINT_TYPES. axis : (3,) unit vector in the child (= joint) frame (a ball joint has none).
    rpy : rad, fixed-axis roll, pitch, yaw (R = Rz(y) Ry(p) Rx(r)). damping, friction :
    what the file says (N·m·s/rad, N·m); the dynamics compared here leave them out.
    mimic : the joint this one mimics, when the file says so.
    """

    name: str
    type: str
    parent: str
    child: str
    axis: Vector = (1.0, 0.0, 0.0)
    xyz: Vector = (0.0, 0.0, 0.0)
    rpy: Vector = (0.0, 0.0, 0.0)
    limits: Limits = field(default_factory=Limits)
    damping: float = 0.0
    friction: float = 0.0
    mimic: str | None = None

    @property
    def moving(self) -> bool:
        return self.type in MOVING

    @property
    def nq(self) -> int:
        """Its configuration entries: 4 for a ball joint (a quaternion x y z w), 1 for another moving joint, else 0."""
        return 4 if self.type == "ball" else int(self.moving)

    @property
    def nv(self) -> int:
        """Its velocity entries: 3 for a ball joint (angular velocity in the child frame), 1 for another moving one."""
        return 3 if self.type == "ball" else int(self.moving)

    def check(self) -> None:
        if self.type not in JOINT_TYPES:
            raise ModelError(f"joint {self.name}: type {self.type!r} is not supported; "
                             f"use one of {', '.join(t for t in JOINT_TYPES if t not in ('floating', 'ball'))}")
        if not all(math.isfinite(c) for c in (*self.xyz, *self.rpy)):
            raise ModelError(f"joint {self.name}: <origin> is not finite; give finite xyz and rpy")
        if self.moving and self.type != "ball":
            norm = math.sqrt(sum(c * c for c in self.axis))
            if not math.isfinite(norm) or abs(norm - 1.0) > 1e-9:
                raise ModelError(f"joint {self.name}: the axis must be a unit vector, got {self.axis}; "
                                 f"give <axis xyz> a nonzero direction")
        lo, hi = self.limits.lower, self.limits.upper
        if lo is not None and hi is not None and lo > hi:
            raise ModelError(f"joint {self.name}: lower limit {lo:g} is above upper {hi:g}; swap them")


@dataclass(frozen=True)
class ModelDescription:
    """A kinematic tree. bodies, joints : depth-first from ``root``.

    A floating base is a joint of type "floating" from the root (the world: MuJoCo's ``world`` for an MJCF
    free joint, a massless ``__world__`` added for a URDF read with a floating base) to the base link, the
    first joint. Coordinates (Pinocchio's convention, the one inside xval): the configuration is (base
    position (3,) m, base orientation quaternion x y z w, joint q) and the velocity (base linear velocity
    (3,) m/s and angular velocity (3,) rad/s, both in the base frame, joint v); fixed base: joint q and v.
    A ball joint's q is its quaternion x y z w (the child frame's orientation in the joint's frame at q = 0)
    and its v the child's angular velocity in the child's frame (:attr:`slots` says where each joint sits).
    """

    name: str
    source: str
    format: str
    root: str
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    notes: tuple[str, ...] = ()
    mimic_independent: bool = False

    def __post_init__(self) -> None:
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ModelError(f"link {_first_repeat(names)} is declared twice; give every link a unique name")
        joint_names = [j.name for j in self.joints]
        if len(set(joint_names)) != len(joint_names):
            raise ModelError(f"joint {_first_repeat(joint_names)} is declared twice; give every joint a unique name")
        for joint in self.joints:
            joint.check()
            if joint.mimic is not None and not self.mimic_independent:
                raise ModelError(f"joint {joint.name}: mimic joints are not supported (it mimics {joint.mimic}); "
                                 f"remove its <mimic> element")
            for end in (joint.parent, joint.child):
                if end not in names:
                    raise ModelError(f"joint {joint.name}: link {end} is not declared; add a <link name=\"{end}\">")
        _check_tree(self)
        for k, joint in enumerate(self.joints):
            if joint.type == "floating" and (k > 0 or joint.parent != self.root or self.body(self.root).inertial.mass):
                raise ModelError(f"joint {joint.name}: a floating joint must join the world to the base; "
                                 f"make it the root body's only joint (a free joint in a top-level body)")
        object.__setattr__(self, "notes", (*self.notes, *(n for n in _inertia_notes(self) if n not in self.notes)))

    @cached_property
    def floating(self) -> Joint | None:
        """The floating joint between the world and the base (None: the root is welded to the world)."""
        return self.joints[0] if self.joints and self.joints[0].type == "floating" else None

    @property
    def base_dofs(self) -> int:
        """6 with a floating base, else 0: the velocity entries before the joints'."""
        return 6 if self.floating is not None else 0

    @property
    def nv(self) -> int:
        """Velocity size: base_dofs + the joints' (one each, three for a ball joint)."""
        return self.base_dofs + sum(j.nv for j in self.moving_joints)

    @property
    def nconfig(self) -> int:
        """Configuration size: 7 (position, quaternion) with a floating base, + nq."""
        return (7 if self.floating is not None else 0) + self.nq

    @property
    def dof_names(self) -> tuple[str, ...]:
        """A name per velocity entry: the base's six (``BASE.vx`` … ``BASE.wz``), then the joints (a ball
        joint's three ``J.wx``, ``J.wy``, ``J.wz``)."""
        base = () if self.floating is None else tuple(f"{self.floating.name}.{a}" for a in
                                                      ("vx", "vy", "vz", "wx", "wy", "wz"))
        return (*base, *(n for j in self.moving_joints for n in _entry_names(j, BALL_VELOCITY)))

    @property
    def joint_config_names(self) -> tuple[str, ...]:
        """A name per joint configuration entry (after the base's): the joint's, or ``J.qx`` … ``J.qw``."""
        return tuple(n for j in self.moving_joints for n in _entry_names(j, BALL_CONFIG))

    @cached_property
    def balls(self) -> tuple[Joint, ...]:
        """The ball joints, in q's order."""
        return tuple(j for j in self.moving_joints if j.type == "ball")

    @cached_property
    def slots(self) -> dict[str, tuple[slice, slice]]:
        """Moving joint name -> (its entries of the configuration, of the velocity), the base's counted."""
        out, at_q, at_v = {}, 7 if self.floating is not None else 0, self.base_dofs
        for joint in self.moving_joints:
            out[joint.name] = (slice(at_q, at_q + joint.nq), slice(at_v, at_v + joint.nv))
            at_q, at_v = at_q + joint.nq, at_v + joint.nv
        return out

    def neutral(self) -> np.ndarray:
        """(nconfig,) the zero configuration (the base at the origin, every orientation the identity)."""
        q = np.zeros(self.nconfig)
        if self.floating is not None:
            q[6] = 1.0
        for joint in self.balls:
            q[self.slots[joint.name][0].stop - 1] = 1.0
        return q

    @cached_property
    def moving_joints(self) -> tuple[Joint, ...]:
        """The joints that carry a coordinate, in q's order."""
        return tuple(j for j in self.joints if j.moving)

    @property
    def nq(self) -> int:
        """The joints' configuration size (the base's left out): one per joint, four per ball joint."""
        return sum(j.nq for j in self.moving_joints)

    def body(self, name: str) -> Body:
        return self._bodies[name]

    def joint(self, name: str) -> Joint:
        return self._joints[name]

    @cached_property
    def _bodies(self) -> dict[str, Body]:
        return {b.name: b for b in self.bodies}

    @cached_property
    def _joints(self) -> dict[str, Joint]:
        return {j.name: j for j in self.joints}

    @cached_property
    def moving_links(self) -> tuple[str, ...]:
        """Links with a moving joint between them and the world (the others cannot change the dynamics),
        the virtual ones left out."""
        moving: set[str] = set()
        for joint in self.joints:  # depth-first: a parent is settled before its children
            if joint.moving or joint.type == "floating" or joint.parent in moving:
                moving.add(joint.child)
        return tuple(b.name for b in self.bodies if b.name in moving and not b.virtual)


def _inertia_notes(model: ModelDescription) -> list[str]:
    """Check every link's mass properties against the model's inertia scale: ModelError for a link that
    moves; a note for one welded to the root (which cannot change the dynamics) or a negative moment accepted."""
    scale = max((float(np.abs(np.linalg.eigvalsh(b.inertial.inertia_matrix)).max())
                 for b in model.bodies if np.all(np.isfinite(b.inertial.inertia_matrix))), default=0.0)
    moving, notes = set(model.moving_links), []
    for body in model.bodies:
        try:
            note = body.inertial.check(body.name, scale)
        except ModelError as exc:
            if body.name in moving:
                raise
            note = (f"{str(exc).split('; ')[0]}: accepted, the link is welded to the root (it cannot move, so it "
                    f"cannot change the dynamics)")
        if note:
            notes.append(note)
    return notes


def _entry_names(joint: Joint, parts: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(f"{joint.name}.{a}" for a in parts) if joint.type == "ball" else (joint.name,)


def _first_repeat(names: list[str]) -> str:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            return name
        seen.add(name)
    return ""


def _check_tree(model: ModelDescription) -> None:
    """One root, every other link the child of exactly one joint, every link reachable from the root."""
    parents: dict[str, str] = {}
    for joint in model.joints:
        if joint.child in parents:
            raise ModelError(f"link {joint.child} is the child of joints {parents[joint.child]} and {joint.name}: "
                             f"closed loops are not supported; keep one joint and drop the other")
        parents[joint.child] = joint.name
    roots = [b.name for b in model.bodies if b.name not in parents]
    if len(roots) != 1:
        listed = ", ".join(roots) if roots else "none (every link has a parent: a loop)"
        raise ModelError(f"the model must have exactly one root link, found {listed}; "
                         f"connect the links into one tree")
    if roots[0] != model.root:
        raise ModelError(f"root link {model.root} is the child of a joint; the root is {roots[0]}")
    children: dict[str, list[str]] = {}
    for joint in model.joints:
        children.setdefault(joint.parent, []).append(joint.child)
    seen, stack = set(), [model.root]
    while stack:
        link = stack.pop()
        seen.add(link)
        stack.extend(children.get(link, []))
    unreachable = [b.name for b in model.bodies if b.name not in seen]
    if unreachable:
        raise ModelError(f"links {', '.join(unreachable)} form a loop cut off from root {model.root}; "
                         f"connect them into one tree")
