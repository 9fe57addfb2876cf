"""Ball joints: a quaternion in q (x y z w, the child frame's rotation in the joint frame) and three velocities
(the child's angular velocity in its own frame), Pinocchio's JointModelSpherical. Each engine's mapping is
tested by invariants computed here from the file's numbers (scipy rotations, finite differences), not from any
engine: ½ vᵀ M v is the links' kinetic energy, and a root ball's rows of M v are the angular momentum of what it
carries about its centre, in the child frame. Then ``model check`` on an MJCF and a URDF with ball joints and on
pybullet_data's spherical_joint_limit.urdf, and a 3-D double pendulum as a model scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from compare.model.parity import check, read_description
from engines.model.description import ModelError
from engines.model.importers import importer

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = ROOT / "tests" / "fixtures"
MJCF = FIXTURES / "mjcf" / "ball_pendulum.xml"
URDF = FIXTURES / "urdf" / "ball_chain.urdf"


def values(model, q):
    """Joint name -> its entries of xval's configuration q."""
    return {name: q[where] for name, (where, _) in model.slots.items()}


def link_frames(model, q):
    """Link name -> (R, p) in the world at xval's configuration q (fixed base), walking the joints with scipy."""
    given = values(model, q)
    frames = {model.root: (np.eye(3), np.zeros(3))}
    for joint in model.joints:
        r, p = frames[joint.parent]
        p = p + r @ np.asarray(joint.xyz)
        r = r @ Rotation.from_euler("xyz", joint.rpy).as_matrix()
        if joint.type == "ball":
            r = r @ Rotation.from_quat(given[joint.name]).as_matrix()
        elif joint.type in ("revolute", "continuous"):
            r = r @ Rotation.from_rotvec(np.asarray(joint.axis) * given[joint.name][0]).as_matrix()
        elif joint.type == "prismatic":
            p = p + r @ np.asarray(joint.axis) * given[joint.name][0]
        frames[joint.child] = (r, p)
    return frames


def advance(model, q, v, h):
    """q moved by h·v: a ball by its child-frame angular velocity (R ← R exp(h [ω]×)), the others by their rates."""
    out = q.copy()
    for joint in model.moving_joints:
        where_q, where_v = model.slots[joint.name]
        if joint.type == "ball":
            out[where_q] = (Rotation.from_quat(q[where_q]) * Rotation.from_rotvec(h * v[where_v])).as_quat()
        else:
            out[where_q] = q[where_q] + h * v[where_v]
    return out


def links_state(model, q, v):
    """Per link with mass: (m, c (3,), ċ (3,), I about c in the world (3, 3), ω (3,)), by central differences."""
    h = 1e-6
    ahead, here, behind = (link_frames(model, advance(model, q, v, s)) for s in (h, 0.0, -h))
    out = []
    for body in model.bodies:
        inertial = body.inertial
        if inertial.mass == 0 and not np.any(inertial.inertia_matrix):
            continue
        com = [f[body.name][1] + f[body.name][0] @ np.asarray(inertial.com) for f in (ahead, here, behind)]
        r = here[body.name][0]
        spin = Rotation.from_matrix(ahead[body.name][0] @ behind[body.name][0].T).as_rotvec() / (2 * h)
        out.append((body.name, inertial.mass, com[1], (com[0] - com[2]) / (2 * h), r @ inertial.inertia_matrix @ r.T,
                    spin))
    return out


def random_state(model, rng):
    q = model.neutral()
    for joint in model.moving_joints:
        where = model.slots[joint.name][0]
        q[where] = Rotation.random(random_state=rng).as_quat() if joint.type == "ball" else rng.uniform(-0.8, 0.8)
    return q, rng.uniform(-1, 1, model.nv)


def give_file_inertias(skeleton, model):
    """Each DART body the file's mass and inertia, its centre moved into DART's body frame (an MJCF body's frame;
    the description's link frame sits at the joint's anchor)."""
    import dartpy

    inertials = {body.name: body.inertial for body in model.bodies}
    for k in range(skeleton.getNumBodyNodes()):
        node = skeleton.getBodyNode(k)
        inertial = inertials[node.getName()]
        anchor = np.asarray(node.getParentJoint().getTransformFromChildBodyNode().translation())
        node.setInertia(dartpy.dynamics.Inertia(inertial.mass, np.asarray(inertial.com) + anchor,
                                                inertial.inertia_matrix))


