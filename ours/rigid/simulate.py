"""Pack a Mechanism for the compiled kernel, run a trajectory, and read states back.

State y (13 per body, ``ours.rigid.kernel``): COM x, quaternion Q (w, x, y, z) of the body frame,
COM velocity v, world angular velocity ω. :func:`initial_state` builds y from joint coordinates.
"""

from __future__ import annotations

import functools
import math
import time
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ours.errors import ModelError, OursError
from ours.method import DEFAULT_K_S, DEFAULT_MAX_ITERATIONS, critical_damping
from ours.simulate import _count, _positive
from ours.rigid.method import BAUMGARTE, resolve
from ours.rigid.model import DOFS, ROWS, Mechanism
from ours.status import STATUS_TEXT

KIND_CODES = {"ball": 0, "revolute": 1, "prismatic": 2, "fixed": 3}
#: Projection stops at max |C| ≤ tolerance (m for anchors, cosine for the orientation rows).
DEFAULT_TOLERANCE = 1e-12


def pack(mech: Mechanism) -> tuple:
    """The model tuple of the kernel (see ``ours.rigid.kernel``): arrays only."""
    nb, nj = len(mech.bodies), len(mech.joints)
    mass = np.array([b.mass for b in mech.bodies])
    inertia = np.array([b.inertia for b in mech.bodies]).reshape(nb, 3, 3)
    com = np.array([b.com for b in mech.bodies]).reshape(nb, 3)
    kind = np.array([KIND_CODES[j.kind] for j in mech.joints], dtype=np.int64)
    parent = np.array([j.parent for j in mech.joints], dtype=np.int64)
    child = np.array([j.child for j in mech.joints], dtype=np.int64)
    la = np.zeros((nj, 3))
    lb = np.zeros((nj, 3))
    FA = np.zeros((nj, 3, 3))
    FB = np.zeros((nj, 3, 3))
    for k, j in enumerate(mech.joints):
        la[k] = j.origin_xyz - (com[j.parent] if j.parent >= 0 else 0.0)
        lb[k] = -com[j.child]
        FA[k] = j.origin_rotation @ j.frame
        FB[k] = j.frame
    rows = np.array([ROWS[j.kind] for j in mech.joints], dtype=np.int64)
    depth = np.zeros(nj, dtype=np.int64)  # joints from the world (or a free body) down to joint k
    inbound = {j.child: k for k, j in enumerate(mech.joints)}
    for k in mech.topological_joints():
        above = mech.joints[k].parent
        depth[k] = depth[inbound[above]] + 1 if above in inbound else 0
    order = np.argsort(-depth, kind="stable").astype(np.int64)  # deepest first: each joint before its parent's
    free = np.array([b for b in range(nb) if b not in inbound], dtype=np.int64)  # bodies no joint holds
    dims = np.concatenate([np.full(nb, 6, dtype=np.int64), rows])
    return (mass, inertia, np.array(mech.gravity, dtype=float), dims, kind, parent, child, la, lb, FA, FB,
            rows, order, free)


_PACKED: "weakref.WeakKeyDictionary[Mechanism, tuple]" = weakref.WeakKeyDictionary()


def packed(mech: Mechanism) -> tuple:
    """:func:`pack` of ``mech``, made once per Mechanism (records are frozen) for the readers of states
    (:func:`joint_coordinates`, read once per sample by a caller that samples as it goes, and
    :func:`joint_errors`); read-only."""
    model = _PACKED.get(mech)
    if model is None:
        model = _PACKED[mech] = pack(mech)
    return model


