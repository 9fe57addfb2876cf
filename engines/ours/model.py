"""ours' rigid bodies for a robot model: the engine-neutral description (engines/model) translated once.

Links welded by fixed joints are fused into the link they hang from (mass properties combined by the
parallel-axis theorem, ``engines.model.inertia``), and links welded to the root belong to the world
(when the base is fixed); continuous joints are revolute. A floating base is a body with no joint above it
(free, as maximal coordinates have it): its pose and velocity are its rigid body's state, mapped to xval's
convention (engines/model/floating.py) here; a ball joint is ours' ball (a point constraint between two bodies),
its quaternion and child-frame angular velocity passed as they are (x y z w read as ours' w x y z). ours never
reads the file. A moving group with no
mass, or whose inertia is not positive definite, is refused naming its links: maximal coordinates
give every moving body its own mass matrix, which must be invertible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engines.errors import Unsupported
from engines.model.description import ModelDescription
from engines.model.floating import continuous
from engines.model.inertia import combine, world_inertia
from engines.model.kinematics import rpy_matrix
from engines.model.stepping import Stepper, unbounded_joints
from ours import OursError
from ours.rigid import (
    Body, Joint, Mechanism, Stepping, ball_coordinates, frames, initial_state, joint_coordinates, joint_errors,
    quaternion, rotation_of, simulate,
)

GRAVITY = (0.0, 0.0, -9.81)


@dataclass(frozen=True, eq=False)
class OursModel:
    """mechanism : ours' bodies and joints (one body per moving group of links).
    carriers : link name -> (ours body index, -1 for the world; R (3, 3); p (3,) m): the link frame in
    that body's frame. joint_names : the moving joints, in the description's order (ours' q order).
    base : the floating base's body index (its body frame is the base link's frame), −1 when the base is fixed."""

    mechanism: Mechanism
    carriers: dict[str, tuple[int, np.ndarray, np.ndarray]]
    joint_names: tuple[str, ...]
    base: int = -1


def translate(description: ModelDescription, gravity=GRAVITY) -> OursModel:
    """ours' Mechanism for ``description`` (Unsupported, naming the links, when a moving group has no mass)."""
    carriers = {description.root: (-1, np.eye(3), np.zeros(3))}
    groups: list[list[str]] = []
    joints = []
    for j in description.joints:  # depth-first: the parent's carrier is known
        body, R, p = carriers[j.parent]
        Rj, pj = R @ rpy_matrix(j.rpy), p + R @ np.asarray(j.xyz, dtype=float)
        if j.type == "fixed":
            carriers[j.child] = (body, Rj, pj)
            if body >= 0:
                groups[body].append(j.child)
            continue
        carriers[j.child] = (len(groups), np.eye(3), np.zeros(3))
        groups.append([j.child])
        if j.type != "floating":  # a floating base is a free body: no joint above it
            joints.append((j, body, Rj, pj))
    bodies = []
    for links in groups:
        parts = [world_inertia(description.body(n).inertial.mass, description.body(n).inertial.com,
                               description.body(n).inertial.inertia_matrix, carriers[n][1], carriers[n][2])
                 for n in links]
        total = combine(parts)
        try:
            bodies.append(Body(links[0], total.mass, total.com, total.inertia))
        except OursError as error:
            raise Unsupported(f"ours: the moving link {' + '.join(links)} has mass {total.mass:g} kg and principal "
                              f"moments {', '.join(f'{m:.3g}' for m in np.linalg.eigvalsh(total.inertia))} kg·m²; "
                              f"maximal coordinates need a positive mass and inertia for every moving body "
                              f"({error})") from None
    ours_joints = tuple(Joint(j.name, "revolute" if j.type == "continuous" else j.type, parent, carriers[j.child][0],
                              pj, Rj, j.axis) for j, parent, Rj, pj in joints)
    mechanism = Mechanism(tuple(bodies), ours_joints, gravity)
    base = -1 if description.floating is None else carriers[description.floating.child][0]
    return OursModel(mechanism, carriers, tuple(j.name for j, *_ in joints), base)