def assert_energy_and_momentum(engine, source, model):
    loaded = importer(engine).load(source, model)
    if engine == "dart":  # its MJCF parser ignores <inertial>: the file's given, so that the mapping alone is tested
        give_file_inertias(loaded.skeleton, model)
    rng = np.random.default_rng(7)
    root = next(j for j in model.moving_joints if j.parent == model.root)
    assert root.type == "ball"
    for _ in range(3):
        q, v = random_state(model, rng)
        m = loaded.mass_matrix(q)
        links = links_state(model, q, v)
        energy = sum(0.5 * mass * dc @ dc + 0.5 * w @ inertia @ w for _, mass, _, dc, inertia, w in links)
        assert 0.5 * v @ m @ v == pytest.approx(energy, rel=1e-7), engine
        frame, centre = link_frames(model, q)[root.child]
        angular = sum(np.cross(c - centre, mass * dc) + inertia @ w for _, mass, c, dc, inertia, w in links)
        np.testing.assert_allclose(frame @ (m @ v)[model.slots[root.name][1]], angular,
                                   atol=1e-6 * np.abs(angular).max(), err_msg=engine)


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco", "pybullet", "drake"])
def test_each_engines_ball_joints_from_a_urdf_map_to_the_one_convention_by_energy_and_momentum(engine):
    """Two spherical joints (shoulder at the root, wrist below a hinge); the upper arm's inertial frame is turned
    and its inertia has products, so PyBullet's principal axes differ from the link frame."""
    assert_energy_and_momentum(engine, *read_description(str(URDF)))


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco", "drake", "dart"])
def test_each_engines_mjcf_ball_joint_maps_to_the_one_convention_by_energy_and_momentum(engine):
    """A ball anchored 0.1 m off its body's frame, a hinge below: MuJoCo's own, Drake's BallRpyJoint, DART's
    BallJoint (its rotation vector), each as its MJCF parser makes it."""
    assert_energy_and_momentum(engine, *read_description(str(MJCF)))


def test_the_description_holds_ball_joints_as_a_quaternion_and_three_velocities():
    _, mjcf = read_description(str(MJCF))
    assert [(j.name, j.type) for j in mjcf.moving_joints] == [("shoulder", "ball"), ("elbow", "continuous")]
    assert (mjcf.nq, mjcf.nv, mjcf.nconfig) == (5, 4, 5)
    assert mjcf.joint_config_names == ("shoulder.qx", "shoulder.qy", "shoulder.qz", "shoulder.qw", "elbow")
    assert mjcf.dof_names == ("shoulder.wx", "shoulder.wy", "shoulder.wz", "elbow")
    np.testing.assert_array_equal(mjcf.neutral(), [0, 0, 0, 1, 0])
    _, urdf = read_description(str(URDF))
    assert [j.type for j in urdf.moving_joints] == ["ball", "revolute", "ball"]
    assert (urdf.nq, urdf.nv) == (9, 7) and urdf.slots["wrist"] == (slice(5, 9), slice(4, 7))
    assert urdf.joint("shoulder").limits.lower is None  # the cone (lower, upper, twist) is left out, as limits are


def test_model_check_compares_ball_joints_in_every_engine_that_has_them():
    """M, bias and q̈ within the check's tolerance (1e-6 relative; q̈ within its conditioning bound) wherever an
    engine has a ball joint; an engine whose reader has none says so in one line."""
    urdf = {e.engine: e for e in check(str(URDF), states=10).engines}
    assert {n: e.agrees for n, e in urdf.items()} == {"mujoco": True, "pybullet": True, "drake": True, "dart": False}
    assert urdf["dart"].message == ("DART's URDF reader (urdfdom) has no spherical joint; DART compares ball "
                                    "joints from an MJCF")
    assert all(e.mass_matrix <= 1e-6 and e.bias <= 1e-6 for n, e in urdf.items() if n != "dart")
    report = check(str(MJCF), states=10)
    mjcf = {e.engine: e for e in report.engines}
    assert {n: e.agrees for n, e in mjcf.items()} == {"mujoco": True, "pybullet": False, "drake": True, "dart": False}
    assert mjcf["pybullet"].message.startswith("loadMJCF makes no joint of an MJCF ball joint")
    # DART loads and compares it; its parser ignores <inertial> (1 kg, 1 kg·m²), which the diagnosis names.
    assert mjcf["dart"].loaded and "dart gives it 1 kg and 1 kg·m²" in mjcf["dart"].diagnosis[0]
    assert any("pitch kept 5° from ±90°" in note for note in report.notes)
    free = {e.engine: e for e in check(str(URDF), states=10, base="floating").engines}  # a floating base as well
    assert {n: e.agrees for n, e in free.items()} == {"mujoco": True, "pybullet": False, "drake": True, "dart": False}
    assert free["pybullet"].message == ("ball joints are compared on a fixed base only (its multibody's floating "
                                        "base with spherical joints is not mapped here)")


