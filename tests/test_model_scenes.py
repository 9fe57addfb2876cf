"""Model files as scenes: the Pinocchio reference against the compound double pendulum's closed forms, every
engine that steps models against it and against each other, the CLI, the suite reader, and refusals.

Numbers in comments were measured with mujoco 4.0.0, pybullet 3.2.7, drake 1.51.1, dartpy 6.20.0 and
pin 4.1.0 (``.venv/bin/python -m pytest tests/test_model_scenes.py -q -p no:xdist``).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from compare.suite.reader import parse_suite
from engines.errors import Unsupported, UserError
from engines.model.scene import model_scene
from engines.reference.reference import ENGINE as REFERENCE, solve, solve_and_bound
from engines.registry import resolve
from engines.scene.trajectory import trajectory_energy

from cli_support import run_cli

ROOT = Path(__file__).resolve().parent.parent
DOUBLE = str(ROOT / "models" / "double_pendulum.urdf")
G = 9.81


def normal_modes() -> tuple[np.ndarray, np.ndarray]:
    """The fixture's linearised modes about hanging, from its stated geometry (not from the file's numbers):
    (ω (2,) rad/s ascending, shapes (2, 2) columns). Rods of radius 0.02 m: I = m (3 r² + l²) / 12."""
    m1, l1, c1, m2, l2, c2, r = 1.0, 1.0, 0.5, 2.0, 0.8, 0.4, 0.02
    i1, i2 = m1 * (3 * r * r + l1 * l1) / 12, m2 * (3 * r * r + l2 * l2) / 12
    a = i1 + m1 * c1**2 + i2 + m2 * (l1 + c2) ** 2
    b = i2 + m2 * (c2**2 + l1 * c2)
    d = i2 + m2 * c2**2
    mass = np.array([[a, b], [b, d]])
    stiffness = G * np.array([[m1 * c1 + m2 * (l1 + c2), m2 * c2], [m2 * c2, m2 * c2]])
    values, vectors = np.linalg.eig(np.linalg.solve(mass, stiffness))
    order = np.argsort(values)
    return np.sqrt(values[order].real), vectors[:, order].real


@pytest.mark.parametrize("mode", [0, 1])
def test_reference_oscillates_at_the_linearised_frequencies(mode):
    # Released at rest in one normal mode with amplitude 1e-4 rad, the reference must follow
    # ε·u·cos(ωt) to within 1e-6 of ε over two periods (the nonlinear terms are O(ε²) ≈ 1e-8 of it).
    omega, shapes = normal_modes()
    amplitude = 1e-4
    q0 = amplitude * shapes[:, mode] / np.abs(shapes[:, mode]).max()
    period = 2 * math.pi / omega[mode]
    scene = model_scene("modes", DOUBLE, q0={"shoulder": math.degrees(q0[0]), "elbow": math.degrees(q0[1])},
                        duration=2 * period)
    times = np.linspace(0, 2 * period, 401)
    states = solve(scene, 1e-12, 1e-14).ode(times).T
    expected = np.outer(np.cos(omega[mode] * times), q0)
    assert np.abs(states[:, :2] - expected).max() < 1e-6 * amplitude


def test_reference_conserves_energy_and_bounds_itself():
    # A large swing (90°, −45°) over 2 s at rtol = atol = 1e-12: |E − E0| ≤ 1e-10 E* (measured 2e-13);
    # solved twice, the two solutions agree to far below the reference's 1e-9 L.
    scene = model_scene("swing", DOUBLE, q0={"shoulder": 90, "elbow": -45}, duration=2.0)
    run = REFERENCE.simulate(scene, 1e-2)
    energy = trajectory_energy(scene, run)
    assert np.abs(energy - energy[0]).max() <= 1e-10 * scene.characteristic_energy
    _, bound = solve_and_bound(scene, 1e-12, 1e-12)
    assert bound.reference_error < 1e-9 * scene.characteristic_length
    assert bound.reference_horizon is None


def test_model_scene_reads_degrees_and_names_the_links():
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30}, v0={"elbow": 1.5})
    assert scene.joint_names == ("shoulder", "elbow") and scene.frames == ("rod1", "rod2")
    assert scene.initial_q == pytest.approx([math.radians(30), 0.0]) and scene.initial_v == pytest.approx([0.0, 1.5])
    # rod2's frame is at the elbow, 1 m down rod1 (turned 30° about +y: toward −x).
    assert scene.initial_positions[1] == pytest.approx([-0.5, 0.0, -math.sqrt(3) / 2])
    assert scene.characteristic_length == pytest.approx(1.4)  # 1 m to the elbow, 0.4 m to rod2's COM


# -- engines ----------------------------------------------------------------------------------------------

EULER = ("mujoco/hinge", "pybullet/multibody", "drake/semi-explicit-euler", "dart/world")


def test_semi_implicit_euler_engines_step_the_same_model_alike():
    # The four step the file's tree with the same scheme (v += dt·a(q, v), then q += dt·v): to round-off
    # (measured below 1e-14 m over 2 s at dt = 1e-3), and 1.9e-3 m off the reference.
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20})
    reference = REFERENCE.simulate(scene, 1e-3)
    runs = {}
    for engine_id in EULER:
        engine, variant = resolve(engine_id)
        runs[engine_id] = engine.simulate(scene, 1e-3, variant=variant)
        assert runs[engine_id].info.status == "ok" and runs[engine_id].joint_states.shape == (201, 4)
    first = runs[EULER[0]]
    for engine_id in EULER[1:]:
        assert np.abs(runs[engine_id].positions - first.positions).max() < 1e-12, engine_id
    assert 1e-3 < np.linalg.norm(first.positions - reference.positions, axis=2).max() < 3e-3


@pytest.mark.parametrize("engine_id, options, bound", [
    ("mujoco/hinge-rk4", {}, 1e-9),  # measured 5.8e-11 m
    ("dart/rk4", {}, 1e-9),  # measured 5.8e-11 m
    ("drake/rk5", {"error_control": False}, 1e-10),  # measured 1.1e-12 m
])
def test_higher_order_engines_agree_with_the_reference(engine_id, options, bound):
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20})
    engine, variant = resolve(engine_id)
    run = engine.simulate(scene, 1e-3, variant=variant, options=options)
    reference = REFERENCE.simulate(scene, 1e-3)
    assert np.linalg.norm(run.positions - reference.positions, axis=2).max() < bound


@pytest.mark.parametrize("engine_id, steps, order", [
    ("mujoco/hinge", (4e-3, 2e-3, 1e-3), 1),  # measured slope 1.000
    ("pybullet/multibody", (4e-3, 2e-3, 1e-3), 1),  # 1.000
    ("drake/rk2", (4e-3, 2e-3, 1e-3), 2),  # 1.99
    ("mujoco/hinge-rk4", (2e-2, 1e-2, 5e-3), 4),  # 3.94
    ("dart/rk4", (2e-2, 1e-2, 5e-3), 4),  # 3.94
])
def test_observed_order_on_the_model(engine_id, steps, order):
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20}, duration=1.0)
    engine, variant = resolve(engine_id)
    errors = []
    for dt in steps:
        run = engine.simulate(scene, dt, variant=variant)
        errors.append(np.linalg.norm(run.positions - REFERENCE.simulate(scene, dt).positions, axis=2).max())
    assert abs(np.polyfit(np.log(steps), np.log(errors), 1)[0] - order) < 0.15


def test_drake_error_control_follows_its_accuracy_on_the_model():
    # RK3 with error control: the 2 s error falls tenfold per decade of accuracy (measured 1.9e-7, 2.0e-9 m
    # at 1e-6, 1e-8), and the steps recorded are the integrator's own (1432, 6222), not the 200 samples.
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20})
    reference = REFERENCE.simulate(scene, 1e-2)
    engine, variant = resolve("drake/rk3")
    runs = [engine.simulate(scene, 1e-2, variant=variant, options={"accuracy": a}) for a in (1e-6, 1e-8)]
    errors = [np.linalg.norm(r.positions - reference.positions, axis=2).max() for r in runs]
    assert errors[0] < 1e-6 and errors[0] / errors[1] > 30
    assert 200 < runs[0].info.steps < runs[1].info.steps


def test_pybullet_joint_limits_are_off():
    # KUKA iiwa released at 30° and −45° swings past its joint limits within 0.5 s; PyBullet enforces the
    # URDF's limits whatever changeDynamics says unless the file's ranges are emptied. With them off it
    # steps what MuJoCo's Euler steps (measured 1.8e-14 rad at 0.5 s; with the limits, 21 rad/s off).
    scene = model_scene("kuka", "pybullet_data:kuka_iiwa/model.urdf",
                        q0={"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}, duration=0.5)
    runs = [engine.simulate(scene, 1e-3, variant=variant)
            for engine, variant in (resolve("mujoco/hinge"), resolve("pybullet/multibody"))]
    assert np.abs(runs[0].joint_states - runs[1].joint_states).max() < 1e-9
    assert "lower 1 > upper -1" in runs[1].info.settings["joint_limits"]


@pytest.mark.parametrize("engine_id, message", [
    ("pymunk", "pymunk does not load model files (URDF, MJCF): it runs the catalog's scenes only"),
    ("ours/rattle", "ours: RATTLE is not offered for rigid bodies"),
    ("ours/lagrangian-rk4", "ours: method 'lagrangian' (reduced coordinates of a planar particle chain) does not apply"),
    ("mujoco/connect", "mujoco: a model file is compiled in joint coordinates"),
    ("pybullet/p2p", "pybullet: a model file is loaded as one multibody"),
    ("drake/discrete", "drake/discrete: a model file is loaded into a continuous plant"),
])
def test_engines_that_cannot_step_models_say_why(engine_id, message):
    engine, variant = resolve(engine_id)
    with pytest.raises(Unsupported, match=re.escape(message)):
        engine.check(model_scene("dp", DOUBLE), variant)


def test_bad_initial_state_names_the_joint():
    with pytest.raises(UserError, match="q0 names joint 'knee', which is not one of its moving joints: shoulder, elbow"):
        model_scene("dp", DOUBLE, q0={"knee": 3})
    with pytest.raises(UserError, match="v0.elbow must be a finite number of rad/s, got 'fast'"):
        model_scene("dp", DOUBLE, v0={"elbow": "fast"})


# -- CLI and suites ---------------------------------------------------------------------------------------


def test_simulate_writes_si_columns_and_score_reads_them(tmp_path, capsys):
    out = tmp_path / "dp.csv"
    code, _, err = run_cli(capsys, "simulate", "--model", DOUBLE, "--engine", "mujoco/hinge-rk4", "--dt", "1e-3",
                           "--param", "q0.shoulder=30", "--param", "v0.elbow=1", "--output", out)
    assert code == 0, err
    header, first = out.read_text().splitlines()[:2]
    assert header == ("t,q_shoulder,q_elbow,v_shoulder,v_elbow,rod1_x,rod1_y,rod1_z,rod2_x,rod2_y,rod2_z,energy")
    values = [float(x) for x in first.split(",")]
    assert values[1] == pytest.approx(math.radians(30)) and values[4] == 1.0  # radians and rad/s
    code, scored, err = run_cli(capsys, "score", "--model", DOUBLE, out, "--param", "q0.shoulder=30",
                                "--param", "v0.elbow=1", "--format", "json")
    assert code == 0, err
    assert '"status": "ok"' in scored
    code, _, err = run_cli(capsys, "simulate", "--model", DOUBLE, "--dt", "1e-3", "--param", "theta=3", "--output", out)
    assert code == 2 and "--param theta: a model takes q0.JOINT=VALUE" in err


def test_suite_reads_a_model_scene_relative_to_the_suite(tmp_path):
    text = """
