"""Scene parameters as variables: which a gradient may be taken with respect to, a scene moved along one,
and the outputs a gradient is of.

A parameter is a catalog scene's real parameter (``theta1``, ``omega2``, ``g``, ``m1``, ``l2``, ...),
measured in SI units (radians for an angle the catalog takes in degrees); the outputs are the CSV's
state columns at one time (positions m and velocities m/s of each particle).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from engines.errors import UserError


def output_columns(scene: Any) -> list[str]:
    """The CSV's state columns, in its order: ``p{i}_x p{i}_y p{i}_z v{i}_x v{i}_y v{i}_z`` per particle; for a
    model scene ``q_<joint>`` then ``v_<joint>`` for its moving joints."""
    if scene.is_model:  # a floating base's and a ball's entries one column each (quaternion x y z w included)
        return [*(f"q_{name}" for name in scene.config_names), *(f"v_{name}" for name in scene.velocity_names)]
    return [f"{kind}{i}_{axis}" for i in range(len(scene.particles)) for kind in "pv" for axis in "xyz"]


def outputs_of(positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """(…, 6P) in :func:`output_columns` order from positions and velocities (…, P, 3)."""
    both = np.concatenate([positions, velocities], axis=-1)  # (…, P, 6)
    return both.reshape(both.shape[:-2] + (-1,))


def si_scale(scene_name: str, name: str) -> float:
    """SI units per unit of catalog parameter ``name``: π/180 for an angle in degrees, 1 otherwise."""
    from engines.scene.catalog import builder

    unit = {p.name: p.unit for p in builder(scene_name).parameters}[name]
    return math.pi / 180.0 if unit == "deg" else 1.0


def model_parameters(scene: Any) -> list[str]:
    """A model scene's parameters: ``q0.<joint>`` and ``v0.<joint>`` for its moving joints (SI: rad or m, rad/s
    or m/s; the q0 a user gives in degrees is differentiated per radian), in v's order. A quaternion's q0 is
    differentiated along the tangent: ``q0.J.rx``, ``.ry``, ``.rz`` turn a ball's child (or, for ``q0.BASE``, the
    base) about its own x, y, z axes (per radian, Q ⊗ exp(δ/2), Pinocchio's q ⊕ δ), so every perturbed
    quaternion stays a unit one; a base's position ``q0.BASE.x`` … ``.z`` (m, world); a base's and a ball's v0
    per entry (``v0.BASE.vx`` … ``.wz``, ``v0.J.wx`` … ``.wz``)."""
    description = scene.description
    rotations = ("rx", "ry", "rz")
    config = [f"{description.floating.name}.{a}" for a in ("x", "y", "z", *rotations)] \
        if description.floating is not None else []
    for joint in description.moving_joints:
        config += [f"{joint.name}.{a}" for a in rotations] if joint.type == "ball" else [joint.name]
    return [*(f"q0.{name}" for name in config), *(f"v0.{name}" for name in scene.velocity_names)]


def _turned(q0: tuple, joint: str, axis: int, angle: float) -> tuple:
    """A model scene's q0 entries with joint ``joint``'s quaternion (``joint.qx`` … ``.qw``) turned by ``angle``
    rad about its own ``axis`` (0, 1, 2): Q ⊗ (sin(angle/2) e, cos(angle/2))."""
    names = [f"{joint}.q{a}" for a in "xyzw"]
    values = dict(q0)
    vector, scalar = np.array([values[n] for n in names[:3]]), values[names[3]]
    turn = np.zeros(3)
    turn[axis] = np.sin(angle / 2)
    c = np.cos(angle / 2)
    moved = dict(zip(names, [*(scalar * turn + c * vector + np.cross(vector, turn)), c * scalar - vector @ turn]))
    return tuple((name, float(moved.get(name, value))) for name, value in q0)


def real_parameters(scene: Any) -> list[str]:
    """The parameters a gradient may be taken with respect to: a catalog scene's real ones (not an integer such as
    ``n``, not ``duration``), a model scene's :func:`model_parameters`."""
    if scene.is_model:
        return model_parameters(scene)
    from engines.scene.catalog import builder

    return [p.name for p in builder(scene.name).parameters if not p.integer and p.name != "duration"]


def check_wrt(scene: Any, wrt: Sequence[str]) -> None:
    """UserError unless every name of ``wrt`` is a real-valued parameter of ``scene``'s catalog entry (or, for a
    model scene, one of :func:`model_parameters`)."""
    if not wrt:
        raise UserError("--wrt: give at least one scene parameter, e.g. --wrt theta1,g")
    allowed = real_parameters(scene)
    for name in wrt:
        if name not in allowed:
            raise UserError(f"--wrt: {scene.name} has no real parameter {name!r}; choose from: {', '.join(allowed)}")
    if len(set(wrt)) != len(wrt):
        raise UserError(f"--wrt: a parameter is named twice in {', '.join(wrt)}")


def perturbed(scene: Any, name: str, delta: float) -> Any:
    """``scene`` with parameter ``name`` moved by ``delta`` SI units (rad for angles): a catalog scene rebuilt from
    the catalog, a model scene with its q0 or v0 entry moved."""
    if scene.is_model:
        kind, _, joint = name.partition(".")
        stem, _, axis = joint.rpartition(".")
        if kind == "q0" and axis in ("rx", "ry", "rz"):
            return replace(scene, q0=_turned(scene.q0, stem, "xyz".index(axis[1]), delta))
        moved = tuple((j, value + delta if j == joint else value) for j, value in getattr(scene, kind))
        return replace(scene, **{kind: moved})
    from engines.scene.catalog import build

    values: dict[str, Any] = dict(scene.parameters)
    values[name] = float(values[name]) + delta / si_scale(scene.name, name)
    return build(scene.name, values)


def central_difference(function, step: float) -> np.ndarray:
    """d function / d δ at δ = 0 by central differences at ±step and ±step/2 with one Richardson step,
    (4 D(h/2) − D(h)) / 3: error O(h⁴) for a smooth ``function`` of the scalar δ (returning an array)."""
    wide = (function(step) - function(-step)) / (2 * step)
    narrow = (function(step / 2) - function(-step / 2)) / step
    return (4 * narrow - wide) / 3