def test_pybullet_datas_spherical_joint_limit_is_checked_not_refused():
    """Its neck's inertia (0.01, 0.001, 0.001) breaks the triangle inequality: MuJoCo refuses it with its
    compiler's message, PyBullet and Drake load and compare it, and the diagnosis names the link and why."""
    report = check("pybullet_data:spherical_joint_limit.urdf", states=10)
    rows = {e.engine: e for e in report.engines}
    assert report.moving_joints == ("neck",)
    assert rows["mujoco"].message.startswith("Error: inertia must satisfy A + B >= C")
    assert rows["pybullet"].loaded and rows["drake"].loaded
    assert report.diagnosis and report.diagnosis[0].startswith(
        "link neck: mass 1 kg, inertia principal moments (0.001, 0.001, 0.01) kg·m², against the triangle inequality")


def ball_pendulum(duration: float = 1.0, g: float = 9.81):
    from engines.model.scene import model_scene

    return model_scene("ball", str(MJCF), q0={"shoulder": [0.3, 0.1, 0.2, 0.9], "elbow": 40.0},
                       v0={"shoulder": [1.0, -0.5, 2.0], "elbow": -1.0}, duration=duration, g=g)


def test_a_3d_double_pendulum_on_a_ball_joint_conserves_energy_and_its_vertical_momentum_and_engines_track_it():
    """The reference (ABA under DOP853, each ball's quaternion integrated beside it as ½ q ⊗ ω) holds the energy
    to ≤ 1e-10 E* and the vertical angular momentum about the pivot (gravity's torque about it is horizontal)
    to ≤ 1e-10 over 1 s; MuJoCo and ours (RK4, dt 1e-3: ours' ball a point constraint between bodies) follow it
    to ≤ 1e-9 L and Drake's RK3 (BallRpyJoint; the motion stays far from pitch ±90°) to ≤ 1e-6 L; PyBullet
    says in one line that it has no MJCF ball (DART: the next test)."""
    from engines.errors import Unsupported
    from engines.reference.reference import ENGINE as REFERENCE
    from engines.registry import resolve

    scene = ball_pendulum()
    assert scene.config_names == ("shoulder.qx", "shoulder.qy", "shoulder.qz", "shoulder.qw", "elbow")
    assert scene.velocity_names == ("shoulder.wx", "shoulder.wy", "shoulder.wz", "elbow")
    assert scene.conserved_momenta() == ("shoulder.Lz",)
    assert ball_pendulum(g=0.0).conserved_momenta() == ("shoulder.Lx", "shoulder.Ly", "shoulder.Lz")
    reference = REFERENCE.simulate(scene, 1e-3)
    q, v = scene.split(reference.joint_states)
    energy = scene.energy(q, v)
    assert np.abs(energy - energy[0]).max() <= 1e-10 * scene.characteristic_energy
    assert scene.momentum_drift(q, v) <= 1e-10
    assert np.abs(np.linalg.norm(q[:, :4], axis=1) - 1).max() <= 1e-9  # the flow keeps the quaternion's norm
    reach = scene.characteristic_length
    assert np.abs(reference.positions - reference.positions[0]).max() > 0.5  # m: it swings
    for engine_id, bound in (("ours/projection-rk4", 1e-9), ("mujoco/hinge-rk4", 1e-9), ("drake/rk3", 1e-6)):
        engine, variant = resolve(engine_id)
        run = engine.simulate(scene, 1e-3, variant=variant)
        assert np.abs(run.positions - reference.positions).max() <= bound * reach, engine_id
    engine, variant = resolve("pybullet")
    with pytest.raises(Unsupported, match=r"^pybullet: ball joints \(shoulder\) are stepped from a URDF's spherical "
                                          r"joints on a fixed base only \(its loadMJCF makes no ball"):
        engine.check(scene, variant)


@pytest.mark.parametrize("integrator, dt, bound", [("rk4", 1e-3, 1e-10), ("rk4", 5e-4, 1e-11),
                                                   ("world", 1e-3, 1e-3), ("world", 5e-4, 5e-4)])