def placed(model: OursModel, y: np.ndarray, pose: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """The state y (13 nb,) built with the floating base at the origin and at rest (``initial_state``), moved
    rigidly to the base pose (p (3,) m, quaternion x y z w) with the base velocity (linear m/s, angular rad/s,
    in the base frame) added to every body: x' = R x + p, v' = R v + V + Ω × (x' − p), ω' = R ω + Ω."""
    r = rotation_of(np.array([pose[6], *pose[3:6]]))
    linear, spin = r @ velocity[:3], r @ velocity[3:6]
    out = np.array(y, dtype=float)
    for b in range(len(model.mechanism.bodies)):
        o = 13 * b
        com = r @ y[o:o + 3] + pose[:3]
        out[o:o + 3] = com
        out[o + 3:o + 7] = quaternion(r @ rotation_of(y[o + 3:o + 7]))
        out[o + 7:o + 10] = r @ y[o + 7:o + 10] + linear + np.cross(spin, com - pose[:3])
        out[o + 10:o + 13] = r @ y[o + 10:o + 13] + spin
    return out


def of_scene(scene) -> OursModel:
    """ours' Mechanism for a model scene: its description translated under the scene's gravity."""
    return translate(scene.description, gravity=tuple(getattr(scene, "gravity", GRAVITY)))


def start_state(model: OursModel, scene) -> np.ndarray:
    """y0 (13 nb,): the model scene's initial joint state (q0, v0, and the floating base's pose and velocity; a ball
    joint's quaternion and child-frame rates) in ours' maximal coordinates."""
    start_q, start_v = np.asarray(scene.initial_q, dtype=float), np.asarray(scene.initial_v, dtype=float)
    floating, description = model.base >= 0, scene.description
    q0, v0 = {}, {}
    for name in model.joint_names:
        where_q, where_v = description.slots[name]
        ball = description.joint(name).type == "ball"
        q0[name] = np.roll(start_q[where_q], 1) if ball else float(start_q[where_q][0])  # x y z w -> w x y z
        v0[name] = start_v[where_v] if ball else float(start_v[where_v][0])
    y0 = initial_state(model.mechanism, q0, v0)
    return placed(model, y0, start_q[:7], start_v[:6]) if floating else y0


def base_state(model: OursModel, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The floating base's pose (7,) (p m, quaternion x y z w) and velocity (6,) (linear m/s and angular rad/s of
    the base frame, in the base frame) at the state y (13 nb,)."""
    o = 13 * model.base
    origins, rotations = frames(model.mechanism, y)
    r, origin = rotations[model.base], origins[model.base]
    w, x, yy, z = y[o + 3:o + 7] / np.linalg.norm(y[o + 3:o + 7])
    spin = y[o + 10:o + 13]
    velocity = y[o + 7:o + 10] + np.cross(spin, origin - y[o:o + 3])
    return np.array([*origin, x, yy, z, w]), np.concatenate([r.T @ velocity, r.T @ spin])


def link_origins(model: OursModel, y: np.ndarray, links) -> np.ndarray:
    """(S, len(links), 3) m: each named link frame's origin at the states y (S, 13 nb)."""
    origins, rotations = frames(model.mechanism, y)
    out = np.zeros(origins.shape[:-2] + (len(links), 3))
    for k, name in enumerate(links):
        body, _, p = model.carriers[name]
        out[..., k, :] = p if body < 0 else origins[..., body, :] + rotations[..., body, :, :] @ p
    return out


def run(model: OursModel, q0: dict, v0: dict, dt: float, n_steps: int, sample_every: int, **options):
    """Simulate from joint coordinates q0, v0 (by joint name; rad, m, rad/s, m/s). Returns
    (result, q (S, nq), v (S, nq)) with q unwrapped from q0 (ours' rows hold the angle only modulo 2π)."""
    result = simulate(model.mechanism, initial_state(model.mechanism, q0, v0), dt, n_steps, sample_every, **options)
    q, v = joint_coordinates(model.mechanism, result.y)
    start = np.array([float(q0.get(name, 0.0)) for name in model.joint_names])
    turns = np.round((start - q[0]) / (2 * np.pi)) if len(q) else np.zeros(len(start))
    revolute = np.array([j.kind == "revolute" for j in model.mechanism.joints], dtype=bool)
    if len(q):
        q[:, revolute] += 2 * np.pi * turns[revolute]
    return result, q, v


class OursStepper(Stepper):
    """A model scene in ours (the Stepper of ``engines.model.stepping``): translate the description,
    start from the scene's joint state, step with the variant's method and integrator. Revolute angles
    are read continuously from sample to sample (ours' rows fix them only modulo 2π). Its joints are
    constraint rows, so they can come apart: :meth:`constraint_violations` says by how much at each state read."""

    def __init__(self, scene, dt: float, method: str, integrator: str, **options) -> None:
        self.scene = scene
        self.model = of_scene(scene)
        floating = self.model.base >= 0
        start_q = np.asarray(scene.initial_q, dtype=float)
        description, names = scene.description, self.model.joint_names
        #: Per moving joint (description order): a ball joint or not.
        self._balls = [description.joint(n).type == "ball" for n in names]
        mech = self.model.mechanism
        self.run = Stepping(mech, start_state(self.model, scene), dt, method=method, integrator=integrator, **options)
        self._turn = start_q[3:7] if floating else np.zeros(4)
        self._last = np.array([start_q[description.slots[n][0]][0] for n, ball in zip(names, self._balls) if not ball])
        self._quaternions = {n: start_q[description.slots[n][0]].copy() for n, ball in zip(names, self._balls) if ball}
        self._revolute = np.array([mech.joints[k].kind == "revolute" for k in mech.moving_joints], dtype=bool)
        #: (13 nb,) the state behind each (q, v) that :meth:`state` returned; NaN once stepping failed.
        self._read: list[np.ndarray] = []
        self.settings = {"model": scene.model, "import": "engines.model description, translated by engines.ours.model",
                         "bodies": len(mech.bodies), "fused_links": {n: mech.bodies[b].name for n, (b, _, _) in
                                                                     self.model.carriers.items() if b >= 0 and
                                                                     mech.bodies[b].name != n},
                         "contacts": "off", "joint_limits": "off",
                         "unbounded_once_limits_off": unbounded_joints(scene), "file_dynamics": "neutral: joint damping, "
                         "friction and armature left out", **self.run.settings}

    def advance(self, steps: int) -> None:
        self.run.advance(steps)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        floating = self.model.base >= 0
        if self.run.status != "ok":
            self._read.append(np.full(len(self.run.y), np.nan))
            description = self.scene.description
            return np.full(description.nconfig, np.nan), np.full(description.nv, np.nan)
        self._read.append(self.run.y.copy())
        q, v = joint_coordinates(self.model.mechanism, self.run.y)
        turns = np.round((self._last - q) / (2 * np.pi))
        q[self._revolute] += 2 * np.pi * turns[self._revolute]
        self._last = q.copy()
        if self._quaternions:
            q, v = self._with_balls(q, v)
        if floating:
            pose, rates = base_state(self.model, self.run.y)
            pose[3:7] = self._turn = continuous(pose[3:7].copy(), self._turn)
            return np.concatenate([pose, q]), np.concatenate([rates, v])
        return q, v

    def _with_balls(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joints' (q, v) in the description's layout: each ball joint's quaternion (x y z w, kept continuous
        between reads) and child-frame rates put in place among the 1-degree-of-freedom joints' values."""
        balls = ball_coordinates(self.model.mechanism, self.run.y)
        scalar_q, scalar_v = iter(q), iter(v)
        parts_q: list[float] = []
        parts_v: list[float] = []
        for name, ball in zip(self.model.joint_names, self._balls):
            if not ball:
                parts_q.append(next(scalar_q))
                parts_v.append(next(scalar_v))
                continue
            turn, spin = balls[name]
            turn = np.roll(turn, -1)  # w x y z -> x y z w
            turn = self._quaternions[name] = continuous(turn, self._quaternions[name])
            parts_q.extend(turn)
            parts_v.extend(spin)
        return np.array(parts_q), np.array(parts_v)

    def constraint_violations(self) -> np.ndarray:
        """(n,) m: at each state :meth:`state` returned, in order, the largest joint violation (NaN once stepping
        failed): the anchor gaps and prismatic slides off their axes (m), and each misalignment of a joint's
        axes θ as L·sin θ (m), the displacement it makes at the scene's characteristic length L (the arm's
        reach). docs/metrics.md. Read once, after the run, like the link frames (engines.model.stepping)."""
        if not self._read:
            return np.zeros(0)
        distance, sine = joint_errors(self.model.mechanism, np.array(self._read))
        return np.maximum(distance, float(self.scene.characteristic_length) * sine)
