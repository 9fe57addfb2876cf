"""ours' own records of a rigid-body mechanism: bodies, joints, the tree, and its initial state.

A :class:`Body` is a mass, its centre of mass (COM) and its inertia about the COM, both in the
body frame. A :class:`Joint` connects a parent body (or the world, parent = -1) to a child body
like a URDF joint: ``origin`` places the joint frame in the parent's frame, the child's frame is
the joint frame moved by the joint coordinate along or about ``axis`` (in the joint frame).
Nothing here knows about files or engines: an adapter maps its model description onto these.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ours.errors import ModelError

#: Joint kinds and the constraint rows each removes (of the 6 relative freedoms).
ROWS = {"revolute": 5, "prismatic": 5, "fixed": 6, "ball": 3}
#: Joint coordinates each kind carries (a ball's are not offered as initial state: it starts at rest, aligned).
DOFS = {"revolute": 1, "prismatic": 1, "fixed": 0, "ball": 3}


def _vector(value, name: str, shape) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape or not np.isfinite(array).all():
        raise ModelError(f"{name}: expected {shape} finite numbers, got {value!r}")
    return array


@dataclass(frozen=True, eq=False)
class Body:
    """name; mass (kg, > 0); com (3,) m in the body frame; inertia (3, 3) kg·m² about the COM, body axes."""

    name: str
    mass: float
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        if not np.isfinite(self.mass) or self.mass <= 0.0:
            raise ModelError(f"body {self.name}: mass must be positive (kg), got {self.mass!r}")
        object.__setattr__(self, "com", _vector(self.com, f"body {self.name}: com", (3,)))
        inertia = _vector(self.inertia, f"body {self.name}: inertia", (3, 3))
        if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(inertia).max())):
            raise ModelError(f"body {self.name}: inertia must be symmetric")
        if np.linalg.eigvalsh(inertia).min() <= 0.0:
            raise ModelError(f"body {self.name}: inertia must be positive definite (every principal moment > 0 kg·m²)")
        object.__setattr__(self, "inertia", inertia)


@dataclass(frozen=True, eq=False)
class Joint:
    """name; kind (revolute, prismatic, fixed, ball); parent body index (-1 = world); child body index;
    origin_xyz (3,) m and origin_rotation (3, 3) of the joint frame in the parent's frame;
    axis (3,) in the joint frame (normalised; ignored by fixed and ball)."""

    name: str
    kind: str
    parent: int
    child: int
    origin_xyz: np.ndarray = field(default_factory=lambda: np.zeros(3))
    origin_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        if self.kind not in ROWS:
            raise ModelError(f"joint {self.name}: kind {self.kind!r} is not one of {', '.join(ROWS)}")
        object.__setattr__(self, "origin_xyz", _vector(self.origin_xyz, f"joint {self.name}: origin_xyz", (3,)))
        rotation = _vector(self.origin_rotation, f"joint {self.name}: origin_rotation", (3, 3))
        if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
            raise ModelError(f"joint {self.name}: origin_rotation must be a rotation matrix")
        object.__setattr__(self, "origin_rotation", rotation)
        axis = _vector(self.axis, f"joint {self.name}: axis", (3,))
        norm = np.linalg.norm(axis)
        if norm < 1e-12:
            raise ModelError(f"joint {self.name}: axis must be a non-zero vector")
        object.__setattr__(self, "axis", axis / norm)

    @property
    def frame(self) -> np.ndarray:
        """(3, 3) a rotation whose third column is the axis: the joint's constraint frame, in the joint frame."""
        return axis_frame(self.axis)


def axis_frame(axis: np.ndarray) -> np.ndarray:
    """(3, 3) a right-handed orthonormal frame whose third column is ``axis`` (unit)."""
    a = np.asarray(axis, dtype=float)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1)
    return np.column_stack((e1, np.cross(a, e1), a))


@dataclass(frozen=True, eq=False)
class Mechanism:
    """Bodies, joints (a forest: each body is the child of at most one joint, parents listed first
    not required) and gravity (3,) m/s²."""

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))

    def __post_init__(self) -> None:
        object.__setattr__(self, "bodies", tuple(self.bodies))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "gravity", _vector(self.gravity, "gravity", (3,)))
        n = len(self.bodies)
        if n == 0:
            raise ModelError("bodies: a mechanism needs at least one body")
        inbound: dict[int, Joint] = {}
        for joint in self.joints:
            if not (0 <= joint.child < n) or not (-1 <= joint.parent < n) or joint.parent == joint.child:
                raise ModelError(f"joint {joint.name}: parent {joint.parent} / child {joint.child} must be body indices "
                                 f"(0..{n - 1}, parent -1 for the world) and differ")
            if joint.child in inbound:
                raise ModelError(f"joint {joint.name}: body {self.bodies[joint.child].name} is already the child of "
                                 f"joint {inbound[joint.child].name}; loops are not supported (the mechanism must be a tree)")
            inbound[joint.child] = joint
        for start in range(n):  # no cycles: walking up from any body reaches the world or a free body
            seen, body = set(), start
            while body in inbound:
                if body in seen:
                    raise ModelError(f"joints: body {self.bodies[start].name} is on a loop of joints; the mechanism must be a tree")
                seen.add(body)
                body = inbound[body].parent

    @property
    def moving_joints(self) -> list[int]:
        """Indices of the joints with one coordinate (revolute, prismatic), in listed order."""
        return [k for k, j in enumerate(self.joints) if DOFS[j.kind] == 1]

    def topological_joints(self) -> list[int]:
        """Joint indices ordered so that every joint comes after the joint that places its parent."""
        inbound = {j.child: k for k, j in enumerate(self.joints)}
        depth = {}

        def level(body: int) -> int:
            if body < 0 or body not in inbound:
                return 0
            if body not in depth:
                depth[body] = 1 + level(self.joints[inbound[body]].parent)
            return depth[body]

        return sorted(range(len(self.joints)), key=lambda k: level(self.joints[k].child))