def test_dart_steps_an_mjcf_ball_joint_as_the_reference_once_its_bodies_have_the_files_inertias(integrator, dt, bound):
    """DART's MJCF parser ignores <inertial> (the check says so); given the file's masses and inertias (their
    centres moved to its body frame, the joint's anchor off the link frame), its BallJoint follows the reference:
    `dart/rk4` (xval's coordinates, the ball's quaternion by ½ q ⊗ ω) to ≤ 1e-10 L at dt 1e-3, falling 16×
    when dt halves (measured 5.9e-12 and 3.5e-13 L); `dart/world` (its semi-implicit Euler in its rotation
    vector) at first order (6.7e-4 and 3.4e-4 L)."""
    from engines.adapter import Schedule
    from engines.dart.model import DartStepper
    from engines.model.stepping import run_model
    from engines.reference.reference import ENGINE as REFERENCE

    scene = ball_pendulum()
    reference = REFERENCE.simulate(scene, dt)
    stepper = DartStepper(scene, dt, integrator)
    give_file_inertias(stepper.skeleton, scene.description)
    start_q, start_v = stepper.state()
    np.testing.assert_allclose(start_q, scene.initial_q, atol=1e-12)
    np.testing.assert_allclose(start_v, scene.initial_v, atol=1e-12)
    run = run_model(scene, Schedule.make(scene.duration, dt), stepper)
    error = np.abs(run.positions - reference.positions).max() / scene.characteristic_length
    assert bound / 4 <= error <= bound if integrator == "world" else error <= bound, error


