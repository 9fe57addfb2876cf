"""Floating bases: every engine's q and v mapped to xval's one convention (Pinocchio's: q = (position,
quaternion x y z w, joints), v = (linear, angular in the base frame, joints)), each mapping tested by
invariants computed here from the file's numbers (scipy rotations, finite differences), not from any engine:
½ vᵀ M v is the links' kinetic energy, and the base rows of M v are the total momentum (linear, and angular
about the base origin) in the base frame. Then ``model check`` on a URDF quadruped with --base floating and
on an MJCF free-joint quadruped."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from compare.model.parity import check, read_description
from engines.model.importers import importer

FIXTURES = Path(__file__).resolve().parent / "fixtures"
URDF = FIXTURES / "urdf" / "quadruped.urdf"
MJCF = FIXTURES / "mjcf" / "quadruped.xml"


def link_frames(model, q):
    """Link name -> (R, p) in the world at xval's configuration q, walking the description's joints with scipy."""
    values = dict(zip((j.name for j in model.moving_joints), q[7:]))
    frames = {model.root: (np.eye(3), np.zeros(3))}
    for joint in model.joints:
        r, p = frames[joint.parent]
        if joint.type == "floating":
            frames[joint.child] = (Rotation.from_quat(q[3:7]).as_matrix(), np.asarray(q[:3]))
            continue
        r = r @ Rotation.from_euler("xyz", joint.rpy).as_matrix()
        p = p + frames[joint.parent][0] @ np.asarray(joint.xyz)
        if joint.type in ("revolute", "continuous"):
            r = r @ Rotation.from_rotvec(np.asarray(joint.axis) * values[joint.name]).as_matrix()
        elif joint.type == "prismatic":
            p = p + r @ np.asarray(joint.axis) * values[joint.name]
        frames[joint.child] = (r, p)
    return frames


def advance(q, v, h):
    """q moved by h·v in xval's convention: the base by its body-frame twist, the joints by their rates."""
    r = Rotation.from_quat(q[3:7])
    out = q.copy()
    out[:3] = q[:3] + r.apply(h * v[:3])
    out[3:7] = (r * Rotation.from_rotvec(h * v[3:6])).as_quat()
    out[7:] = q[7:] + h * v[6:]
    return out


def links_state(model, q, v):
    """Per link with mass: (m, c (3,), ċ (3,), I about c in the world (3, 3), ω (3,)), by central differences."""
    h = 1e-6
    ahead, here, behind = link_frames(model, advance(q, v, h)), link_frames(model, q), link_frames(model, advance(q, v, -h))
    out = []
    for body in model.bodies:
        inertial = body.inertial
        if inertial.mass == 0 and not np.any(inertial.inertia_matrix):
            continue
        com = {k: f[body.name][1] + f[body.name][0] @ np.asarray(inertial.com) for k, f in
               (("ahead", ahead), ("here", here), ("behind", behind))}
        r = here[body.name][0]
        spin = Rotation.from_matrix(ahead[body.name][0] @ behind[body.name][0].T).as_rotvec() / (2 * h)
        out.append((inertial.mass, com["here"], (com["ahead"] - com["behind"]) / (2 * h),
                    r @ inertial.inertia_matrix @ r.T, spin))
    return out


def random_state(model, rng):
    q = np.concatenate([rng.uniform(-1, 1, 3), Rotation.random(random_state=rng).as_quat(),
                        rng.uniform(-0.8, 0.8, model.nq)])
    return q, rng.uniform(-1, 1, model.nv)


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco", "pybullet", "drake", "dart"])
def test_each_engines_floating_base_maps_to_the_one_convention_by_energy_and_momentum(engine):
    source, model = read_description(str(URDF), "floating")
    loaded = importer(engine).load(source, model)
    rng = np.random.default_rng(7)
    for _ in range(2):
        q, v = random_state(model, rng)
        m = loaded.mass_matrix(q)
        links = links_state(model, q, v)
        energy = sum(0.5 * mass * dc @ dc + 0.5 * w @ inertia @ w for mass, _, dc, inertia, w in links)
        assert 0.5 * v @ m @ v == pytest.approx(energy, rel=1e-7), engine
        momentum = m @ v
        rotation = Rotation.from_quat(q[3:7]).as_matrix()
        linear = sum(mass * dc for mass, _, dc, _, _ in links)
        angular = sum(np.cross(c - q[:3], mass * dc) + inertia @ w for mass, c, dc, inertia, w in links)
        np.testing.assert_allclose(rotation @ momentum[:3], linear, atol=1e-6 * np.abs(linear).max(), err_msg=engine)
        np.testing.assert_allclose(rotation @ momentum[3:6], angular, atol=1e-6 * np.abs(angular).max(), err_msg=engine)


def test_a_urdf_quadruped_with_a_floating_base_checks_in_every_engine():
    report = check(str(URDF), states=10, base="floating")
    assert {e.engine: e.agrees for e in report.engines} == {"mujoco": True, "pybullet": True, "drake": True, "dart": True}
    assert report.moving_joints == tuple(f"{leg}_{j}" for leg in ("fl", "fr", "bl", "br") for j in ("hip", "knee"))


def test_an_mjcf_free_joint_is_the_floating_base_and_checks():
    """MuJoCo and Drake agree with the reference; PyBullet compares (its MJCF import drops the inertias, and
    the diagnosis says so); DART's MJCF parser makes the floor a skeleton of its own here (and elsewhere welds a
    free joint's body to the world), so it is refused."""
    source, model = read_description(str(MJCF))
    assert model.floating is not None and model.floating.name == "root" and (model.nv, model.nconfig) == (14, 15)
    rows = {e.engine: e for e in check(str(MJCF), states=10).engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "pybullet": False, "drake": True,
                                                                 "dart": False}
    assert rows["pybullet"].loaded and all("pybullet drops the inertia" in line for line in rows["pybullet"].diagnosis)
    assert not rows["dart"].loaded
    assert rows["dart"].message == "MjcfParser.readWorld did not give one skeleton (DART printed the reason)"


def test_a_model_scene_refuses_a_floating_base_in_one_line():
    from engines.model.description import ModelError
    from engines.model.scene import model_scene

    with pytest.raises(ModelError, match=r"^model .*quadruped.xml: a floating base \(joint root\) is not supported "
                                         r"in model scenes yet; use `xval model check` for its dynamics, or weld "
                                         r"the base \(remove the free joint\)$"):
        model_scene("q", str(MJCF))


def test_the_panda_fingers_are_named_as_unbounded_once_limits_are_off():
    from engines.model.scene import model_scene
    from engines.model.stepping import unbounded_joints

    scene = model_scene("panda", "pybullet_data:franka_panda/panda.urdf")
    assert unbounded_joints(scene) == ["panda_finger_joint1", "panda_finger_joint2"]
