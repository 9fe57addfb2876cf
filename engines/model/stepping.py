"""Stepping a model scene in an engine: one loop for every engine, each engine's own step.

An engine adapter that runs model scenes builds a :class:`Stepper` (a subclass of it) from the
engine's import of the file (``engines/<engine>/model.py``), with its
integrator and time step, and hands it to :func:`run_model`. The loop
advances to each sample step (only that is timed), reads the joint state
(q, v) in the model's joint order, and afterwards turns every sample into
link frames (``ModelScene.frame_states``). ``neutral`` and ``keep`` (the
file's joint damping, friction and armature) are applied by the stepper;
every override goes into the run's settings.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from engines.adapter import RawRun, Schedule
from engines.recorder import Recorder
from engines.model.scene import ModelScene


class Stepper:
    """An engine's model, ready to step at the schedule's dt from the scene's initial state: the base of each
    engine's stepper (engines/<engine>/model.py), which implements ``advance`` and ``state``.

    settings : what the run must record (import options, overrides, integrator).
    """

    settings: dict[str, Any]

    def advance(self, steps: int) -> None:
        """Take ``steps`` steps of dt."""
        raise NotImplementedError

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) (nq,) each, in the model's joint order (rad or m, rad/s or m/s)."""
        raise NotImplementedError

    def steps_taken(self) -> int | None:
        """Steps taken so far, for an integrator that chooses its own (error-controlled); None (the default):
        the schedule's count."""
        return None

    def constraint_violations(self) -> np.ndarray | None:
        """(n,) m: the largest joint violation at each state ``state`` returned, read once after the run
        (RawRun.constraint_violation), for an engine whose joints can come apart (maximal coordinates,
        ours); None (the default): a reduced-coordinate engine's joints hold by construction."""
        return None


def run_model(scene: ModelScene, schedule: Schedule, stepper: Stepper) -> RawRun:
    """Step ``scene`` (an engines.model.scene.ModelScene) to every sample of ``schedule`` through the one
    Recorder loop (it stops at a non-finite state).
    Positions and velocities are the link frames' (n, L, 3); ``joint_states`` (n, 2·nq) holds q then v;
    ``constraint_violation`` (n,) m the stepper's joint violation, when it measures one."""
    recorder = Recorder(scene, schedule)
    recorder.record(0, *stepper.state())
    recorder.run(stepper.advance, stepper.state)
    q, v = recorder.samples()
    states = np.concatenate([q, v], axis=1)
    positions = np.full((len(states), len(scene.frames), 3), np.nan)
    velocities = positions.copy()
    finite = np.isfinite(states).all(axis=1)
    if finite.any():
        good = np.flatnonzero(finite)
        positions[good], velocities[good] = scene.frame_states(q[good], v[good])
    # An error-controlled integrator takes steps of its own choosing: the stepper counts them.
    taken = stepper.steps_taken()
    raw = recorder.raw_run(positions=positions, velocities=velocities, settings=stepper.settings, steps=taken)
    violation = stepper.constraint_violations()
    return replace(raw, joint_states=states, constraint_violation=violation)


def file_values(scene: ModelScene) -> dict[str, dict[str, float]]:
    """The file's joint damping and friction by joint (what ``keep`` leaves in place), for the record."""
    return {j.name: {"damping": j.damping, "friction": j.friction} for j in scene.description.moving_joints
            if j.damping or j.friction}


def common_settings(scene: ModelScene, loaded: Any) -> dict[str, Any]:
    """Settings every model run records: the import's options and notes, and what the file's joint
    damping and friction were (set to 0, or the damping kept; contacts and joint limits are off)."""
    return {
        "model": scene.model,
        "import_options": dict(loaded.options),
        "import_notes": list(loaded.notes),
        "file_damping_friction": file_values(scene),
        "file_dynamics": ("keep: the file's joint damping kept (no friction in the file)" if scene.file_dynamics == "keep"
                          else "neutral: joint damping, friction and armature set to 0"),
        "contacts": "off", "joint_limits": "off",
        "unbounded_once_limits_off": unbounded_joints(scene),
    }


def unbounded_joints(scene: ModelScene) -> list[str]:
    """The prismatic joints the file limits: with limits off nothing stops them (a gripper's finger slides
    away), so their links' errors say little; named in every run's settings."""
    return [j.name for j in scene.description.moving_joints
            if j.type == "prismatic" and (j.limits.lower is not None or j.limits.upper is not None)]


def kept_damping(scene: ModelScene) -> np.ndarray:
    """(nv − base,) N·m·s/rad (N·s/m): the file's joint damping per joint velocity entry (a ball joint's on each
    of its three) in the model's joint order when kept, else 0."""
    keep = scene.file_dynamics == "keep"
    return np.array([j.damping if keep else 0.0 for j in scene.description.moving_joints for _ in range(j.nv)])