dt = [1e-3]
[[scenes]]
id = "dp"
model = "../models/double_pendulum.urdf"
q0 = { shoulder = 30 }
[[engines]]
id = "dart/world"
"""
    suite = parse_suite(text, str(ROOT / "suites" / "inline.toml"))
    [spec] = suite.scenes
    assert spec.id == "dp" and spec.scene.initial_q[0] == pytest.approx(math.radians(30))
    with pytest.raises(UserError, match=r"scenes\[0\]\.model.*q0 names joint 'hip'"):
        parse_suite(text.replace("shoulder = 30", "hip = 1"), str(ROOT / "suites" / "inline.toml"))


# -- the file's joint damping --------------------------------------------------------------------------------


def damped_copy(tmp_path: Path, dynamics: str) -> str:
    """The double pendulum fixture with ``dynamics`` (a <dynamics …/> element) on both joints."""
    text = Path(DOUBLE).read_text().replace('<axis xyz="0 1 0"/>', f'<axis xyz="0 1 0"/>{dynamics}')
    path = tmp_path / "damped.urdf"
    path.write_text(text)
    return str(path)


def test_file_damping_is_set_to_0_unless_kept(tmp_path):
    # Damping 0.3 N·m·s/rad on both joints. neutral: the reference keeps its energy and the engines
    # record what they zeroed. keep: the reference loses 2.3 % of E* in 2 s, RK4 in MuJoCo and DART
    # follows it (measured 9.6e-12 m), and DART's World.step equals MuJoCo's Euler (both implicit in damping).
    model = damped_copy(tmp_path, '<dynamics damping="0.3"/>')
    neutral = model_scene("dd", model, q0={"shoulder": 30, "elbow": -20})
    energy = trajectory_energy(neutral, REFERENCE.simulate(neutral, 1e-2))
    assert abs(energy[-1] - energy[0]) < 1e-10 * neutral.characteristic_energy
    engine, variant = resolve("mujoco/hinge-rk4")
    settings = engine.simulate(neutral, 1e-3, variant=variant).info.settings
    assert settings["file_damping_friction"] == {"shoulder": {"damping": 0.3, "friction": 0.0},
                                                 "elbow": {"damping": 0.3, "friction": 0.0}}
    kept = model_scene("dd", model, q0={"shoulder": 30, "elbow": -20}, file_dynamics="keep")
    reference = REFERENCE.simulate(kept, 1e-3)
    energy = trajectory_energy(kept, reference)
    assert energy[-1] - energy[0] < -1e-2 * kept.characteristic_energy
    runs = {}
    for engine_id in ("mujoco/hinge-rk4", "dart/rk4", "mujoco/hinge", "dart/world"):
        engine, variant = resolve(engine_id)
        runs[engine_id] = engine.simulate(kept, 1e-3, variant=variant)
    for engine_id in ("mujoco/hinge-rk4", "dart/rk4"):
        assert np.linalg.norm(runs[engine_id].positions - reference.positions, axis=2).max() < 1e-10
    assert np.abs(runs["mujoco/hinge"].positions - runs["dart/world"].positions).max() < 1e-12
    for engine_id in ("drake/rk2", "pybullet/multibody"):
        engine, variant = resolve(engine_id)
        with pytest.raises(Unsupported, match='file_dynamics = "keep" is not supported here'):
            engine.check(kept, variant)
    with pytest.raises(UserError, match='"keep" with joint friction \\(shoulder, elbow\\): the reference has no'):
        model_scene("df", damped_copy(tmp_path, '<dynamics damping="0.3" friction="0.1"/>'), file_dynamics="keep")


def _run_no_inertial(tmp_path, capsys, duration: float, q0: str = "") -> tuple[str, Path]:
    """`xval run` of the no-<inertial> pitfall as scene "bare" on mujoco/hinge; its model path and run dir."""
    model = str(ROOT / "models" / "pitfalls" / "no_inertial.urdf")
    suite = tmp_path / "suite.toml"
    suite.write_text(f'duration = {duration}\ndt = [1e-2]\n[[scenes]]\nid = "bare"\nmodel = "{model}"\n'
                     f'{q0}[[engines]]\nid = "mujoco/hinge"\n')
    out = tmp_path / "run"
    code, _, err = run_cli(capsys, "run", suite, "--output", out, "--jobs", "1")
    assert code == 0, err
    return model, out


def test_report_shows_a_model_scene_with_its_parity_table(tmp_path, capsys):
    # A run of the no-<inertial> pitfall and its `xval model check` JSON in DIR/model_check/: the report's
    # parity table colours PyBullet's and DART's differences (1 kg given to the link) "far", MuJoCo's "agree".
    model, out = _run_no_inertial(tmp_path, capsys, duration=0.2, q0="q0 = { shoulder = 20 }\n")
    code, check, err = run_cli(capsys, "model", "check", model, "--format", "json", "--states", "5")
    assert code == 1, err  # PyBullet and DART disagree
    (out / "model_check").mkdir()
    (out / "model_check" / "bare.json").write_text(check)
    code, _, err = run_cli(capsys, "report", out)
    assert code == 0, err
    page = (out / "report.html").read_text()
    assert "model file " + model in page and "Dynamics parity of the import (model_check/bare.json)" in page
    rows = {engine: page.split(f"<tr><td>{engine} ")[1].split("</tr>")[0] for engine in ("mujoco", "pybullet", "dart")}
    assert rows["mujoco"].count("parity-agree") == 3
    assert rows["pybullet"].count("parity-far") == 3 and "pybullet gives it 1 kg" in rows["pybullet"]
    assert rows["dart"].count("parity-far") == 3


def test_ours_steps_a_model_in_maximal_coordinates_as_mujoco_does_in_joint_coordinates():
    """ours' rigid bodies (engines/ours/model.py) and MuJoCo's hinges, both RK4 at 1 ms over 1 s: the joint
    states agree to 1e-9 (each method's own error is ~1e-10 here), and projection keeps the joints shut."""
    scene = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20}, duration=1.0)
    runs = {eid: resolve(eid)[0].simulate(scene, 1e-3, variant=resolve(eid)[1])
            for eid in ("mujoco/hinge-rk4", "ours/projection-rk4", "ours/baumgarte-rk4")}
    for eid in ("ours/projection-rk4", "ours/baumgarte-rk4"):
        assert np.abs(runs[eid].joint_states - runs["mujoco/hinge-rk4"].joint_states).max() < 1e-9
        assert np.abs(runs[eid].positions - runs["mujoco/hinge-rk4"].positions).max() < 1e-9
    assert runs["ours/projection-rk4"].info.settings["method"] == "projection"


