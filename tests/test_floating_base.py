"""Floating bases: every engine's q and v mapped to xval's one convention (Pinocchio's: q = (position,
quaternion x y z w, joints), v = (linear, angular in the base frame, joints)), each mapping tested by
invariants computed here from the file's numbers (scipy rotations, finite differences), not from any engine:
½ vᵀ M v is the links' kinetic energy, and the base rows of M v are the total momentum (linear, and angular
about the base origin) in the base frame. Then ``model check`` on a URDF quadruped with --base floating and
on an MJCF free-joint quadruped, and that quadruped as a model scene (g = 0: its momentum holds)."""

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
    assert_energy_and_momentum(engine, *read_description(str(URDF), "floating"))


@pytest.mark.parametrize("engine", ["mujoco", "drake", "dart"])
def test_an_mjcf_free_joint_maps_to_the_one_convention_by_energy_and_momentum(engine):
    """The free joint as each MJCF parser makes it (DART's puts the body's pose in its FreeJoint's parent
    transform; xval makes the joint's frames the body's). DART's parser ignores <inertial>: its bodies are
    given the file's here, so that the mapping alone is tested. PyBullet's loadMJCF drops the inertias."""
    assert_energy_and_momentum(engine, *read_description(str(MJCF)))


def assert_energy_and_momentum(engine, source, model):
    loaded = importer(engine).load(source, model)
    if engine == "dart" and source.format == "mjcf":
        import dartpy

        inertials = {body.name: body.inertial for body in model.bodies}
        for k in range(loaded.skeleton.getNumBodyNodes()):
            node = loaded.skeleton.getBodyNode(k)
            inertial = inertials[node.getName()]
            node.setInertia(dartpy.dynamics.Inertia(inertial.mass, np.asarray(inertial.com), inertial.inertia_matrix))
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


def test_the_urdf_quadruped_with_its_base_welded_checks_in_every_engine():
    """Its base's inertial frame is turned: PyBullet's fixed-base calculateInverseDynamics reads gravity in that
    frame's axes (its gravity torques were 28 % off while its stepping was right); handed gravity there, every
    engine agrees, and PyBullet's notes say so."""
    rows = {e.engine: e for e in check(str(URDF), states=10).engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "pybullet": True, "drake": True,
                                                                 "dart": True}
    assert any("handed gravity in that frame's axes" in note for note in rows["pybullet"].notes)


def test_an_mjcf_free_joint_is_the_floating_base_and_checks():
    """MuJoCo and Drake agree with the reference; PyBullet and DART compare, and the diagnosis names what their
    MJCF imports do to the inertias (PyBullet drops them; DART's parser ignores <inertial>: 1 kg and 1 kg·m²).
    DART's parser makes the floor a skeleton of its own (left out) and welds a <freejoint>'s body (given the
    long form, <joint type="free">): its notes say both."""
    source, model = read_description(str(MJCF))
    assert model.floating is not None and model.floating.name == "root" and (model.nv, model.nconfig) == (14, 15)
    rows = {e.engine: e for e in check(str(MJCF), states=10).engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "pybullet": False, "drake": True,
                                                                 "dart": False}
    assert rows["pybullet"].loaded and all("pybullet drops the inertia" in line for line in rows["pybullet"].diagnosis)
    assert rows["dart"].loaded and rows["dart"].diagnosis[0] == (
        "link torso: mass 4 kg, inertia principal moments (0.05, 0.08, 0.1) kg·m² — dart gives it 1 kg and 1 kg·m²")
    assert rows["dart"].notes[:2] == (
        "1 skeleton of the world body's static geoms left out (MjcfParser.readWorld makes one per geom)",
        '<freejoint> given to DART as <joint type="free"> (its parser welds the body of a <freejoint>)')


