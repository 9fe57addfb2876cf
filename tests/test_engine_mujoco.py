"""The MuJoCo adapter against closed forms and the reference, with the real engine.

Numbers quoted in comments were measured with mujoco 4.0.0 (`.venv/bin/python
-m pytest tests/test_engine_mujoco.py -q`); each tolerance is derived, not fitted.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from engines.model.scene import model_scene
from engines.scene import catalog
from engines.reference.closed_form import normal_modes, pendulum_period
from engines.errors import Unsupported, UserError
from engines.mujoco.adapter import ENGINE
from engines.mujoco.options import MUJOCO_SOLIMP, MUJOCO_SOLREF, STIFF
from engines.reference.reference import solve
from engines.scene.scene import Particle, Pin, Rod, Scene
from engines.scene.trajectory import max_constraint_error, tensions, total_energy

ROOT = Path(__file__).resolve().parent.parent

VARIANTS = list(ENGINE.variants)
G = 9.81


def settings(variant: str) -> dict:
    return ENGINE.resolve(variant)


def order(variant: str) -> int:
    """Every MuJoCo integrator is first order except RK4 (ENGINE_NOTES, MuJoCo's docs)."""
    return 4 if settings(variant)["integrator"] == "RK4" else 1


def is_soft(variant: str) -> bool:
    """connect with MuJoCo's default solref/solimp: a visibly soft constraint."""
    s = settings(variant)
    return s["formulation"] == "connect" and s["timeconst_steps"] == 0 and tuple(s["solref"]) == MUJOCO_SOLREF


def soft_stretch(acceleration: float) -> float:
    """Steady stretch (m) of a default connect pulled with ``acceleration`` (m/s²).

    MuJoCo's constraint acceleration is a_c = d·a_ref + (1 − d)·a_0 with
    a_ref = −k·r − b·v and k = 1/(dmax·timeconst·dampratio)². At rest (a_c = 0,
    v = 0): r = (1 − d)·a_0 / (d·k). With r below solimp's width, d ≈ dmin.
    """
    timeconst, dampratio = MUJOCO_SOLREF
    dmin, dmax = MUJOCO_SOLIMP[:2]
    k = 1.0 / (dmax * timeconst * dampratio) ** 2
    return (1 - dmin) * acceleration / (dmin * k)


def crossing_times(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Upward zero crossings of x(t), linearly interpolated between samples."""
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def measured_period(t: np.ndarray, x: np.ndarray) -> float:
    c = crossing_times(t, x)
    return float((c[-1] - c[0]) / (len(c) - 1))


# -- the bead's period -----------------------------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_bead_period_matches_the_elliptic_integral(variant):
    dt, theta0 = 1e-3, math.radians(10)
    scene = catalog.build("bead", {"theta0": 10, "duration": 6.5})  # three full periods
    run = ENGINE.simulate(scene, dt, variant=variant, sample_interval=dt)
    assert run.info.status == "ok", run.info.message
    exact = pendulum_period(1.0, G, theta0)
    relative = measured_period(run.t, run.positions[:, 0, 0]) / exact - 1
    omega = 2 * math.pi / exact
    # A method of order p has phase error O((ω·dt)^p) per unit time, so the period's
    # relative error is bounded by (ω·dt)^p (3.1e-3 for first order; symplectic Euler
    # does better, −(ω·dt)²/24 = −4e-7 measured). 1e-8 covers the crossing interpolation
    # and the point-mass inertia (inertia_ratio 1e-9 lengthens the period by 5e-10).
    tolerance = (omega * dt) ** order(variant) + 1e-8
    expected = 0.0
    if is_soft(variant):
        # The default connect stretches by r at the bottom (tension ≈ m·g), lengthening
        # the pendulum: the period grows by r / (2L) (1.9e-4 predicted, 1.8e-4 measured).
        # The stretch varies over the swing, hence the 25% band.
        expected = soft_stretch(G) / 2
        tolerance += 0.25 * expected
    assert abs(relative - expected) <= tolerance, f"{variant}: relative period error {relative:.3e}"


# -- the double pendulum against the reference --------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_double_pendulum_follows_the_reference(variant, double_pendulum):
    scene, reference = double_pendulum
    dt = 1e-4
    run = ENGINE.simulate(scene, dt, variant=variant)
    assert run.info.status == "ok", run.info.message
    positions, _, forces = reference.at(run.t)
    error = np.linalg.norm(run.positions - positions, axis=2).max()
    # First order: the global error is ≈ t·dt·|jerk|/2, with |jerk| ≈ ω²·v ≈ 40 m/s³ over
    # the first 0.5 s (ω² ≈ 2g/l, v ≲ 2 m/s): 0.5·1e-4·40/2 = 1e-3 m (measured 2.6e-4 m).
    # RK4: O(dt⁴) is ~1e-12; 1e-6 m leaves room for the reference (rtol 1e-12) and the
    # point-mass inertia (measured 3e-9 m).
    tolerance = 1e-3 if order(variant) == 1 else 1e-6
    if is_soft(variant):
        # Each default connect stretches by up to soft_stretch(tension/m); the two rods add.
        peak = np.abs(tensions(scene, positions, forces)).max()  # N, 42 N here
        tolerance += 2 * soft_stretch(peak / scene.masses.min())
    assert error <= tolerance, f"{variant}: position error {error:.3e} m"


# -- energy ----------------------------------------------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_bead_energy_drift_is_bounded(variant):
    scene = catalog.build("bead", {"duration": 10})  # theta0 = 60°
    dt = 1e-3
    run = ENGINE.simulate(scene, dt, variant=variant)
    assert run.info.status == "ok", run.info.message
    energy = total_energy(scene, run.positions, run.velocities)
    drift = np.abs(energy - energy[0]).max() / scene.characteristic_energy
    v_max = math.sqrt(2 * G * (1 - math.cos(math.radians(60))))  # m/s at the bottom
    # Symplectic Euler conserves a modified energy H + O(dt): the oscillation of H is at
    # most dt·v_max·g·m / 2, i.e. dt·v_max / (2L) relative to E* = m·g·L (1.6e-3; measured
    # 7.4e-4). RK4: O((ω·dt)⁴) ≈ 1e-10 per period; 1e-8 (measured 5e-10).
    # The default connect also dissipates through its damped soft constraint: measured
    # 2.6e-3 over 10 s (scripts/defaults_mujoco.py); bound 5e-3.
    # Any of these bounds fails for a 0.04 /s damping creeping back in (≈ 33% lost in 10 s).
    bound = dt * v_max / 2 if order(variant) == 1 else 1e-8
    if order(variant) == 4 and settings(variant)["formulation"] == "connect":
        # The stiff connect's damping term b·v (b = 2/(dmax·2·dt)) acts on the tiny constraint
        # velocity RK4 leaves, and removes a little energy: measured 5.7e-8; bound 1e-6.
        bound = 1e-6
    if is_soft(variant):
        bound = 5e-3
    assert drift <= bound, f"{variant}: energy drift {drift:.3e} of E*"


# -- normal modes ------------------------------------------------------------------------------


@pytest.mark.parametrize("variant", ["hinge", "connect-stiff", "hinge-rk4"])
@pytest.mark.parametrize("mode", [0, 1])
def test_normal_mode_oscillates_at_its_frequency(variant, mode):
    omegas, shapes = normal_modes([1.0, 1.0], [1.0, 1.0], G)
    amplitude = 1.0  # degrees: the nonlinear frequency shift is ~θ²/16 ≈ 2e-5
    theta = amplitude * shapes[:, mode]
    period = 2 * math.pi / omegas[mode]
    scene = catalog.build(
        "double-pendulum", {"theta1": theta[0], "theta2": theta[1], "duration": 3.2 * period}
    )
    dt = 1e-3
    run = ENGINE.simulate(scene, dt, variant=variant, sample_interval=dt)
    assert run.info.status == "ok", run.info.message
    measured = measured_period(run.t, run.positions[:, 0, 0])
    # Period error of order (ω·dt)^p (≤ 5e-3 for the faster mode at first order) plus the
    # nonlinear shift ~2e-5 and the mixing of the other mode at this amplitude (~1e-4).
    tolerance = (omegas[mode] * dt) ** order(variant) + 1e-3
    assert abs(measured / period - 1) <= tolerance
    # The shape holds: the lower particle's x stays the mode's multiple of the upper's.
    x = run.positions[:, :, 0]
    ratio = (shapes[0, mode] + shapes[1, mode]) / shapes[0, mode]
    assert np.abs(x[:, 1] - ratio * x[:, 0]).max() <= 0.05 * np.abs(x[:, 1]).max()


# -- spherical pendulum -------------------------------------------------------------------------


@pytest.mark.parametrize("variant", ["hinge", "hinge-rk4", "connect-stiff", "connect-rk4-stiff"])
def test_spherical_pendulum_conserves_energy_and_follows_the_reference(variant):
    scene = catalog.build("spherical-pendulum", {"duration": 3})
    dt = 1e-3
    if settings(variant)["formulation"] == "hinge":
        model, _, _ = ENGINE.build(scene, dt, settings(variant))
        assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_BALL
    run = ENGINE.simulate(scene, dt, variant=variant)
    assert run.info.status == "ok", run.info.message
    energy = total_energy(scene, run.positions, run.velocities)
    drift = np.abs(energy - energy[0]).max() / scene.characteristic_energy
    positions, _, _ = solve(scene).at(run.t)
    error = np.linalg.norm(run.positions - positions, axis=2).max()
    speed = np.linalg.norm(scene.initial_velocities[0])  # m/s, 2.6
    v_max = math.sqrt(speed**2 + 2 * G * 1.0)  # m/s, bound from energy
    # First order: the same O(dt) modified-energy bound as the bead, dt·v_max/(2L)
    # (3e-3; measured 4e-4), and a position error of a few ω·dt·L per second (3 s: 1e-2 m;
    # measured 4e-3). RK4: 1e-6 and 1e-5 m (measured 3e-7, 2e-6).
    if order(variant) == 1:
        assert drift <= dt * v_max / 2 and error <= 1e-2, (drift, error)
    else:
        assert drift <= 1e-6 and error <= 1e-5, (drift, error)


# -- constraint forces -----------------------------------------------------------------------------


@pytest.mark.parametrize("variant", ["hinge", "hinge-rk4", "connect-stiff", "connect-rk4-stiff"])
def test_constraint_forces_match_the_reference_tensions(variant, double_pendulum):
    scene, reference = double_pendulum
    run = ENGINE.simulate(scene, 1e-4, variant=variant)
    positions, _, forces = reference.at(run.t)
    ours, theirs = tensions(scene, run.positions, run.constraint_forces), tensions(scene, positions, forces)
    peak = np.abs(theirs).max()  # N, 42 here
    error = np.abs(ours - theirs).max()
    # The tension follows the state: first order, relative error ~ the position error
    # over L (≤ 1e-3, see above) times the peak; RK4 hinge: 1e-6 of the peak (measured 4e-7 N).
    tolerance = 1e-3 * peak if order(variant) == 1 else 1e-6 * peak
    if settings(variant)["formulation"] == "connect":
        # A stiff connect adds its feedback m·k·r with k = 1/(dmax·2·dt)², r the constraint
        # error (2.5e7 /s² × 3e-9 m ≈ 0.08 N; measured 0.09 N for RK4): allow three times it.
        k = 1.0 / (STIFF["solimp"][1] * 2 * 1e-4) ** 2
        tolerance += 3 * scene.masses.sum() * k * max_constraint_error(scene, run.positions).max()
    assert error <= tolerance, f"{variant}: tension error {error:.3e} N (peak {peak:.1f} N)"


def test_pin_force_holds_a_resting_bead_up():
    scene = catalog.build("bead", {"theta0": 0, "duration": 0.1, "m": 2.0})
    for variant in ("hinge", "connect-stiff"):
        run = ENGINE.simulate(scene, 1e-3, variant=variant)
        # At rest the Pin carries the weight: +m·g along z on the particle (to 1e-6 relative).
        np.testing.assert_allclose(run.constraint_forces[-1, 0], [0, 0, 2.0 * G], rtol=1e-6, atol=1e-6 * G)


# -- the state handed in and read back ---------------------------------------------------------------


@pytest.mark.parametrize("variant", ["hinge", "connect"])
@pytest.mark.parametrize("name", ["double-pendulum", "spherical-pendulum"])
def test_first_sample_is_the_scene_initial_state(variant, name):
    scene = catalog.build(name, {"duration": 0.1, **({"omega2": 1.5} if name == "double-pendulum" else {})})
    run = ENGINE.simulate(scene, 1e-3, variant=variant)
    np.testing.assert_allclose(run.positions[0], scene.initial_positions, atol=1e-12)
    np.testing.assert_allclose(run.velocities[0], scene.initial_velocities, atol=1e-12)


# -- blow-ups, refusals, bad input ------------------------------------------------------------------------


def test_blow_up_ends_unstable_before_the_reset(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)  # where MuJoCo would write MUJOCO_LOG.TXT
    scene = catalog.build("chain", {"n": 8, "duration": 5})
    run = ENGINE.simulate(scene, 0.05, variant="hinge")
    assert run.info.status == "unstable"
    assert "mjWARN_BADQACC" in run.info.message and "reset" in run.info.message
    assert 0 < run.n_samples < 101  # stopped early (measured: 20 samples, t ≤ 0.95 s)
    # Nothing after the reset: the last sample is not the initial state put back.
    assert not np.allclose(run.positions[-1], scene.initial_positions)
    assert np.isclose(run.t[-1], run.info.steps * 0.05)
    assert not os.path.exists("MUJOCO_LOG.TXT")
    assert capfd.readouterr() == ("", "")


def test_loop_is_closed_by_hinge_and_refused_by_connect():
    """hinge closes a loop with an arm body and a connect equality (test_mechanisms_engines.py runs one);
    connect has no arm left for the third constraint."""
    a, b, c = (0.0, 0.0, -1.0), (1.0, 0.0, -1.0), (0.0, 0.0, 0.0)
    ring = Scene(
        "ring",
        (Particle(1.0, a), Particle(1.0, b)),
        (Pin(0, c, 1.0), Pin(1, c, math.sqrt(2.0)), Rod(0, 1, 1.0)),
        duration=1.0,
    )
    ENGINE.check(ring, "hinge")
    assert "<connect" in ENGINE.build(ring, 1e-3, ENGINE.resolve("hinge"))[1]
    with pytest.raises(Unsupported, match="cannot get an arm"):
        ENGINE.check(ring, "connect")


def test_bad_solref_names_the_option():
    scene = catalog.build("bead", {"duration": 0.1})
    with pytest.raises(UserError, match="solref must be two positive numbers"):
        ENGINE.simulate(scene, 1e-3, variant="connect", options={"solref": "0.02,1,3"})
    with pytest.raises(UserError, match="integrator must be one of"):
        ENGINE.simulate(scene, 1e-3, options={"integrator": "verlet"})


def test_a_bad_option_value_is_refused_on_a_model_file_too():
    """Option values are checked whatever the scene (Engine._check_options): a model file, which only
    the hinge variants load, gets the same error as the bead, not a run that ignores the value."""
    model = model_scene("dp", str(ROOT / "models" / "double_pendulum.urdf"), q0={"shoulder": 30}, duration=0.1)
    for scene in (catalog.build("bead", {"duration": 0.1}), model):
        with pytest.raises(UserError, match=r"mujoco: option inertia_ratio must be positive, got -1\.0"):
            ENGINE.check(scene, "hinge", {"inertia_ratio": -1.0})
        with pytest.raises(UserError, match="mujoco: option solref must be two positive numbers"):
            ENGINE.check(scene, "hinge", {"solref": "0.02,1,3"})
    ENGINE.check(model, "hinge")


@pytest.mark.parametrize("name", ["double-pendulum", "four-bar", "slider-pendulum", "spherical-pendulum"])
def test_a_model_and_data_kept_from_another_run_give_bit_for_bit_a_fresh_compiles_run(name):
    # engines.mujoco.adapter._model_and_data keeps each MJCF's compiled model and MjData (per thread) and,
    # for the next run of it, sets the timestep and resets the data rather than compile again: every
    # variant's run at a dt must equal a fresh compile's exactly, after a run of the same MJCF at
    # another dt (the stiff variants too: their dt-dependent equality softness is set on the kept model).
    import engines.mujoco.adapter as adapter

    scene = catalog.build(name, {"duration": 0.3})
    for variant in VARIANTS:
        try:
            ENGINE.check(scene, variant, {})
        except Unsupported:
            continue
        adapter._CACHE.models = None
        fresh = ENGINE.simulate(scene, 2e-3, variant=variant)
        adapter._CACHE.models = None
        ENGINE.simulate(scene, 5e-3, variant=variant)  # only the 5e-3 run's model and data are kept now
        [kept] = adapter._CACHE.models.values()
        reused = ENGINE.simulate(scene, 2e-3, variant=variant)
        [(model, _data)] = adapter._CACHE.models.values()
        assert model is kept[0], f"{variant}: the 2e-3 run compiled its own model"
        assert reused.info.settings == fresh.info.settings, variant
        for a, b in ((fresh.positions, reused.positions), (fresh.velocities, reused.velocities),
                     (fresh.constraint_forces, reused.constraint_forces)):
            assert np.array_equal(a, b, equal_nan=True), variant


def test_only_the_connect_equalities_solref_and_the_timestep_are_left_out_of_the_kept_models_key():
    # A solref anywhere else (here a geom's) is part of the model the compiler builds: each value its
    # own kept model. A connect's is set on the kept model, as is the timestep.
    import engines.mujoco.adapter as adapter

    def mjcf(dt, geom_solref, connect_solref):
        return (f'<mujoco><option timestep="{dt!r}"/><worldbody><body name="a"><freejoint/>'
                f'<geom size="0.1" mass="1"/></body><body name="b" pos="1 0 0"><freejoint/>'
                f'<geom size="0.1" mass="1" solref="{geom_solref}"/></body></worldbody><equality>'
                f'<connect body1="a" body2="b" anchor="0 0 0" solref="{connect_solref}"/></equality></mujoco>')

    adapter._CACHE.models = None
    try:
        first, _ = adapter._model_and_data(mjcf(1e-3, "0.02 1", "0.02 1"), 1e-3)
        again, _ = adapter._model_and_data(mjcf(2e-3, "0.02 1", "0.05 1"), 2e-3)
        assert again is first and again.opt.timestep == 2e-3 and list(again.eq_solref[0]) == [0.05, 1.0]
        other, _ = adapter._model_and_data(mjcf(2e-3, "0.03 1", "0.05 1"), 2e-3)
        assert other is not first and len(adapter._CACHE.models) == 2
    finally:
        adapter._CACHE.models = None  # later tests start with no kept model


def test_a_kept_mjdata_that_blew_up_starts_the_next_run_clean(tmp_path, monkeypatch):
    # mj_resetData clears the warning counters too: a run after a blow-up (MuJoCo reset its state and
    # counted mjWARN_BADQACC) of the same MJCF is bit for bit a fresh compile's run, not cut short.
    import engines.mujoco.adapter as adapter

    monkeypatch.chdir(tmp_path)  # where MuJoCo would write MUJOCO_LOG.TXT
    scene = catalog.build("chain", {"n": 8, "duration": 5})
    adapter._CACHE.models = None
    fresh = ENGINE.simulate(scene, 0.01, variant="hinge")
    adapter._CACHE.models = None
    assert ENGINE.simulate(scene, 0.05, variant="hinge").info.status == "unstable"
    after = ENGINE.simulate(scene, 0.01, variant="hinge")
    assert (after.info.status, after.info.message, after.n_samples) == (fresh.info.status, fresh.info.message,
                                                                        fresh.n_samples)
    np.testing.assert_array_equal(after.positions, fresh.positions)