def test_report_runs_the_parity_check_itself_when_the_run_has_none(tmp_path, capsys):
    # No model_check/ JSON in the run: `xval report` checks the scene's file itself, writes the JSON beside the
    # cases (so the next report reads it) and shows the table, PyBullet flagged for the 1 kg it gives the link.
    model, out = _run_no_inertial(tmp_path, capsys, duration=0.1)
    code, _, err = run_cli(capsys, "report", out)
    assert code == 0, err
    written = json.loads((out / "model_check" / "bare.json").read_text())
    assert {e["engine"]: e["agrees"] for e in written["engines"]}["pybullet"] is False
    page = (out / "report.html").read_text()
    assert "Dynamics parity of the import (model_check/bare.json)" in page and "No parity table" not in page
    row = page.split("<tr><td>pybullet ")[1].split("</tr>")[0]
    assert row.count("parity-far") == 3 and "pybullet gives it 1 kg" in row


def test_in_zero_gravity_the_pivot_momentum_holds_and_a_still_arm_stays_put(tmp_path, capsys):
    """g = 0 (``--param g=0``, a suite's ``parameters = { g = 0 }``): nothing acts about the pivot axis, so the
    shoulder's generalised momentum (M v)₀ (the angular momentum about that axis) holds: to ≤ 1e-10 relative
    over 1 s in the reference and in the RK4 variants of MuJoCo and ours at dt 1e-3; an arm at rest stays."""
    from compare.model.parity import read_description
    from engines.model.importers import importer

    path = DOUBLE
    scene = model_scene("dp0", path, q0={"shoulder": 30, "elbow": -45}, v0={"shoulder": 2.0, "elbow": -1.0},
                        duration=1.0, g=0)
    assert scene.gravity == (0.0, 0.0, 0.0) and scene.parameters["g"] == 0.0
    mass = importer("pinocchio").load(*read_description(path)).mass_matrix

    def drift(run) -> float:
        q, v = run.joint_states[:, :2], run.joint_states[:, 2:]
        momentum = np.array([(mass(qk) @ vk)[0] for qk, vk in zip(q, v)])
        exported = scene.momentum_drift(q, v)  # the metric momentum_drift, relative to M·L·√(g·L)
        assert exported is not None and exported <= 1e-10
        return float(np.abs(momentum - momentum[0]).max() / abs(momentum[0]))

    assert scene.conserved_joints() == ("shoulder",)
    assert model_scene("dp", path).conserved_joints() == ()  # a horizontal pivot axis under gravity

    assert drift(REFERENCE.simulate(scene, 1e-3)) <= 1e-10
    for engine_id in ("mujoco/hinge-rk4", "ours/projection-rk4"):
        engine, variant = resolve(engine_id)
        assert drift(engine.simulate(scene, 1e-3, variant=variant)) <= 1e-10, engine_id
    still = model_scene("dp1", path, q0={"shoulder": 30}, duration=0.2, g=0)
    engine, variant = resolve("mujoco/hinge-rk4")
    assert np.abs(engine.simulate(still, 1e-3, variant=variant).joint_states[:, 0] - math.radians(30)).max() == 0.0
    suite = f'dt = [1e-2]\n[[scenes]]\nmodel = "{path}"\nparameters = {{ g = 0 }}\n[[engines]]\nid = "mujoco/hinge"\n'
    assert parse_suite(suite, str(tmp_path / "s.toml")).scenes[0].scene.g == 0.0
    with pytest.raises(UserError, match=r"g must be a finite number of m/s² ≥ 0 \(along −z\), got -1"):
        model_scene("bad", path, g=-1)


