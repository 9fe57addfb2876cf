"""The reference's own error bar and horizon, the Lyapunov exponent, and the vertical angular momentum."""

from __future__ import annotations

import re

import numpy as np
import pytest

from engines.scene import catalog

from engines.reference import reference
from engines.scene.scene import Particle, Pin, Rod, Scene
from engines.scene.trajectory import momentum_drift, vertical_axis


def test_the_bead_has_no_horizon_over_40_s():
    scene = catalog.build("bead", {"duration": 40.0})
    b = reference.bound(scene)
    # A regular orbit: the two solves drift apart in phase only (measured 5.7e-12 m in 40 s).
    assert b.reference_horizon is None
    assert b.reference_error < 0.5 * b.threshold
    assert b.tight_rtol < b.rtol / 40  # 100× tighter, floored at what DOP853 accepts (2.2e-14)


def test_the_chaotic_double_pendulum_has_a_horizon_inside_40_s():
    scene = catalog.build("double-pendulum", {"duration": 40.0})
    b = reference.bound(scene)
    # The difference grows like 1e-12·e^{λt} with λ ≈ 1/s: past 1e-10 m near 7 s (measured 7.29 s).
    assert b.reference_horizon is not None and 5.0 < b.reference_horizon < 10.0
    assert b.difference[b.t < b.reference_horizon].max() <= b.threshold
    assert b.reference_error > 1e-3  # by 40 s the two solves are different motions


def test_horizon_is_the_first_time_above_the_threshold():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert reference.reference_horizon(t, np.array([0.0, 1e-12, 2e-10, 1e-12]), 1e-10) == 2.0
    assert reference.reference_horizon(t, np.zeros(4), 1e-10) is None


def test_lyapunov_exponent_of_the_default_double_pendulum_is_about_one_per_second():
    scene = catalog.build("double-pendulum", {"duration": 10.0})
    # Measured 0.99 /s over 10 s; a regular scene's estimate is ln(growth)/T, small and falling.
    assert 0.7 < reference.lyapunov_exponent(scene) < 1.3
    bead = catalog.build("bead", {"duration": 40.0})
    assert reference.lyapunov_exponent(bead) < 0.15


def test_momentum_drift_of_the_spherical_pendulum():
    scene = catalog.build("spherical-pendulum", {"duration": 5.0})
    t = np.linspace(0.0, scene.duration, 501)
    p, v, _ = reference.solve(scene).at(t)
    assert momentum_drift(scene, p, v) < 1e-10  # the reference conserves L_z (measured 8.5e-13)
    # A torque about the vertical (a tangential push growing with time) shows up in full:
    # adding δv along e_phi at the last sample changes L_z by m·r·sinθ·δv.
    kicked = v.copy()
    radial = p[-1, 0, :2] / np.linalg.norm(p[-1, 0, :2])
    kicked[-1, 0, :2] += 1e-3 * np.array([-radial[1], radial[0]])
    r_xy = np.linalg.norm(p[-1, 0, :2])
    expected = 1.0 * r_xy * 1e-3 / (1.0 * 1.0 * np.sqrt(9.81))
    assert momentum_drift(scene, p, kicked) == pytest.approx(expected, rel=1e-6, abs=1e-10)


def test_momentum_drift_is_none_where_lz_is_not_conserved_or_trivially_zero():
    assert momentum_drift(catalog.build("bead"), np.zeros((2, 1, 3)), np.zeros((2, 1, 3))) is None  # planar
    two_anchors = Scene(
        "two-anchors",
        (Particle(1.0, (1.0, 0.0, -1.0), (0.0, 1.0, 0.0)), Particle(1.0, (3.0, 0.0, -1.0))),
        (Pin(0, (0.0, 0.0, 0.0), 2**0.5), Pin(1, (2.0, 0.0, 0.0), 2**0.5), Rod(0, 1, 2.0)),
        duration=1.0,
    )
    assert vertical_axis(two_anchors) is None


