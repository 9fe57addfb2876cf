"""pymunk (Chipmunk2D / Munk2D) adapter: planar scenes as point masses joined by ``PinJoint``s.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/pymunk/adapter.py``.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule, refuse_constraint_kinds, refuse_ellipse
from engines.errors import UserError
from engines.pymunk.library import pymunk
from engines.recorder import Recorder
from engines.scene.scene import Line, Pin, Rod, Scene

#: pymunk's own defaults, read from the library rather than copied.
_PROBE_SPACE = pymunk.Space()
PYMUNK_ERROR_BIAS = pymunk.PinJoint(_PROBE_SPACE.static_body, pymunk.Body(1.0, math.inf)).error_bias
PYMUNK_ITERATIONS = _PROBE_SPACE.iterations
PYMUNK_DAMPING = _PROBE_SPACE.damping
del _PROBE_SPACE

#: A Line's GrooveJoint runs this many characteristic lengths either side of the line's point.
GROOVE_LENGTHS = 1e3


class PymunkEngine(Engine):
    """pymunk ``PinJoint`` formulation of planar point-mass scenes."""

    name = "pymunk"
    capabilities = frozenset({"constraint-forces"})
    options = {
        "error_bias": Option(
            "error_bias",
            PYMUNK_ERROR_BIAS,
            "fraction of a joint's error left uncorrected after 1 s (pymunk's default "
            f"{PYMUNK_ERROR_BIAS:.6g} = 0.9^60: 10% per 1/60 s; 0 = full correction every step); in [0, 1]",
        ),
        "iterations": Option(
            "iterations", PYMUNK_ITERATIONS, f"solver passes per step (pymunk's default {PYMUNK_ITERATIONS})", "int",
            high=10_000,
        ),
        "max_bias": Option(
            "max_bias",
            None,
            "largest error-correction speed, m/s (pymunk's default: unlimited); >= 0",
        ),
        "damping": Option(
            "damping",
            PYMUNK_DAMPING,
            "fraction of velocity kept after 1 s (pymunk's default 1 = no damping); in (0, 1]",
        ),
    }
    variants = {
        "pin": {},
        "pin-bias0": {"error_bias": 0.0},
        "pin-bias0-iter50": {"error_bias": 0.0, "iterations": 50},
    }
    variant_docs = {
        "pin": "PinJoints with pymunk's own solver defaults (error_bias 0.9^60, 10 iterations)",
        "pin-bias0": "PinJoints with error_bias = 0: the whole drift corrected every step",
        "pin-bias0-iter50": "error_bias = 0 and 50 solver iterations (converged Gauss-Seidel for chains)",
    }
    overrides = {
        "Body.moment": "inf (non-rotating point mass; pymunk has no default for a body without shapes)",
        "PinJoint.distance": "the scene's length (pymunk measures it from the anchors when the joint is created)",
        "Space.gravity": "the scene's (g_x, g_z) (pymunk's default is (0, 0))",
        "shapes": "none (nothing collides; pymunk would need shapes for contact)",
        "GrooveJoint": f"a Line is a groove ±{GROOVE_LENGTHS:g}·L about its point (pymunk's grooves are segments)",
    }

    def version(self) -> str:
        return f"{pymunk.version} (Munk2D {pymunk.chipmunk_version.split('-')[0]})"

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        refuse_ellipse(scene, "pymunk has no joint that holds a body on an ellipse (only circles, via PinJoint, "
                              "and straight segments, via GrooveJoint)")
        refuse_constraint_kinds(scene, (Pin, Rod, Line), "pymunk")

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        """Refuse option values pymunk would accept but that mean nothing (or trip an assert in C)."""
        if not 0.0 <= settings["error_bias"] <= 1.0:
            raise UserError(f"pymunk: option error_bias must be in [0, 1], got {settings['error_bias']!r}")
        if settings["iterations"] < 1:
            raise UserError(f"pymunk: option iterations must be at least 1, got {settings['iterations']!r}")
        max_bias = settings["max_bias"]
        if max_bias is not None and not (isinstance(max_bias, (int, float)) and max_bias >= 0):
            raise UserError(f"pymunk: option max_bias must be a number >= 0 (m/s), got {max_bias!r}")
        if not 0.0 < settings["damping"] <= 1.0:
            raise UserError(f"pymunk: option damping must be in (0, 1] (1 = none), got {settings['damping']!r}")

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        """Step ``schedule.n_steps`` times; record positions (m), velocities (m/s), forces (N) at the sample steps.

        Only ``Space.step`` calls are timed. The velocity before each sample
        step is read (untimed) for the sign of that step's constraint forces.
        """
        model = _Model(scene, settings)
        dt = schedule.dt
        step = model.space.step
        bodies, joints = model.bodies, model.joints
        rec = Recorder(scene, schedule)
        # Read per sample as pymunk gives them (Vec2d are tuples), in pymunk's frame, and made arrays after
        # the loop, with what each sample's constraint force is computed from: the velocities before its
        # last step (before_rows) and the joints' impulses in it (the recorder's force rows).
        before_rows: list = []

        def advance(n: int) -> None:
            for _ in range(n - 1):
                step(dt)
            with rec.paused():
                before_rows.append([b.velocity for b in bodies])
            step(dt)

        def read() -> tuple[list, list, list]:
            return [b.position for b in bodies], [b.velocity for b in bodies], [j.impulse for j in joints]

        # No step has been taken, so no constraint impulse exists yet: the
        # force at t = 0 is the one of the first step (filled below).
        rec.record(0, [b.position for b in bodies], [b.velocity for b in bodies])
        rec.run(advance, read)
        p_planar, v_planar = rec.samples()
        recorded = len(p_planar)
        forces = np.full((recorded, len(scene.constraints), 3), np.nan)
        finite = np.isfinite(p_planar).all(axis=(1, 2)) & np.isfinite(v_planar).all(axis=(1, 2))
        good = recorded if finite.all() else int(np.argmin(finite))  # samples before the first non-finite one
        if good > 1:
            v_before = np.array(before_rows[:good - 1], dtype=float).reshape(good - 1, *p_planar.shape[1:])
            impulses = np.array(rec.f_rows[1:good], dtype=float).reshape(good - 1, len(joints))
            forces[1:good] = _to_scene(model.constraint_forces(p_planar[1:good], v_planar[1:good], v_before,
                                                               impulses, dt))
        forces[0] = forces[1] if recorded > 1 else np.nan
        return rec.raw_run(
            positions=_to_scene(p_planar),
            velocities=_to_scene(v_planar),
            forces=forces,
            settings={
                "moment_of_inertia": "inf",
                "gravity_pymunk": tuple(model.space.gravity),
                "timing": "Python loop over Space.step (no batched stepping API in pymunk)",
                "force_t0": "the force at t = 0 is the one of the first step",
            },
        )


def _to_scene(xy: np.ndarray) -> np.ndarray:
    """(..., k, 2) pymunk (x, y) -> (..., k, 3) scene (x, 0, z)."""
    out = np.zeros((*xy.shape[:-1], 3))
    out[..., 0], out[..., 2] = xy[..., 0], xy[..., 1]
    return out


class _Model:
    """The pymunk space built from a scene, with readers in pymunk's frame ((k, 2) arrays)."""

    def __init__(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        space = pymunk.Space()
        space.gravity = (scene.gravity[0], scene.gravity[2])
        space.iterations = int(settings["iterations"])
        space.damping = float(settings["damping"])
        self.space = space
        self.damping = float(settings["damping"])
        self.gravity = np.array(space.gravity)
        self.bodies: list[pymunk.Body] = []
        for particle in scene.particles:
            body = pymunk.Body(particle.mass, math.inf)
            body.position = (particle.position[0], particle.position[2])
            body.velocity = (particle.velocity[0], particle.velocity[2])
            self.bodies.append(body)
        space.add(*self.bodies)
        self.joints: list[pymunk.Constraint] = []
        # ends[k] = (index of the joint's body a or None for static, index of body b)
        self.ends: list[tuple[int | None, int]] = []
        #: +1 when the constraint's first particle is the joint's body b (Pin), −1 when it is body a (Rod).
        self.first_sign = np.empty(len(scene.constraints))
        #: A groove's constraint direction is its fixed normal (None for pins: their axis turns).
        self.normals: list[np.ndarray | None] = []
        reach = GROOVE_LENGTHS * scene.characteristic_length
        for k, c in enumerate(scene.constraints):
            self.normals.append(None)
            joint: pymunk.Constraint
            if isinstance(c, Line):
                u = np.array([c.unit[0], c.unit[2]])
                point = np.array([c.point[0], c.point[2]])
                joint = pymunk.GrooveJoint(space.static_body, self.bodies[c.particle], tuple(point - reach * u),
                                           tuple(point + reach * u), (0, 0))
                self.ends.append((None, c.particle))
                self.first_sign[k] = 1.0
                self.normals[k] = np.array([-u[1], u[0]])
            elif isinstance(c, Pin):
                joint = pymunk.PinJoint(space.static_body, self.bodies[c.particle], (c.anchor[0], c.anchor[2]), (0, 0))
                self.ends.append((None, c.particle))
                self.first_sign[k] = 1.0
            else:
                joint = pymunk.PinJoint(self.bodies[c.a], self.bodies[c.b], (0, 0), (0, 0))
                self.ends.append((c.a, c.b))
                self.first_sign[k] = -1.0
            # Created from positions, the distance carries their rounding: set it.
            if not isinstance(c, Line):
                joint.distance = c.length
            joint.error_bias = float(settings["error_bias"])
            if settings["max_bias"] is not None:
                joint.max_bias = float(settings["max_bias"])
            self.joints.append(joint)
        space.add(*self.joints)
        self.masses = scene.masses
        self.anchors = np.array(
            [(c.anchor[0], c.anchor[2]) if isinstance(c, Pin) else (np.nan, np.nan) for c in scene.constraints]
        ).reshape(-1, 2)

    def directions(self, p2: np.ndarray) -> np.ndarray:
        """(S, n_constraints, 2): unit vector from each joint's body a (or anchor) to its body b, at each
        of S samples of positions p2 (S, n_particles, 2)."""
        out = np.empty((len(p2), len(self.joints), 2))
        for k, (a, b) in enumerate(self.ends):
            if self.normals[k] is not None:
                out[:, k] = self.normals[k]
                continue
            start = self.anchors[k] if a is None else p2[:, a]
            delta = p2[:, b] - start
            length = np.linalg.norm(delta, axis=-1)
            out[:, k] = delta / np.where(length == 0.0, math.inf, length)[:, None]
        return out

    def constraint_forces(self, p2: np.ndarray, v2: np.ndarray, v_before: np.ndarray, impulses: np.ndarray,
                          dt: float) -> np.ndarray:
        """(S, n_constraints, 2) N on each constraint's first particle during the last step before each of
        S samples, from the positions p2 and velocities v2 after it and v_before before it (S,
        n_particles, 2) and the joints' impulses in it (S, n_constraints).

        Magnitude: pymunk's ``impulse`` / dt. Direction: the joint's axis at
        the end of the step (where pymunk's pre-step measured it). Sign: from
        the step's momentum balance (pymunk reports |impulse|), solved in the
        least-squares sense for all samples at once.
        """
        n = self.directions(p2)
        # Momentum balance, per body and axis: m (v_new − d v_old − g dt) = Σ_k j_k s_{k,body} n_k,
        # with s = +1 on the joint's body b and −1 on its body a (cpPinJoint's apply_impulses).
        change = self.masses[:, None] * (v2 - self.damping**dt * v_before - self.gravity * dt)
        matrix = np.zeros((len(p2), 2 * len(self.bodies), len(self.joints)))
        for k, (a, b) in enumerate(self.ends):
            matrix[:, 2 * b : 2 * b + 2, k] += n[:, k]
            if a is not None:
                matrix[:, 2 * a : 2 * a + 2, k] -= n[:, k]
        signed = (np.linalg.pinv(matrix) @ change.reshape(len(p2), -1, 1))[..., 0]
        impulse_on_b = np.copysign(impulses / dt, signed)
        return (self.first_sign * impulse_on_b)[..., None] * n


ENGINE = PymunkEngine()
