"""`xval probe`: hidden damping told apart from integrator error (compare/stability/dissipation.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli_support import run_cli
from compare.stability.dissipation import RATE_FLOOR, extrapolate, hidden, loss_rate, probe
from engines.scene import catalog
from engines.scene.scene import Particle, Scene

BEAD = catalog.build("bead", {"duration": 20.0})


# -- the pure measurement ------------------------------------------------------------------


def test_loss_rate_is_the_slope_of_the_energy_in_e_star_per_second():
    # A free particle in gravity-free space slowing down linearly in energy: E = E0 (1 - 0.01 t).
    scene = Scene("free", (Particle(2.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),), (), (0.0, 0.0, -9.81), 1.0)
    t = np.linspace(0.0, 10.0, 101)
    speed = np.sqrt(1.0 - 0.01 * t)
    velocities = np.zeros((101, 1, 3))
    velocities[:, 0, 0] = speed
    rate = loss_rate(scene, t, np.zeros((101, 1, 3)), velocities)
    # E0 = ½·2·1 = 1 J lost at 0.01 J/s; E* = M g L with L = 1 (no constraints): 2·9.81 J.
    assert rate == pytest.approx(0.01 / (2 * 9.81 * scene.characteristic_length), rel=1e-9)


def test_extrapolation_recovers_a_floor_and_rejects_a_pure_step_error():
    dts = np.array([4e-3, 2e-3, 1e-3, 5e-4])
    rate, sigma = extrapolate(dts, 2e-4 + 3.0 * dts)
    assert rate == pytest.approx(2e-4, abs=1e-12) and sigma < 1e-12
    assert hidden(rate, sigma)
    rate, sigma = extrapolate(dts, 5.0 * dts)  # an integrator's loss: gone at dt -> 0
    assert abs(rate) < 1e-12 and not hidden(rate, sigma)
    rate, sigma = extrapolate(dts, 40.0 * dts**2)  # second order: linear extrapolation undershoots, σ says so
    assert not hidden(rate, sigma)
    assert not hidden(0.5 * RATE_FLOOR, 0.0)


# -- real engines -------------------------------------------------------------------------------


def test_pymunk_with_damping_has_hidden_dissipation():
    result = probe("pymunk/pin", BEAD, {"damping": 0.9}, isolate=False)
    # v ← 0.9^dt·v every step: about 2.1e-2 E*/s on the 60° bead, the same at every dt.
    assert result.hidden_dissipation is True
    assert 0.015 < result.rate < 0.025 and result.uncertainty < 1e-3 * result.rate


@pytest.mark.parametrize("engine_id", ["mujoco/hinge", "ours/rattle"])
def test_conservative_integrators_have_none(engine_id):
    result = probe(engine_id, BEAD, isolate=False)
    # Semi-implicit Euler and RATTLE: bounded energy error, so the rate goes to 0 with dt
    # (measured |r0| < 5e-9 E*/s, σ < 4e-9).
    assert result.hidden_dissipation is False
    assert abs(result.rate) < 1e-7 and all(p.status == "ok" for p in result.points)


def test_the_default_mujoco_connect_damps_on_its_own():
    # The soft equality's damper (docs/engines.md): ~2.4e-4 E*/s at every dt, not an integration error.
    result = probe("mujoco/connect", BEAD, isolate=False)
    assert result.hidden_dissipation is True
    assert 1.5e-4 < result.rate < 3.5e-4


# -- the command ----------------------------------------------------------------------------------


def test_probe_json_is_one_object_with_the_verdict(capsys):
    code, out, _ = run_cli(capsys, *["probe", "pymunk/pin", "--option", "damping=0.9", "--duration", "5", "--format", "json"])
    assert code == 0
    document = json.loads(out)
    assert document["hidden_dissipation"] is True
    assert set(document) >= {"engine", "scene", "rate", "uncertainty", "hidden_dissipation", "rule", "points"}
    assert document["engine"] == "pymunk/pin" and document["options"] == {"damping": "0.9"}


@pytest.mark.parametrize("argv, message", [
    (["probe", "mujoco/nope"], "unknown variant 'mujoco/nope'"),
    (["probe", "mujoco/hinge", "--dt", "1e-3", "--dt", "2e-3"], "--dt: give at least 3 different time steps"),
    (["probe", "pymunk/pin", "--option", "damping=2"], "damping"),
    (["probe", "pymunk/pin", "--scene", "spherical-pendulum"], "2-D"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, argv, message):
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert message in err and len(err.strip().splitlines()) == 1


def test_a_case_host_left_by_the_probe_is_not_reused_by_a_forked_child():
    # The probe runs its cases in this thread's case host; a process forked afterwards (a run's
    # process pool) inherits the thread-local host object but must start a host of its own.
    import multiprocessing

    from compare.run.isolation import CaseTask, execute

    scene = catalog.build("bead", {"duration": 0.05})
    task = CaseTask("fork-check", "mujoco/hinge", "hinge", {}, scene, 1e-3, 0.01)
    assert execute(task).status == "ok"
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_status_in_child, args=(task, queue))
    child.start()
    try:
        status = queue.get(timeout=120)
    finally:
        child.join(timeout=30)
    assert status == "ok"


def _status_in_child(task, queue):
    from compare.run.isolation import execute

    try:
        queue.put(str(execute(task).status))
    except BaseException as exc:  # the assertion "can only test a child process", before the fix
        queue.put(f"{type(exc).__name__}: {exc}")


def test_probe_output_is_what_the_report_lists(capsys, tmp_path):
    from compare.stability.dissipation import PROBE_VERSION, load_probe_files

    code, _, _ = run_cli(capsys, *["probe", "pymunk/pin", "--option", "damping=0.9", "--duration", "5",
                              "--output", str(tmp_path)])
    assert code == 0
    stored = load_probe_files(tmp_path)
    assert [p["engine"] for p in stored] == ["pymunk/pin"] and stored[0]["hidden_dissipation"] is True
    assert (stored[0]["schema"], stored[0]["schema_version"]) == ("xval-probe", PROBE_VERSION)
    # A file of another version is not read as this one's fields.
    (file,) = tmp_path.glob("probe*.json")
    file.write_text(file.read_text().replace(f'"schema_version": {PROBE_VERSION}', '"schema_version": 99'))
    assert load_probe_files(tmp_path) == []
    code, _, err = run_cli(capsys, *["probe", "pymunk/pin", "--output", str(tmp_path / "nope")])
    assert code == 2 and "does not exist" in err
