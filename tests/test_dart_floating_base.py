"""DART steps floating-base model scenes: its FreeJoint's (rotation vector, position; R ω, R v) mapped to xval's
convention (docs/models.md, "Floating bases") at every sample, ``dart/world`` in DART's own coordinates and
``dart/rk4`` in xval's (the quaternion's rate ½ q ⊗ ω, as the reference's). In g = 0 with the legs swinging the
total momentum holds; with gravity the trajectory converges to the reference's at the integrator's order.

Numbers in comments were measured with dartpy 6.20.0 and pin 4.1.0
(``.venv/bin/python -m pytest tests/test_dart_floating_base.py -q -n 0``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engines.model.scene import model_scene
from engines.reference.reference import ENGINE as REFERENCE
from engines.registry import resolve

FIXTURES = Path(__file__).resolve().parent / "fixtures"
URDF = FIXTURES / "urdf" / "quadruped.urdf"
MJCF = FIXTURES / "mjcf" / "quadruped.xml"
LEGS = [f"{leg}_{part}" for leg in ("fl", "fr", "bl", "br") for part in ("hip", "knee")]


def free_quadruped(g: float, duration: float, base_v=(0.1, 0.0, 0.2, 0.0, 0.5, 0.3)):
    """The URDF quadruped with ``--base floating`` (DART's import agrees with the reference's on it): the base
    off the origin, turned and moving at ``base_v`` (m/s, rad/s in its frame), the legs swinging."""
    q0 = {name: 20.0 * (-1) ** k for k, name in enumerate(LEGS)}
    v0 = {name: (3.0 if name.endswith("hip") else -4.0) * (1 + 0.3 * (k // 2)) for k, name in enumerate(LEGS)}
    return model_scene("free", str(URDF), q0={**q0, "__floating_base__": [0.1, -0.2, 0.6, 0.1, 0.2, 0.05, 0.97]},
                       v0={**v0, "__floating_base__": list(base_v)}, duration=duration, g=g,
                       root_joint="floating")


def run_suite(tmp_path: Path, capsys, scene: str, engines: tuple[str, ...]) -> Path:
    """`xval run` of one scene (``scene``: its TOML lines after ``id``) for 0.2 s at dt 1e-3 in ``engines``; the run dir."""
    from cli_support import run_cli

    suite = tmp_path / "suite.toml"
    suite.write_text('duration = 0.2\ndt = [1e-3]\n[[scenes]]\nid = "free"\n' + scene
                     + "".join(f'[[engines]]\nid = "{e}"\n' for e in engines))
    code, _, err = run_cli(capsys, "run", suite, "--output", tmp_path / "run", "--jobs", "1")
    assert code == 0, err
    return tmp_path / "run"


def simulate(engine_id: str, scene, dt: float):
    engine, variant = resolve(engine_id)
    return engine.simulate(scene, dt, variant=variant)


def test_in_zero_gravity_dart_holds_the_total_momentum_and_the_base_answers_the_legs():
    """g = 0 over 1 s: dart/rk4 at dt 1e-3 holds the total linear and angular momentum (momentum_drift,
    docs/metrics.md) to ≤ 1e-10 (measured 1.6e-12) and follows the reference to 1e-9·L (7.8e-12 m); the base, at
    rest at t = 0, moves and turns (0.18 rad) as the legs swing. dart/world (semi-implicit Euler in DART's coordinates, which does not
    conserve momentum exactly) drifts at first order: ≤ 1e-3 at dt 1e-3 (measured 1.8e-4), half that at
    dt 5e-4."""
    scene = free_quadruped(g=0.0, duration=1.0, base_v=(0.0,) * 6)
    assert scene.conserved_momenta() == ("px", "py", "pz", "Lx", "Ly", "Lz")
    reference = REFERENCE.simulate(scene, 1e-3)
    run = simulate("dart/rk4", scene, 1e-3)
    q, v = scene.split(run.joint_states)
    assert q.shape == (101, 15) and v.shape == (101, 14)
    assert np.all(np.isfinite(run.joint_states))
    assert scene.momentum_drift(q, v) <= 1e-10
    assert np.abs(run.positions - reference.positions).max() <= 1e-9 * scene.characteristic_length
    assert np.abs(v[0, :6]).max() == 0 and np.abs(v[-1, :6]).max() > 0.05  # the base answers the legs
    assert (Rotation.from_quat(q[-1, 3:7]) * Rotation.from_quat(q[0, 3:7]).inv()).magnitude() > 0.01
    drifts = [scene.momentum_drift(*scene.split(simulate("dart/world", scene, dt).joint_states)) for dt in (1e-3, 5e-4)]
    assert drifts[0] <= 1e-3 and 1.8 < drifts[0] / drifts[1] < 2.2, drifts


@pytest.mark.parametrize("engine_id, steps, order", [
    ("dart/rk4", (2e-3, 1e-3), 4),  # errors 5.0e-11, 3.2e-12 m: slope 3.98
    ("dart/world", (2e-3, 1e-3, 5e-4), 1),  # 6.1e-3, 3.0e-3, 1.5e-3 m: slope 1.00
])
def test_with_gravity_dart_converges_to_the_reference_at_its_integrators_order(engine_id, steps, order):
    """g = 9.81 over 0.5 s, the base falling and turning: the largest link-frame distance from the reference
    (sampled on the same schedule) falls as dtᵒʳᵈᵉʳ."""
    scene = free_quadruped(g=9.81, duration=0.5)
    errors = [np.linalg.norm(simulate(engine_id, scene, dt).positions - REFERENCE.simulate(scene, dt).positions,
                             axis=2).max() for dt in steps]
    assert abs(np.polyfit(np.log(steps), np.log(errors), 1)[0] - order) < 0.15, errors


def test_the_minitaur_with_a_floating_base_steps_in_dart_as_in_the_reference():
    """pybullet_data's minitaur (16 moving joints) with ``--base floating``, g = 0, eight joints swinging: dart/rk4
    at dt 1e-3 is the reference to its own error (7.9e-12 m, the same at dt 5e-4, as MuJoCo's RK4) and holds the
    momentum (4.8e-15)."""
    names = [n for n in model_scene("m", "pybullet_data:quadruped/minitaur.urdf", root_joint="floating").joint_names
             if n != "__floating_base__"]
    scene = model_scene("m", "pybullet_data:quadruped/minitaur.urdf", v0={n: 2.0 * (-1) ** k for k, n in
                                                                           enumerate(names[:8])},
                        duration=0.5, g=0.0, root_joint="floating")
    run = simulate("dart/rk4", scene, 1e-3)
    assert np.abs(run.positions - REFERENCE.simulate(scene, 1e-3).positions).max() <= 1e-9 * scene.characteristic_length
    assert scene.momentum_drift(*scene.split(run.joint_states)) <= 1e-10


def test_an_mjcf_free_joint_steps_in_dart_as_the_reference_once_its_bodies_have_the_files_inertias():
    """DART's MJCF parser ignores <inertial> (its import disagrees, and the check says so); given the file's
    masses and inertias, its skeleton stepped from the same start (the FreeJoint's frames made the body's,
    engines/dart/model.py) follows the reference to 1e-9·L and holds the momentum to 1e-10 at RK4, dt 1e-3: the
    free joint and its mapping are right, only the import's inertias differ. As parsed, it is 0.36 m off."""
    import dartpy

    from engines.adapter import Schedule
    from engines.dart.model import DartStepper
    from engines.model.stepping import run_model

    scene = model_scene("quadruped", str(MJCF), q0={"root": [0.1, -0.2, 0.6, 0.1, 0.2, 0.05, 0.97],
                                                   **{n: 20.0 * (-1) ** k for k, n in enumerate(LEGS)}},
                        v0={"root": [0.0, 0.1, 0.0, 0.3, 0.0, -0.2], "fl_hip": 3.0, "br_knee": -4.0},
                        duration=0.5, g=0.0)
    reference = REFERENCE.simulate(scene, 1e-3)
    as_parsed = simulate("dart/rk4", scene, 1e-3)
    assert np.abs(as_parsed.positions - reference.positions).max() > 1e-2
    schedule = Schedule.make(scene.duration, 1e-3)
    stepper = DartStepper(scene, 1e-3, "rk4")
    inertials = {body.name: body.inertial for body in scene.description.bodies}
    for k in range(stepper.skeleton.getNumBodyNodes()):
        node = stepper.skeleton.getBodyNode(k)
        inertial = inertials[node.getName()]
        node.setInertia(dartpy.dynamics.Inertia(inertial.mass, np.asarray(inertial.com), inertial.inertia_matrix))
    start_q, start_v = stepper.state()
    assert np.allclose(start_q[:3], [0.1, -0.2, 0.6]) and np.allclose(start_v[:6], [0.0, 0.1, 0.0, 0.3, 0.0, -0.2])
    assert Rotation.from_quat(start_q[3:7]).approx_equal(Rotation.from_quat([0.1, 0.2, 0.05, 0.97]), atol=1e-12)
    run = run_model(scene, schedule, stepper)
    assert np.abs(run.positions - reference.positions).max() <= 1e-9 * scene.characteristic_length
    assert scene.momentum_drift(*scene.split(run.joint_states)) <= 1e-10


def test_the_verdict_of_an_mjcf_free_joint_scene_leads_with_darts_import(tmp_path, capsys):
    """DART runs the MJCF quadruped (no longer refused); its import ignores <inertial>, so the scene's verdict in
    the report says first that DART disagrees with the model reference on the file, naming the links, and that
    its error reflects the import, not the stepping; MuJoCo, which agrees, is not named."""
    from cli_support import run_cli

    out = run_suite(tmp_path, capsys, f'model = "{MJCF}"\nparameters = {{ g = 0 }}\nv0 = {{ fl_hip = 3, br_knee = -2 }}\n',
                    ("dart/rk4", "mujoco/hinge-rk4"))
    code, _, err = run_cli(capsys, "report", out)
    assert code == 0, err
    article = (out / "report.html").read_text().split('<article class="verdict-scene"')[1].split("</article>")[0]
    lead = article.split('<div class="import-lead">')[1].split("</div>")[0]
    assert "<strong>dart</strong> disagrees with pinocchio" in lead and "torso" in lead, lead
    assert "its error below reflects the import, not the stepping" in lead and "mujoco" not in lead
    assert article.index('class="import-lead"') < article.index('class="answer"')


def test_a_suite_runs_a_floating_urdf_in_dart_and_exports_its_momentum_drift(tmp_path, capsys):
    """`base = "floating"`, g = 0, through `xval run` and `xval show`: both DART variants ok, momentum_drift exported
    (dart/rk4 ≤ 1e-10 and on the reference to 1e-9 m; dart/world, first order, ≤ 1e-3)."""
    import json

    from cli_support import run_cli

    out = run_suite(tmp_path, capsys, f'model = "{URDF}"\nbase = "floating"\nparameters = {{ g = 0 }}\n'
                    'v0 = { fl_hip = 3, br_knee = -2, __floating_base__ = [0.1, 0, 0, 0, 0.5, 0] }\n',
                    ("dart/rk4", "dart/world"))
    code, shown, err = run_cli(capsys, "show", out, "--format", "json")
    rows = {r["engine"]: r for r in json.loads(shown)}
    assert {name: r["status"] for name, r in rows.items()} == {"dart/rk4": "ok", "dart/world": "ok"}
    assert rows["dart/rk4"]["momentum_drift"] <= 1e-10 and rows["dart/rk4"]["position_error_linf"] <= 1e-9, rows
    assert 1e-10 < rows["dart/world"]["momentum_drift"] <= 1e-3, rows


def test_the_base_quaternion_read_from_dart_stays_continuous_past_half_a_turn():
    """DART keeps the FreeJoint's turn as a rotation vector, which wraps at π: read back as a quaternion it would
    flip to −q there, a jump in the base's q columns though the body turned smoothly. Spun at 8 rad/s for 1 s
    (past 2π) in g = 0, every sample's base quaternion is the nearer of ±q to the one before, and follows the
    reference's (which integrates q itself) to first order."""
    scene = free_quadruped(0.0, 1.0, base_v=(0.0, 0.0, 0.0, 0.0, 0.0, 8.0))
    q, _ = scene.split(simulate("dart/world", scene, 1e-3).joint_states)
    reference, _ = scene.split(REFERENCE.simulate(scene, 1e-3).joint_states)
    quaternion = slice(3, 7)  # the base's x y z w, after its position
    steps = np.einsum("ij,ij->i", q[1:, quaternion], q[:-1, quaternion])
    assert steps.min() > 0.9
    assert np.abs(q[:, quaternion] - reference[:, quaternion]).max() < 0.1