def test_momentum_drift_is_a_declared_gated_metric_computed_for_each_case():
    from compare.results.declared import METRICS, MetricInputs, computed_extras
    from engines.mujoco.adapter import ENGINE as MUJOCO

    metric = METRICS["momentum_drift"]
    assert metric.gated and metric.better == "lower" and metric.unit == "L*"
    sphere = catalog.build("spherical-pendulum", {"duration": 1.0})
    run = MUJOCO.simulate(sphere, 1e-3, variant="connect")
    values = computed_extras(MetricInputs(sphere, run, run.positions, np.zeros(run.n_samples)))
    assert values["momentum_drift"] == pytest.approx(momentum_drift(sphere, run.positions, run.velocities))
    assert values["momentum_drift"] > 1e-6  # the soft connect leaks L_z (measured 1.7e-3 over 10 s)
    bead = catalog.build("bead", {"duration": 0.1})
    run = MUJOCO.simulate(bead, 1e-3, variant="hinge")
    assert computed_extras(MetricInputs(bead, run, run.positions, np.zeros(run.n_samples)))["momentum_drift"] is None


def test_a_run_records_the_reference_horizon_and_error(tmp_path):
    from compare.run.results import load_results
    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite

    suite = parse_suite(
        'name = "horizon"\nduration = 12.0\ndt = [0.01]\n'
        '[[scenes]]\nid = "dp"\nscene = "double-pendulum"\n'
        '[[scenes]]\nid = "bead"\nscene = "bead"\n'
        '[[engines]]\nid = "mujoco/hinge-rk4"\n'
    )
    run_suite(suite, tmp_path / "run", jobs=1, isolate=False)
    records = {r.case.scene_id: r for r in load_results(tmp_path / "run").records}
    # The chaotic double pendulum's two reference solves part near 7.3 s; the bead's never do.
    assert 6.0 < records["dp"].reference_horizon < 9.0
    assert records["bead"].reference_horizon is None
    assert records["bead"].reference["reference_error"] < 1e-10
    assert records["dp"].reference["tight_rtol"] < 1e-13
    # Errors are judged within the horizon; the whole run's are kept under their own names.
    dp, bead = records["dp"].metrics, records["bead"].metrics
    assert dp["position_error_linf"] <= dp["position_error_linf_whole_run"]
    assert dp["position_error_linf_whole_run"] > 10 * dp["position_error_linf"]  # RK4 at 0.01 s: the chaos grows it
    assert "position_error_linf_whole_run" not in bead
    # The cheap Lyapunov estimate from the same two solves: Benettin's is 0.99 /s over 10 s (the test above);
    # the regular bead has none. Both go to show and to every export.
    assert 0.6 < records["dp"].reference["lyapunov_exponent"] < 1.3
    assert records["bead"].reference["lyapunov_exponent"] is None
    from compare.results.table import case_rows, scene_tables
    from compare.results.sweep import sweeps

    rows = {row["scene"]: row for row in case_rows(load_results(tmp_path / "run").records)}
    assert rows["dp"]["reference_horizon"] == records["dp"].reference_horizon
    assert rows["dp"]["reference_error"] == records["dp"].reference["reference_error"]
    assert rows["dp"]["lyapunov_exponent"] == records["dp"].reference["lyapunov_exponent"]
    assert rows["bead"]["reference_horizon"] is None and rows["bead"]["lyapunov_exponent"] is None
    text = scene_tables(sweeps(load_results(tmp_path / "run").records))
    assert "scene dp (reference error" in text and "Lyapunov exponent 0." in text
    assert "horizon none, Lyapunov exponent -)" in text


