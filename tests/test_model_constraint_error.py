"""The constraint error of a model scene: ours' joints (maximal coordinates) come apart and say by how much,
through RawRun → Trajectory → the runner → the ``constraint_error`` metric; MuJoCo's hinges (joint
coordinates) hold by construction and report nothing. On the compound double pendulum fixture."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from compare.results.measure import apply_bounds, truncate as _truncate
from compare.results.metrics import Bounds, case_metrics
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from engines.adapter import Schedule
from engines.model.scene import model_scene
from engines.ours.adapter import OursEngine
from engines.registry import resolve
from engines.scene.trajectory import trajectory_constraint_error

ROOT = Path(__file__).resolve().parent.parent
DOUBLE = str(ROOT / "models" / "double_pendulum.urdf")
SCENE = model_scene("dp", DOUBLE, q0={"shoulder": 30, "elbow": -20}, duration=1.0)
DTS = (4e-3, 2e-3, 1e-3)


def _run(engine_id: str, dt: float, scene=SCENE):
    engine, variant = resolve(engine_id)
    return engine.simulate(scene, dt, variant=variant)


@pytest.mark.parametrize("method", ["plain", "baumgarte"])
@pytest.mark.parametrize("integrator, order", [("rk4", 4), ("midpoint", 2), ("symplectic-euler", 1)])
def test_ours_joint_gap_falls_with_dt_at_the_integrators_order(method, integrator, order):
    """No cure, or Baumgarte's: the exact flow keeps C = 0, so C at the numerical state is of the order of the
    integrator's global error, O(dtᵖ) (plain rk4 over 1 s: 9.8e-9, 6.1e-10, 3.8e-11 m)."""
    errors = []
    for dt in DTS:
        run = _run(f"ours/{method}-{integrator}", dt)
        assert run.info.status == "ok" and run.constraint_violation.shape == (run.n_samples,)
        errors.append(trajectory_constraint_error(SCENE, run).max())
    slopes = np.log2(np.array(errors[:-1]) / errors[1:])
    assert errors[-1] > 1e-12 and np.all(np.abs(slopes - order) < 0.15), (errors, slopes)


@pytest.mark.parametrize("integrator", ["rk4", "symplectic-euler"])
def test_ours_projection_holds_the_joints_and_mujoco_reports_none(integrator):
    projected = _run(f"ours/projection-{integrator}", 1e-3)
    assert trajectory_constraint_error(SCENE, projected).max() <= 1e-10  # m
    hinge = _run("mujoco/hinge-rk4", 1e-3)
    assert hinge.constraint_violation is None and not trajectory_constraint_error(SCENE, hinge).any()


@pytest.mark.parametrize("model, q0", [
    ("pybullet_data:kuka_iiwa/model.urdf", {"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}),  # axes tilt
    (str(ROOT / "models" / "cart_pole.urdf"), {"hinge": 20}),  # a prismatic joint's slide
])
def test_the_reported_violation_is_the_size_of_what_the_link_frames_hide(model, q0):
    """The link frames compared are computed from ours' joint coordinates; the same links as ours' bodies
    carry them stand off by about the reported violation (measured 0.18 to 2.0 times it: anchor gaps count
    once per joint, misalignments at the full reach L), so the metric says how far the frames are wrong."""
    from engines.ours.model import OursStepper, link_origins

    scene = model_scene("drift", model, q0=q0, duration=1.0)
    stepper = OursStepper(scene, 1e-2, "plain", "rk4")
    ratios = []
    for _ in range(10):
        stepper.advance(10)
        q, v = stepper.state()
        by_joints = scene.frame_states(q[None], v[None])[0][0]
        by_bodies = link_origins(stepper.model, stepper.run.y, scene.frames)
        violation = stepper.constraint_violations()[-1]  # at the state just read
        assert violation > 1e-10  # m: RK4's drift at 10 ms, far above round-off
        ratios.append(np.linalg.norm(by_bodies - by_joints, axis=-1).max() / violation)
    assert 0.1 < min(ratios) and max(ratios) < 3.0, ratios


def test_the_runner_records_ours_joint_gap_and_zero_for_mujoco(tmp_path):
    text = """
duration = 0.5
dt = [2e-3]
timeout = 120
[[scenes]]
id = "dp"
model = "../models/double_pendulum.urdf"
q0 = { shoulder = 30, elbow = -20 }
[[engines]]
id = "ours/baumgarte-rk4"
[[engines]]
id = "ours/projection-rk4"
[[engines]]
id = "mujoco/hinge-rk4"
"""
    run_suite(parse_suite(text, str(ROOT / "suites" / "inline.toml")), tmp_path / "r", jobs=1)
    records = {r.case.engine: r for r in load_results(tmp_path / "r").records}
    assert {r.status.value for r in records.values()} == {"ok"}
    drifting = records["ours/baumgarte-rk4"].metrics["constraint_error"]
    assert 1e-12 < drifting < 1e-8  # m: 4th order at 2 ms (1.9e-10 m over 1 s)
    assert records["ours/projection-rk4"].metrics["constraint_error"] <= 1e-10
    assert records["mujoco/hinge-rk4"].metrics["constraint_error"] == 0.0  # the report's "0 (by construction)"


def test_joints_that_come_apart_make_an_ok_run_unstable():
    """Explicit Euler without a cure, 25 ms steps, the elbow whirling: the link frames (from the joint
    coordinates) look fine, the joints are metres apart: past the bound of 0.1 L."""
    scene = model_scene("whirl", DOUBLE, q0={"shoulder": 30, "elbow": -20}, v0={"elbow": 20}, duration=1.0)
    run = _run("ours/plain-euler", 2.5e-2, scene)
    assert run.info.status == "ok"
    times = Schedule.make(scene.duration, 2.5e-2).times
    metrics, series = case_metrics(scene, run, run.positions, None, scheduled_times=times, wall_times=[0.0])
    assert metrics.constraint_error > 0.1 * scene.characteristic_length and series.constraint_error[0] < 1e-12
    status, message = apply_bounds("ok", "", metrics, Bounds(), scene)
    assert status == "unstable" and "constraint error" in message and "exceeds the bound 0.1 L" in message


def test_an_overflowing_joint_gap_is_a_non_finite_state_and_truncation_keeps_the_channel_in_step():
    scene = model_scene("whirl", DOUBLE, q0={"shoulder": 30, "elbow": -20}, v0={"elbow": 20}, duration=1.0)
    run = _run("ours/baumgarte-euler", 3e-2, scene)
    assert run.info.status == "unstable" and run.info.message.startswith("non-finite state at t = ")
    assert run.constraint_violation.shape == (run.n_samples,) and np.isfinite(run.constraint_violation).all()
    cut = _truncate(run, 5)
    assert cut.n_samples == 5 and np.array_equal(cut.constraint_violation, run.constraint_violation[:5])


class _OneShort(OursEngine):
    """ours, but its channel is one sample short of its positions."""

    def _run_model(self, scene, schedule, settings):
        raw = super()._run_model(scene, schedule, settings)
        return replace(raw, constraint_violation=raw.constraint_violation[:-1])


def test_a_channel_of_the_wrong_length_fails_the_case_naming_the_field():
    run = _OneShort().simulate(SCENE.with_duration(0.1), 1e-2, variant="baumgarte-rk4")
    assert run.info.status == "failed"
    assert run.info.message == ("RawRunError: ours: RawRun.constraint_violation has shape (10,), expected (11,): "
                                "the largest constraint violation (m) at each recorded sample, or None")