def test_a_locked_joint_is_welded_at_its_initial_value_in_every_engine(tmp_path):
    """lock = ["elbow"] at q0 = 30°: the locked scene's link frames are the free model's at elbow = 30° (the
    weld folded into the file's origin); the Panda without its fingers steps in DART (whose import of the Panda
    agrees with the reference's; MuJoCo's does not, docs/models.md) as in the reference, and no unbounded joint
    is left to name."""
    from engines.model.stepping import unbounded_joints

    free = model_scene("dp", DOUBLE, q0={"shoulder": 10, "elbow": 30})
    locked = model_scene("dpl", DOUBLE, q0={"shoulder": 10, "elbow": 30}, lock=["elbow"])
    assert locked.joint_names == ("shoulder",) and locked.lock == (("elbow", pytest.approx(math.radians(30))),)
    for shoulder in (0.2, -1.1):
        np.testing.assert_allclose(locked.frame_states(np.array([[shoulder]]), np.zeros((1, 1)))[0][0, -1],
                                   free.frame_states(np.array([[shoulder, math.radians(30)]]), np.zeros((1, 2)))[0][0, -1],
                                   atol=1e-12)
    panda = model_scene("arm", "pybullet_data:franka_panda/panda.urdf", duration=0.2,
                        lock=["panda_finger_joint1", "panda_finger_joint2"])
    assert len(panda.joint_names) == 7 and unbounded_joints(panda) == []
    engine, variant = resolve("dart/rk4")
    run = engine.simulate(panda, 1e-3, variant=variant)
    reference = REFERENCE.simulate(panda, 1e-3)
    assert np.linalg.norm(run.positions - reference.positions, axis=2).max() < 1e-6
    assert any("welded at their initial value (lock)" in note for note in run.info.settings["import_notes"])
    with pytest.raises(UserError, match=r"lock names joint 'wrist', which is not one of its moving joints"):
        model_scene("bad", DOUBLE, lock=["wrist"])
    suite = f'dt = [1e-2]\n[[scenes]]\nmodel = "{DOUBLE}"\nlock = ["elbow"]\n[[engines]]\nid = "mujoco/hinge"\n'
    assert parse_suite(suite, str(tmp_path / "s.toml")).scenes[0].scene.joint_names == ("shoulder",)