def test_show_json_carries_the_chaotic_estimates_with_their_intervals(tmp_path):
    """The Lyapunov exponent and the horizon of a chaotic scene are ensemble estimates with an interval
    (engines/reference/ensemble.py); `xval show --format json` carries both, a regular scene's are null."""
    import json

    from conftest import run_xval

    suite = tmp_path / "chaos.toml"
    suite.write_text('name = "chaos"\nduration = 10.0\ndt = [0.01]\n'
                     '[[scenes]]\nid = "dp"\nscene = "double-pendulum"\n'
                     '[[scenes]]\nid = "bead"\nscene = "bead"\n'
                     '[[engines]]\nid = "ours/baumgarte-rk4"\n')
    assert run_xval("run", suite, "--output", tmp_path / "run", "--quiet", timeout=300).returncode == 0
    shown = run_xval("show", tmp_path / "run", "--format", "json")
    assert shown.returncode == 0, shown.stderr
    rows = {row["scene"]: row for row in json.loads(shown.stdout)}
    dp, bead = rows["dp"], rows["bead"]
    low, high = dp["lyapunov_interval"]
    # Twelve Benettin runs over 10 s: measured 0.95 [0.55, 1.1] /s; an orbit's ±15 % and more in the ends.
    assert 0.3 < low < dp["lyapunov_exponent"] < high < 2.0
    low, high = dp["reference_horizon_interval"]
    assert low <= dp["reference_horizon"] <= high and low < high  # measured 7.29 [5.83, 8.8] s
    assert bead["lyapunov_exponent"] is None and bead["lyapunov_interval"] is None
    assert bead["reference_horizon"] is None and bead["reference_horizon_interval"] is None
    # So does the verdict's document, per scene.
    verdict = run_xval("verdict", tmp_path / "run", "--format", "json")
    assert verdict.returncode == 0, verdict.stderr
    scenes = {scene["scene"]: scene["reference"] for scene in json.loads(verdict.stdout)["scenes"]}
    assert scenes["dp"]["lyapunov_interval"] == dp["lyapunov_interval"]
    assert scenes["dp"]["reference_horizon_interval"] == dp["reference_horizon_interval"]
    assert scenes["bead"]["lyapunov_interval"] is None
    # The text table's scene line says the estimate with its interval.
    text = run_xval("show", tmp_path / "run").stdout
    assert re.search(r"scene dp \(reference error \S+ m, horizon [\d.]+ \[[\d.]+, [\d.]+\] s, "
                     r"Lyapunov exponent [\d.]+ \[[\d.]+, [\d.]+\] /s\)", text), text


def test_growth_rate_tells_exponential_from_linear_separation():
    t = np.linspace(0.0, 10.0, 1001)
    # Exponential growth from round-off: the slope of ln d (1/s), in the band from 1e-13 L to 1e-3 L.
    assert reference.growth_rate(t, 2.0 * 1e-15 * np.exp(1.5 * t), 2.0) == pytest.approx(1.5, rel=1e-9)
    # Saturated past 1e-3 L: the samples above it are left out.
    d = np.minimum(1e-14 * np.exp(3.0 * t), 0.5)
    assert reference.growth_rate(t, d, 1.0) == pytest.approx(3.0, rel=1e-9)
    # A regular scene's phase drift grows linearly (50× over the run): no exponent.
    assert reference.growth_rate(t, 1e-13 * (1 + 5 * t), 1.0) is None
    assert reference.growth_rate(t, np.full_like(t, 1e-16), 1.0) is None


def test_momentum_drift_without_gravity_is_measured_against_the_initial_speed():
    # g = 0: the characteristic speed is √(2 T₀ / M), T₀ the initial kinetic energy: for one particle, its
    # initial speed (m/s, not the √L of a units-less fallback). A tangential kick δ at the last sample
    # changes L_z by m·r_xy·δ, measured against M·L·|v₀|. m = 2 kg, L = 2 m, |v₀| ≠ 1, L, √L.
    scene = catalog.build("spherical-pendulum", {"g": 0.0, "m": 2.0, "radius": 2.0, "duration": 1.0})
    p = scene.initial_positions[None].repeat(2, 0)
    v = scene.initial_velocities[None].repeat(2, 0)
    x, y = p[1, 0, 0], p[1, 0, 1]
    r_xy = float(np.hypot(x, y))
    v[1, 0] += 0.1 * np.array([-y, x, 0.0]) / r_xy
    mass, length = float(scene.masses.sum()), scene.characteristic_length
    speed = float(np.linalg.norm(scene.initial_velocities[0]))
    assert (mass, length) == (2.0, 2.0) and speed not in (0.0, 1.0, length, np.sqrt(length))
    assert scene.characteristic_speed == pytest.approx(speed, rel=1e-12)
    assert scene.characteristic_energy == pytest.approx(0.5 * mass * speed**2, rel=1e-12)  # J: T₀
    assert momentum_drift(scene, p, v) == pytest.approx(mass * r_xy * 0.1 / (mass * length * speed), rel=1e-9)


def test_a_scene_at_rest_without_gravity_falls_back_to_unit_acceleration():
    # g = 0 and nothing moving: no energy to measure against; E* = M·L·1 m/s², v* = √(L·1 m/s²).
    scene = catalog.build("bead", {"g": 0.0, "m": 3.0, "radius": 2.0, "theta0": 60.0})
    assert not scene.initial_velocities.any()
    assert scene.characteristic_energy == pytest.approx(3.0 * 2.0)
    assert scene.characteristic_speed == pytest.approx(np.sqrt(2.0))