def test_pybullet_steps_spherical_joints_at_first_order():
    """The URDF chain (two spherical joints, a hinge) as a scene (scripts/ball_joints.py, which docs/models.md
    quotes): PyBullet (semi-implicit Euler) follows the reference, its error halving with dt (measured 5.2e-3 m
    and 2.6e-3 m at dt 1e-3 and 5e-4 over 1 s)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("ball_joints_script", ROOT / "scripts" / "ball_joints.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    errors = script.first_order_errors()
    assert errors[0] <= 1e-2 and 1.8 <= errors[0] / errors[1] <= 2.2, errors


def test_a_ball_joints_initial_state_is_checked_in_one_line():
    from engines.model.scene import model_scene

    with pytest.raises(ModelError, match=r"^model .*ball_pendulum.xml: q0.shoulder \(a ball joint\) must be \[qx, qy, "
                                         r"qz, qw\] \(a nonzero quaternion\), got \[0, 0, 0, 0\]$"):
        model_scene("b", str(MJCF), q0={"shoulder": [0, 0, 0, 0]})
    with pytest.raises(ModelError, match=r"^model .*ball_pendulum.xml: v0.shoulder \(a ball joint\) must be \[wx, wy, "
                                         r"wz\] \(rad/s, in the child link's frame\), got 2$"):
        model_scene("b", str(MJCF), v0={"shoulder": 2})
    with pytest.raises(ModelError, match=r"^model .*ball_pendulum.xml: lock names ball joint 'shoulder'; only "):
        model_scene("b", str(MJCF), lock=["shoulder"])


def test_a_ball_joint_runs_through_simulate_and_score(tmp_path, capsys):
    """The CSV names a ball's columns (q_shoulder.qx … q_shoulder.qw, v_shoulder.wx … v_shoulder.wz), its
    initial state given at the command line as numbers apart by commas; `xval score` reads them back to the same
    link frames (MuJoCo's own run against the reference: ≤ 1e-9 m at RK4, dt 1e-3)."""
    import json

    from cli_support import run_cli

    out = tmp_path / "ball.csv"
    params = ["--param", "q0.shoulder=0,0.2,0,1", "--param", "v0.shoulder=1,0,2", "--param", "q0.elbow=30"]
    code, _, err = run_cli(capsys, "simulate", "--model", MJCF, "--engine", "mujoco/hinge-rk4", "--dt", "1e-3",
                           "--duration", "0.5", *params, "--output", out)
    assert code == 0, err
    header = out.read_text().splitlines()[0].split(",")
    assert header[1:6] == ["q_shoulder.qx", "q_shoulder.qy", "q_shoulder.qz", "q_shoulder.qw", "q_elbow"]
    assert header[6:10] == ["v_shoulder.wx", "v_shoulder.wy", "v_shoulder.wz", "v_elbow"]
    code, scored, err = run_cli(capsys, "score", "--model", MJCF, out, *params, "--format", "json")
    (row,) = json.loads(scored)
    assert code == 0 and row["status"] == "ok" and row["position_error_linf"] < 1e-9, err


def test_a_suite_runs_ball_joints_in_every_engine_that_steps_them(tmp_path, capsys):
    """`q0 = { J = [qx, qy, qz, qw] }`, `v0 = { J = [wx, wy, wz] }` in a suite: ours, MuJoCo, Drake and PyBullet
    run the URDF chain (ours and MuJoCo within 1e-9 m of the reference at RK4, Drake's RK3 1e-6 m, PyBullet's
    semi-implicit Euler 1e-2 m at dt 1e-3); DART's case is skipped with its one line (no spherical in urdfdom)."""
    import json

    from cli_support import run_cli

    suite = tmp_path / "suite.toml"
    suite.write_text(f'duration = 0.3\ndt = [1e-3]\n[[scenes]]\nid = "ball"\nmodel = "{URDF}"\n'
                     f'q0 = {{ shoulder = [0.3, 0.1, 0.2, 0.9], elbow = 40 }}\n'
                     f'v0 = {{ shoulder = [1.0, -0.5, 2.0], wrist = [0, 0, 3] }}\n'
                     + "".join(f'[[engines]]\nid = "{e}"\n' for e in ("ours/projection-rk4", "mujoco/hinge-rk4",
                                                                      "drake/rk3", "pybullet", "dart/rk4")))
    code, _, err = run_cli(capsys, "run", suite, "--output", tmp_path / "run", "--jobs", "1")
    assert code == 0, err
    code, shown, err = run_cli(capsys, "show", tmp_path / "run", "--format", "json")
    rows = {r["engine"]: r for r in json.loads(shown)}
    bounds = {"ours/projection-rk4": 1e-9, "mujoco/hinge-rk4": 1e-9, "drake/rk3": 1e-6, "pybullet/multibody": 1e-2}
    assert {name: r["status"] for name, r in rows.items()} == {**{name: "ok" for name in bounds}, "dart/rk4": "skipped"}
    assert all(rows[name]["position_error_linf"] <= bound for name, bound in bounds.items()), rows
    assert rows["dart/rk4"]["message"] == ("dart: its URDF reader (urdfdom) has no spherical joint (shoulder, wrist); "
                                           "DART steps ball joints from an MJCF")


def test_a_difference_nothing_explains_names_the_joint_of_its_velocity_entry():
    """The diagnosis's last resort names the joint and link of the velocity entry that differs most: a ball's
    three entries are its joint's, the entries after it the next joints'."""
    from compare.model.diagnosis import unexplained

    _, model = read_description(str(URDF))
    assert [unexplained(model, "mass_matrix", row) for row in (2, 3, 6)] == [
        f"cause not found: largest difference at joint {joint}, link {link} (in M)"
        for joint, link in (("shoulder", "upper"), ("elbow", "lower"), ("wrist", "hand"))]


def test_a_free_chain_of_ball_joints_holds_its_momentum_in_zero_gravity():
    """The URDF chain with a floating base (`base = "floating"`) in g = 0: the total linear and angular momentum
    hold to ≤ 1e-10 over 1 s in the reference and in ours' and MuJoCo's RK4 at dt 1e-3, which follow the
    reference to ≤ 1e-9 m (Drake's RK3 to ≤ 1e-6 m); PyBullet says in one line that it does not map a floating
    base with spherical joints."""
    from engines.errors import Unsupported
    from engines.model.scene import model_scene
    from engines.reference.reference import ENGINE as REFERENCE
    from engines.registry import resolve

    scene = model_scene("free", str(URDF), q0={"shoulder": [0.3, 0.1, 0.2, 0.9], "elbow": 40, "wrist": [0, 0.3, 0, 1]},
                        v0={"shoulder": [1.0, -0.5, 2.0], "elbow": -1.0, "wrist": [0, 0, 3]}, duration=1.0, g=0.0,
                        root_joint="floating")
    assert scene.conserved_momenta() == ("px", "py", "pz", "Lx", "Ly", "Lz")
    reference = REFERENCE.simulate(scene, 1e-3)
    assert scene.momentum_drift(*scene.split(reference.joint_states)) <= 1e-10
    for engine_id, bound in (("ours/projection-rk4", 1e-9), ("mujoco/hinge-rk4", 1e-9), ("drake/rk3", 1e-6)):
        engine, variant = resolve(engine_id)
        run = engine.simulate(scene, 1e-3, variant=variant)
        assert np.abs(run.positions - reference.positions).max() <= bound, engine_id
        if bound < 1e-6:
            assert scene.momentum_drift(*scene.split(run.joint_states)) <= 1e-10, engine_id
    engine, variant = resolve("pybullet")
    with pytest.raises(Unsupported, match=r"^pybullet: ball joints \(shoulder, wrist\) are stepped from a URDF's"):
        engine.check(scene, variant)