def workspace(mech: Mechanism, stages: int, dtype: type = np.float64) -> tuple:
    """Scratch arrays of the kernel (nothing in it allocates), with the constant entries of the joints'
    Jacobians J_A, J_B (work[2], work[3]) written once; complex128 for ``ours.rigid.sensitivity``'s complex step."""
    nb, nj = len(mech.bodies), len(mech.joints)
    nn = nb + nj

    def z(*shape):
        return np.zeros(shape, dtype)

    JA, JB = z(nj, 6, 6), z(nj, 6, 6)
    for k, j in enumerate(mech.joints):  # the point rows' linear half, ±e, is constant: the kernel never writes it
        if j.kind != "prismatic":
            JA[k, :3, :3], JB[k, :3, :3] = np.eye(3), -np.eye(3)
    return (z(nb, 3, 3), z(nj, 6), JA, JB, z(nj, 6), z(nn, 6, 6), z(nn, 6, 6), z(nn, 1, 6), z(nj, 6),
            z(max(stages, 1), 13 * nb), z(13 * nb))


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` rad about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def quaternion(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    t = np.trace(R)
    cases = [t, R[0, 0], R[1, 1], R[2, 2]]
    i = int(np.argmax(cases))
    if i == 0:
        w = math.sqrt(1.0 + t) / 2.0
        q = [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]
    else:
        a, b, c = (i - 1), i % 3, (i + 1) % 3
        s = math.sqrt(1.0 + R[a, a] - R[b, b] - R[c, c]) * 2.0
        q = [0.0] * 4
        q[0] = (R[c, b] - R[b, c]) / s
        q[1 + a] = s / 4.0
        q[1 + b] = (R[b, a] + R[a, b]) / s
        q[1 + c] = (R[c, a] + R[a, c]) / s
    unit = np.array(q)
    return unit / np.linalg.norm(unit)


def rotation_of(Q: np.ndarray) -> np.ndarray:
    """(3, 3) the rotation of a quaternion (w, x, y, z), normalised first."""
    w, x, y, z = np.asarray(Q, dtype=float) / np.linalg.norm(Q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _coordinate(values, joint, default=0.0) -> float:
    value = (values or {}).get(joint.name, default)
    number = float(value)
    if not math.isfinite(number):
        raise ModelError(f"joint {joint.name}: its coordinate must be finite, got {value!r}")
    return number


def _ball_coordinate(values, joint, size: int) -> np.ndarray | None:
    """A ball joint's given quaternion (w, x, y, z; normalised) or rate (3,), None when not given."""
    if joint.name not in (values or {}):
        return None
    value = np.asarray(values[joint.name], dtype=float).reshape(-1)
    if value.shape != (size,) or not np.isfinite(value).all() or (size == 4 and not np.linalg.norm(value)):
        raise ModelError(f"joint {joint.name}: a ball joint's {'quaternion' if size == 4 else 'rate'} must be "
                         f"{size} finite numbers{' (nonzero)' if size == 4 else ''}, got {values[joint.name]!r}")
    return value / np.linalg.norm(value) if size == 4 else value


def initial_state(mech: Mechanism, q: dict | None = None, v: dict | None = None) -> np.ndarray:
    """y (13 nb,) from joint coordinates q and rates v (by joint name: rad and rad/s for revolute,
    m and m/s for prismatic; for a ball joint a unit quaternion (w, x, y, z), the child frame's rotation in
    the joint frame, and the child's angular velocity relative to the parent in the child frame (3,) rad/s;
    missing = 0, a ball aligned and at rest). Fixed joints start aligned and at rest;
    a body with no inbound joint starts at the origin, at rest."""
    known = {j.name for j in mech.joints if DOFS[j.kind] >= 1}
    for values, what in ((q, "q"), (v, "v")):
        for name in values or {}:
            if name not in known:
                raise ModelError(f"{what}.{name}: no revolute or prismatic joint of that name, nor a ball joint; "
                                 f"choose from {sorted(known)}")
    nb = len(mech.bodies)
    R = [np.eye(3) for _ in range(nb)]
    p = [np.zeros(3) for _ in range(nb)]  # body frame origins
    vel = [np.zeros(3) for _ in range(nb)]  # velocities of the frame origins
    w = [np.zeros(3) for _ in range(nb)]
    for k in mech.topological_joints():
        j = mech.joints[k]
        Rp, pp, vp, wp = (R[j.parent], p[j.parent], vel[j.parent], w[j.parent]) if j.parent >= 0 else (
            np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3))
        Rj = Rp @ j.origin_rotation
        pj = pp + Rp @ j.origin_xyz
        axis = Rj @ j.axis
        angle = rate = 0.0
        if DOFS[j.kind] == 1:
            angle, rate = _coordinate(q, j), _coordinate(v, j)
        turn, spin = (_ball_coordinate(q, j, 4), _ball_coordinate(v, j, 3)) if j.kind == "ball" else (None, None)
        c = j.child
        R[c], p[c], w[c] = Rj, pj, wp.copy()
        vel[c] = vp + np.cross(wp, pj - pp)
        if j.kind == "revolute":
            R[c] = Rj @ rotation(j.axis, angle)
            w[c] = wp + rate * axis
        elif j.kind == "prismatic":
            p[c] = pj + angle * axis
            vel[c] = vp + np.cross(wp, p[c] - pp) + rate * axis
        elif j.kind == "ball":
            R[c] = Rj if turn is None else Rj @ rotation_of(turn)
            w[c] = wp if spin is None else wp + R[c] @ spin
    y = np.zeros(13 * nb)
    for b, body in enumerate(mech.bodies):
        o = 13 * b
        com = p[b] + R[b] @ body.com
        y[o:o + 3] = com
        y[o + 3:o + 7] = quaternion(R[b])
        y[o + 7:o + 10] = vel[b] + np.cross(w[b], com - p[b])
        y[o + 10:o + 13] = w[b]
    return y


def frames(mech: Mechanism, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origins (..., nb, 3) m, rotations (..., nb, 3, 3)) of the body frames at states y (..., 13 nb)."""
    y = np.asarray(y, dtype=float)
    s = y.reshape(y.shape[:-1] + (len(mech.bodies), 13))
    Q = s[..., 3:7] / np.linalg.norm(s[..., 3:7], axis=-1, keepdims=True)
    w, x, yy, z = (Q[..., i] for i in range(4))
    R = np.stack([
        np.stack([1 - 2 * (yy * yy + z * z), 2 * (x * yy - w * z), 2 * (x * z + w * yy)], -1),
        np.stack([2 * (x * yy + w * z), 1 - 2 * (x * x + z * z), 2 * (yy * z - w * x)], -1),
        np.stack([2 * (x * z - w * yy), 2 * (yy * z + w * x), 1 - 2 * (x * x + yy * yy)], -1),
    ], -2)
    com = np.array([b.com for b in mech.bodies])
    return s[..., 0:3] - np.einsum("...ij,...j->...i", R, com), R


def energy(mech: Mechanism, y: np.ndarray) -> np.ndarray:
    """(...,) J: ½ m v² + ½ ωᵀ I_w ω − m g·x at states y (..., 13 nb)."""
    s = np.asarray(y, dtype=float).reshape(np.shape(y)[:-1] + (len(mech.bodies), 13))
    _, R = frames(mech, y)
    mass = np.array([b.mass for b in mech.bodies])
    inertia = np.array([b.inertia for b in mech.bodies])
    wb = np.einsum("...ji,...j->...i", R, s[..., 10:13])  # ω in the body frame
    rot = 0.5 * np.einsum("...bi,bij,...bj->...b", wb, inertia, wb)
    lin = 0.5 * mass * np.sum(s[..., 7:10] ** 2, axis=-1)
    pot = -mass * (s[..., 0:3] @ mech.gravity)
    return np.sum(lin + rot + pot, axis=-1)


def angular_momentum(mech: Mechanism, y: np.ndarray) -> np.ndarray:
    """(..., 3) kg·m²/s about the world origin: Σ m x × v + I_w ω."""
    s = np.asarray(y, dtype=float).reshape(np.shape(y)[:-1] + (len(mech.bodies), 13))
    _, R = frames(mech, y)
    inertia = np.array([b.inertia for b in mech.bodies])
    mass = np.array([b.mass for b in mech.bodies])
    wb = np.einsum("...ji,...j->...i", R, s[..., 10:13])
    spin = np.einsum("...bij,bjk,...bk->...bi", R, inertia, wb)
    orbit = mass[:, None] * np.cross(s[..., 0:3], s[..., 7:10])
    return np.sum(spin + orbit, axis=-2)


def joint_coordinates(mech: Mechanism, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) (..., moving joints) at states y: angle (rad) and rate for revolute joints, displacement
    (m) and rate for prismatic, in ``mech.moving_joints`` order. Angles are in (−π, π] at a single
    state; along a series y (S, 13 nb) they are unwrapped from the first sample on (so a joint that
    turns twice reads 4π), which needs less than half a turn between samples."""
    y = np.asarray(y, dtype=float)
    s = y.reshape(y.shape[:-1] + (len(mech.bodies), 13))
    origin, R = frames(mech, y)
    FA, FB = packed(mech)[9:11]  # FB[k] is joint k's frame (Joint.frame), made once
    qs, vs = [], []
    for k in mech.moving_joints:
        j = mech.joints[k]
        c = j.child
        if j.parent >= 0:
            Rp, pp, wp, xp, vp = R[..., j.parent, :, :], origin[..., j.parent, :], s[..., j.parent, 10:13], \
                s[..., j.parent, 0:3], s[..., j.parent, 7:10]
        else:
            shape = y.shape[:-1]
            Rp = np.broadcast_to(np.eye(3), shape + (3, 3))
            pp = wp = xp = vp = np.zeros(shape + (3,))
        joint_frame = Rp @ FA[k]  # world, third column = axis
        axis = joint_frame[..., :, 2]
        wc = s[..., c, 10:13]
        if j.kind == "revolute":
            rel = np.swapaxes(joint_frame, -1, -2) @ R[..., c, :, :] @ FB[k]
            qs.append(np.arctan2(rel[..., 1, 0], rel[..., 0, 0]))
            vs.append(np.sum((wc - wp) * axis, axis=-1))
        else:
            pj = pp + np.einsum("...ij,j->...i", Rp, j.origin_xyz)
            d = origin[..., c, :] - pj
            v_child = s[..., c, 7:10] + np.cross(wc, origin[..., c, :] - s[..., c, 0:3])
            v_joint = vp + np.cross(wp, pj - xp)
            qs.append(np.sum(d * axis, axis=-1))
            vs.append(np.sum((v_child - v_joint) * axis + d * np.cross(wp, axis), axis=-1))
    if not qs:
        return np.zeros(y.shape[:-1] + (0,)), np.zeros(y.shape[:-1] + (0,))
    q, v = np.stack(qs, axis=-1), np.stack(vs, axis=-1)
    if q.ndim == 2:
        revolute = [mech.joints[k].kind == "revolute" for k in mech.moving_joints]
        q[:, revolute] = np.unwrap(q[:, revolute], axis=0)
    return q, v


def ball_coordinates(mech: Mechanism, y: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Ball joint name -> (quaternion (..., 4) w x y z of the child frame in the joint frame, sign as computed;
    the child's angular velocity relative to the parent, in the child frame (..., 3) rad/s) at states y."""
    y = np.asarray(y, dtype=float)
    s = y.reshape(y.shape[:-1] + (len(mech.bodies), 13))
    _, R = frames(mech, y)
    out = {}
    for j in mech.joints:
        if j.kind != "ball":
            continue
        c = j.child
        if j.parent >= 0:
            Rp, wp = R[..., j.parent, :, :], s[..., j.parent, 10:13]
        else:
            Rp, wp = np.broadcast_to(np.eye(3), y.shape[:-1] + (3, 3)), np.zeros(y.shape[:-1] + (3,))
        rel = np.swapaxes(Rp @ j.origin_rotation, -1, -2) @ R[..., c, :, :]
        out[j.name] = (_quaternions(rel), np.einsum("...ji,...j->...i", R[..., c, :, :], s[..., c, 10:13] - wp))
    return out


def _quaternions(matrices: np.ndarray) -> np.ndarray:
    """(..., 4) w x y z of rotation matrices (..., 3, 3)."""
    flat = matrices.reshape(-1, 3, 3)
    return np.array([quaternion(m) for m in flat]).reshape(matrices.shape[:-2] + (4,))


@dataclass(frozen=True, eq=False)
class RigidResult:
    """Samples of one run. t (S,) s; y (S, 13 nb) states (see the module docstring); steps taken;
    wall_time (s, the compiled loop alone); status "ok" or why it stopped; settings used."""

    t: np.ndarray
    y: np.ndarray
    steps: int
    wall_time: float
    status: str
    settings: dict[str, Any] = field(default_factory=dict)


def _kernel():
    from ours.rigid import kernel  # imports numba: only when a run needs it

    return kernel


_warmed: set[tuple] = set()


@dataclass(frozen=True, eq=False)
class Prepared:
    """A run's checked settings, as the kernel's ``run`` takes them: args (method code, integrator code, A, b);
    stages of the integrator; y (13 nb,) the start; dt s; n_steps; stride (steps between samples); n_samples;
    ks (1/s²), kd (1/s) the gains (0 unless baumgarte); tolerance; max_iterations; settings (as RigidResult's)."""

    args: tuple
    stages: int
    y: np.ndarray
    dt: float
    n_steps: int
    stride: int
    n_samples: int
    ks: float
    kd: float
    tolerance: float
    max_iterations: int
    settings: dict[str, Any]

    def times(self, written: int) -> np.ndarray:
        """(written,) s: the times of the first ``written`` samples (step 0, every stride steps, the last)."""
        return np.minimum(np.arange(self.n_samples) * self.stride, self.n_steps)[:written] * self.dt


def prepare(mech: Mechanism, y0, dt: float, n_steps: int, sample_every: int = 1, *, method: str = "baumgarte",
            integrator: str | None = None, k_s: float | None = None, k_d: float | None = None,
            tolerance: float = DEFAULT_TOLERANCE, max_iterations: int = DEFAULT_MAX_ITERATIONS) -> Prepared:
    """:func:`simulate`'s arguments checked (OursError / ModelError naming the field) and resolved."""
    code, scheme = resolve(method, integrator)
    y = np.array(y0, dtype=float).ravel()
    if y.shape != (13 * len(mech.bodies),) or not np.isfinite(y).all():
        raise ModelError(f"y0: expected {13 * len(mech.bodies)} finite numbers (13 per body), got shape {np.shape(y0)}")
    dt = _positive(dt, "dt", "pass a time step in seconds such as 1e-3")
    n_steps, stride = _count(n_steps, "n_steps"), _count(sample_every, "sample_every")
    ks = DEFAULT_K_S if k_s is None else float(k_s)
    kd = critical_damping(ks) if k_d is None else float(k_d)
    if not (math.isfinite(ks) and ks >= 0.0 and math.isfinite(kd) and kd >= 0.0):
        raise OursError(f"k_s, k_d: must be ≥ 0, got {k_s!r}, {k_d!r}")
    if code != BAUMGARTE:
        ks = kd = 0.0
    tolerance = _positive(tolerance, "tolerance", "1e-12 is near round-off for joints of order 1 m")
    max_iterations = _count(max_iterations, "max_iterations")
    n_samples = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    settings = {"method": method, "integrator": scheme.name, "tolerance": tolerance, "max_iterations": max_iterations}
    if code == BAUMGARTE:
        settings.update(k_s=ks, k_d=kd)
    return Prepared((code, scheme.code, scheme.A, scheme.b), scheme.stages, y, dt, n_steps, stride, n_samples, ks, kd,
                    tolerance, max_iterations, settings)


def simulate(mech: Mechanism, y0, dt: float, n_steps: int, sample_every: int = 1, *, method: str = "baumgarte",
             integrator: str | None = None, k_s: float | None = None, k_d: float | None = None,
             tolerance: float = DEFAULT_TOLERANCE, max_iterations: int = DEFAULT_MAX_ITERATIONS) -> RigidResult:
    """Simulate ``mech`` from y0 (13 nb,) for n_steps steps of dt s; samples at step 0, every
    sample_every steps and the last. method: plain, baumgarte, projection; integrator: euler,
    symplectic-euler, midpoint, rk4 (default). k_s (1/s²), k_d (1/s): Baumgarte gains (default 100, 2√k_s)."""
    run = prepare(mech, y0, dt, n_steps, sample_every, method=method, integrator=integrator, k_s=k_s, k_d=k_d,
                  tolerance=tolerance, max_iterations=max_iterations)
    kernel = _kernel()
    model = pack(mech)
    work = workspace(mech, run.stages)
    y, args = run.y, run.args
    out = np.full((run.n_samples, y.size), np.nan)
    if args[:2] not in _warmed:  # compile (or load from numba's cache) before the clock starts
        kernel.run(*args, y.copy(), model, work, run.ks, run.kd, run.dt, 1, 1, run.tolerance, run.max_iterations,
                   out[:2].copy())
        _warmed.add(args[:2])
    start = time.perf_counter()
    written, steps, status = kernel.run(*args, y, model, work, run.ks, run.kd, run.dt, run.n_steps, run.stride,
                                        run.tolerance, run.max_iterations, out)
    wall_time = time.perf_counter() - start
    return RigidResult(t=run.times(written), y=out[:written], steps=int(steps), wall_time=wall_time,
                       status=STATUS_TEXT[int(status)], settings=run.settings)


def joint_errors(mech: Mechanism, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance (S,) m, angle (S,) rad): at each state of y (S, 13 nb), the largest violation of a
    joint's position rows (anchor gap, slide off its axis) and of its orientation rows (|p·w|, the
    sine of the misalignment)."""
    kernel = _kernel()
    states = np.atleast_2d(np.asarray(y, dtype=float))
    model, work = packed(mech), workspace(mech, 1)
    kind, rows = model[4], model[11]
    # which rows hold lengths: the anchor rows 0–2 (not prismatic), the slide rows 3–4 (prismatic)
    length = np.zeros((len(mech.joints), 6), dtype=bool)
    length[kind != KIND_CODES["prismatic"], :3] = True
    length[kind == KIND_CODES["prismatic"], 3:5] = True
    used = np.arange(6)[None, :] < rows[:, None]
    distance, angle = np.zeros(len(states)), np.zeros(len(states))
    for s, state in enumerate(states):
        kernel.rotations(state, len(mech.bodies), work[0])
        kernel.joint_rows(state, model, work[0], work[1], work[2], work[3], work[4])
        C = np.abs(work[1])
        distance[s] = C[used & length].max(initial=0.0)
        angle[s] = C[used & ~length].max(initial=0.0)
    return distance, angle


def _compiled_run(args: tuple, y: np.ndarray, model: tuple, work: tuple, out: np.ndarray):
    """``kernel.run``'s machine code for these argument types, called without numba's dispatch: the
    dispatcher types every argument at every call (a microsecond for the model's and the work's tuples
    of arrays), which a caller advancing a sample at a time, ten steps of a robot, pays on each sample.
    The dispatcher itself when the compiled version is not found (a numba that keeps them elsewhere)."""
    run = _kernel().run
    values = (*args, y, model, work, 0.0, 0.0, 1.0, 1, 1, 1.0, 1, out)
    try:
        return run.overloads[tuple(run.typeof_pyval(v) for v in values)].entry_point
    except (AttributeError, KeyError):
        return run


class Stepping:
    """A run that advances on request (for a caller that samples as it goes): the same compiled step
    as :func:`simulate`. ``y`` (13 nb,) is the current state, stepped in place (set it with ``y[:] = ...``:
    the compiled call holds this array); ``status`` "ok" or why it stopped (then ``y`` is left as it was
    when the step failed and :meth:`advance` does nothing more)."""

    def __init__(self, mech: Mechanism, y0, dt: float, *, method: str = "baumgarte", integrator: str | None = None,
                 k_s: float | None = None, k_d: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
                 max_iterations: int = DEFAULT_MAX_ITERATIONS) -> None:
        options: dict[str, Any] = dict(method=method, integrator=integrator, k_s=k_s, k_d=k_d, tolerance=tolerance,
                                   max_iterations=max_iterations)
        run = prepare(mech, y0, dt, 1, 1, **options)  # validated and resolved, as simulate has them
        simulate(mech, y0, dt, 1, 1, **options)  # compiles (or loads) and warms the kernel
        self.settings = run.settings
        self._args, self._gains, self._dt = run.args, (run.ks, run.kd), run.dt
        self._tolerance, self._max_iterations = run.tolerance, run.max_iterations
        self._model, self._work = pack(mech), workspace(mech, run.stages)
        self.y = run.y
        self._out = np.zeros((2, self.y.size))
        self.status, self.steps = "ok", 0
        # the arguments before the step count bound once: a sample's call passes the count and the three after it
        self._run = functools.partial(_compiled_run(self._args, self.y, self._model, self._work, self._out),
                                      *self._args, self.y, self._model, self._work, *self._gains, self._dt)

    def advance(self, steps: int) -> str:
        """Take ``steps`` steps of dt in place; returns the status."""
        if self.status == "ok" and steps > 0:
            steps = int(steps)
            _, taken, status = self._run(steps, steps, self._tolerance, self._max_iterations, self._out)
            self.steps += int(taken)
            self.status = STATUS_TEXT[int(status)]
        return self.status