def swinging_quadruped(g: float = 0.0, duration: float = 1.0):
    """The MJCF quadruped as a scene: the base at rest, somewhere off the origin and turned, the legs swinging."""
    from engines.model.scene import model_scene

    legs = [f"{leg}_{part}" for leg in ("fl", "fr", "bl", "br") for part in ("hip", "knee")]
    q0 = {name: 20.0 * (-1) ** k for k, name in enumerate(legs)}
    v0 = {name: (3.0 if name.endswith("hip") else -4.0) * (1 + 0.3 * (k // 2)) for k, name in enumerate(legs)}
    return model_scene("quadruped", str(MJCF), q0={**q0, "root": [0.1, -0.2, 0.6, 0.1, 0.2, 0.05, 0.97]},
                       v0=v0, duration=duration, g=g)


def test_in_zero_gravity_a_free_quadruped_swinging_its_legs_holds_its_momentum_and_its_base_answers():
    """g = 0, nothing outside acts: the total linear momentum and the angular momentum about the world origin
    (momentum_drift, relative to M·√(g·L) and M·L·√(g·L)) hold to ≤ 1e-10 over 1 s in the reference (ABA under
    DOP853, the quaternion's rate ½ q ⊗ ω) and in ours' RK4 at dt 1e-3 (a free rigid body in maximal
    coordinates); the base, at rest at t = 0, turns and moves as the legs swing. MuJoCo's RK4 and Drake step it
    too and follow the reference (DART steps it as well: tests/test_dart_floating_base.py)."""
    from engines.reference.reference import ENGINE as REFERENCE
    from engines.registry import resolve

    scene = swinging_quadruped()
    assert scene.config_names[:7] == ("root.x", "root.y", "root.z", "root.qx", "root.qy", "root.qz", "root.qw")
    assert scene.conserved_momenta() == ("px", "py", "pz", "Lx", "Ly", "Lz")
    assert swinging_quadruped(g=9.81).conserved_momenta() == ("px", "py", "Lz")
    reference = REFERENCE.simulate(scene, 1e-3)
    q, v = scene.split(reference.joint_states)
    assert q.shape == (101, 15) and v.shape == (101, 14)
    assert scene.momentum_drift(q, v) <= 1e-10
    assert np.abs(v[0, :6]).max() == 0 and np.abs(v[-1, :6]).max() > 0.05  # the base answers the legs
    turned = Rotation.from_quat(q[-1, 3:7]) * Rotation.from_quat(q[0, 3:7]).inv()
    assert turned.magnitude() > 0.01
    reach = scene.characteristic_length
    for engine_id, bound in (("ours/projection-rk4", 1e-9), ("mujoco/hinge-rk4", 1e-9), ("drake/rk3", 1e-6)):
        engine, variant = resolve(engine_id)
        run = engine.simulate(scene, 1e-3, variant=variant)
        if engine_id.startswith("ours"):
            assert scene.momentum_drift(*scene.split(run.joint_states)) <= 1e-10
        assert np.abs(run.positions - reference.positions).max() <= bound * reach, engine_id


def test_a_floating_base_s_initial_state_is_checked_in_one_line():
    from engines.model.description import ModelError
    from engines.model.scene import model_scene

    with pytest.raises(ModelError, match=r"^model .*quadruped.xml: q0.root \(the floating base\) must be \[x, y, z, "
                                         r"qx, qy, qz, qw\] \(m, a nonzero quaternion\), got \[0, 0, 0\]$"):
        model_scene("q", str(MJCF), q0={"root": [0, 0, 0]})


def test_the_panda_fingers_are_named_as_unbounded_once_limits_are_off():
    from engines.model.scene import model_scene
    from engines.model.stepping import unbounded_joints

    scene = model_scene("panda", "pybullet_data:franka_panda/panda.urdf")
    assert unbounded_joints(scene) == ["panda_finger_joint1", "panda_finger_joint2"]


def test_a_floating_base_runs_through_simulate_score_and_a_suite(tmp_path, capsys):
    """The CSV names the base's columns (q_root.x … q_root.qw, v_root.vx … v_root.wz) and `xval score` reads
    them back to the same frames; a suite with `parameters = { g = 0 }` runs it in ours and MuJoCo, whose
    momentum_drift is the total momentum's (≤ 1e-10 at RK4, dt 1e-3)."""
    import json

    from cli_support import run_cli

    out = tmp_path / "q.csv"
    code, _, err = run_cli(capsys, "simulate", "--model", MJCF, "--engine", "mujoco/hinge-rk4", "--dt", "1e-3",
                           "--param", "g=0", "--param", "v0.fl_hip=2", "--output", out)
    assert code == 0, err
    header = out.read_text().splitlines()[0].split(",")
    assert header[1:8] == ["q_root.x", "q_root.y", "q_root.z", "q_root.qx", "q_root.qy", "q_root.qz", "q_root.qw"]
    assert header[16:22] == ["v_root.vx", "v_root.vy", "v_root.vz", "v_root.wx", "v_root.wy", "v_root.wz"]
    code, scored, err = run_cli(capsys, "score", "--model", MJCF, out, "--param", "g=0", "--param", "v0.fl_hip=2",
                                "--format", "json")
    (row,) = json.loads(scored)
    assert code == 0 and row["status"] == "ok" and row["position_error_linf"] < 1e-9, err
    suite = tmp_path / "suite.toml"
    suite.write_text(f'duration = 0.3\ndt = [1e-3]\n[[scenes]]\nid = "free"\nmodel = "{MJCF}"\n'
                     f'parameters = {{ g = 0 }}\nv0 = {{ fl_hip = 3, br_knee = -2 }}\n'
                     f'[[engines]]\nid = "ours/projection-rk4"\n[[engines]]\nid = "mujoco/hinge-rk4"\n')
    code, _, err = run_cli(capsys, "run", suite, "--output", tmp_path / "run", "--jobs", "1")
    assert code == 0, err
    code, shown, err = run_cli(capsys, "show", tmp_path / "run", "--format", "json")
    rows = {r["engine"]: r for r in json.loads(shown)}
    assert {name: r["status"] for name, r in rows.items()} == {"ours/projection-rk4": "ok", "mujoco/hinge-rk4": "ok"}
    assert all(r["momentum_drift"] <= 1e-10 for r in rows.values()), rows


def test_a_urdf_runs_with_a_floating_base_when_the_suite_says_base_floating(tmp_path, capsys):
    """`base = "floating"` frees the URDF quadruped's root (a floating joint __floating_base__ above it, its
    state first in q and v): in g = 0 ours, MuJoCo and Drake run it, following the reference and holding the
    total momentum; PyBullet (semi-implicit Euler, its base the base link's turned and offset inertial frame)
    follows it at first order: its error and momentum drift fall 4× when dt does (measured 7.9e-5 m and 2.0e-5 m
    at dt 1e-3 and 2.5e-4). `base` on an MJCF is refused in one line (its free joint says it)."""
    import json

    from cli_support import run_cli
    from engines.model.description import ModelError
    from engines.model.scene import model_scene

    suite = tmp_path / "suite.toml"
    suite.write_text(f'duration = 0.3\ndt = [1e-3]\n[[scenes]]\nid = "free"\nmodel = "{URDF}"\nbase = "floating"\n'
                     f'parameters = {{ g = 0 }}\nv0 = {{ fl_hip = 3, br_knee = -2, '
                     f'__floating_base__ = [0.1, 0, 0, 0, 0.5, 0] }}\n[[engines]]\nid = "ours/projection-rk4"\n'
                     f'[[engines]]\nid = "mujoco/hinge-rk4"\n[[engines]]\nid = "drake/rk3"\n')
    code, _, err = run_cli(capsys, "run", suite, "--output", tmp_path / "run", "--jobs", "1")
    assert code == 0, err
    code, shown, err = run_cli(capsys, "show", tmp_path / "run", "--format", "json")
    rows = json.loads(shown)
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert all(r["momentum_drift"] <= 1e-10 and r["position_error_linf"] <= 1e-9 for r in rows), rows
    from engines.registry import resolve
    from engines.reference.reference import ENGINE as REFERENCE

    scene = model_scene("q", str(URDF), v0={"fl_hip": 3, "br_knee": -2, "__floating_base__": [0.1, 0, 0, 0, 0.5, 0]},
                        duration=0.3, g=0, root_joint="floating")
    reference = REFERENCE.simulate(scene, 1e-3).positions
    engine, variant = resolve("pybullet/multibody")
    runs = [engine.simulate(scene, dt, variant=variant) for dt in (1e-3, 2.5e-4)]
    errors = [np.abs(run.positions - reference).max() for run in runs]
    drifts = [scene.momentum_drift(*scene.split(run.joint_states)) for run in runs]
    assert 3 < errors[0] / errors[1] < 5 and 3 < drifts[0] / drifts[1] < 5, (errors, drifts)
    scene = model_scene("q", str(URDF), root_joint="floating")
    assert scene.config_names[:7] == tuple(f"__floating_base__.{a}" for a in ("x", "y", "z", "qx", "qy", "qz", "qw"))
    with pytest.raises(ModelError, match=r'^model .*quadruped.xml: base = "floating" is for a URDF; an MJCF\'s '
                                         r'base floats when its root body has a free joint$'):
        model_scene("q", str(MJCF), root_joint="floating")
