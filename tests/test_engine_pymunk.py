"""pymunk adapter: physics checked with the real engine against closed forms and the reference.

pymunk steps with semi-implicit (symplectic) Euler plus an impulse solver
whose drift correction is set by ``error_bias``: a first-order method. Every
tolerance below is derived from that, and the measured value is quoted next
to it (measured with pymunk 7.3.1, Munk2D 2.0.1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from engines.scene import catalog
from engines.reference.closed_form import normal_modes, pendulum_period
from engines.errors import Unsupported, UserError
from engines.pymunk.adapter import ENGINE
from engines.reference.reference import solve
from engines.scene.scene import Pin, Rod, Scene
from engines.scene.trajectory import max_constraint_error, tensions, total_energy

VARIANTS = list(ENGINE.variants)
G = 9.81


def zero_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times (s) where x changes sign, by linear interpolation between samples."""
    below = np.signbit(x)
    i = np.nonzero(below[1:] != below[:-1])[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def half_period(t: np.ndarray, x: np.ndarray) -> float:
    """Least-squares spacing (s) of successive zero crossings of x."""
    crossings = zero_crossings(t, x)
    if len(crossings) < 4:
        raise ValueError(f"need at least 4 zero crossings to measure a period, got {len(crossings)}")
    return float(np.polyfit(np.arange(len(crossings)), crossings, 1)[0])


@pytest.mark.parametrize("variant", VARIANTS)
def test_bead_period_matches_elliptic_integral(variant):
    theta0, dt = math.radians(10.0), 1e-3
    exact = pendulum_period(1.0, G, theta0)
    scene = catalog.build("bead", {"theta0": 10.0, "duration": 4 * exact})
    # Sampling every step: linear interpolation of a zero crossing is then
    # off by O(dt^3 ω^2), far below the tolerance.
    run = ENGINE.simulate(scene, dt, variant=variant, sample_interval=dt)
    assert run.info.status == "ok"
    measured = 2 * half_period(run.t, run.positions[:, 0, 0])
    # First-order method: relative period error = C·ω0·dt. Its O(dt) part
    # comes only from constraint drift, a stretch of the pendulum
    # proportional to v²·dt, and v² ∝ θ0², so C ≈ θ0²: tolerance ω0·dt·θ0²
    # = 9.5e-5. Measured: 9.7e-6 (pin, default bias), 3.3e-7 (bias 0, where
    # only symplectic Euler's (ω0·dt)²/24-size phase error remains).
    omega0 = math.sqrt(G / 1.0)
    tolerance = omega0 * dt * theta0**2
    assert abs(measured - exact) / exact < tolerance


def _position_error(scene, solution, variant, dt):
    run = ENGINE.simulate(scene, dt, variant=variant)
    assert run.info.status == "ok"
    reference, _, _ = solution.at(run.t)
    return float(np.linalg.norm(run.positions - reference, axis=2).max())


@pytest.mark.parametrize("variant", VARIANTS)
def test_double_pendulum_follows_reference(variant, double_pendulum):
    scene, solution = double_pendulum
    error = _position_error(scene, solution, variant, 1e-4)
    # First order: the error grows like dt (measured 3.6e-4 m for pin and
    # 2.6e-4 m for bias 0 at dt = 1e-4, 7.3e-4 / 5.1e-4 m at 2e-4). The bound
    # 5e-4·L (L = 2 m) is 3x the worst measured value and below the 3.6e-3 m
    # that dt = 1e-3 gives, so losing the step's accuracy fails it.
    assert error < 5e-4 * scene.characteristic_length


def test_double_pendulum_error_is_first_order(double_pendulum):
    scene, solution = double_pendulum
    coarse = _position_error(scene, solution, "pin-bias0", 2e-4)
    fine = _position_error(scene, solution, "pin-bias0", 1e-4)
    # Halving dt halves a first-order error: observed order log2(coarse/fine)
    # (measured 1.00). A band of ±0.2 still tells order 1 from orders 0 and 2.
    assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.2)


# Energy drift over 10 s of the 60° bead at dt = 1e-3, in units of E* = m·g·L.
# pin: error_bias's correction dissipates steadily (measured 5.3e-3 in 10 s,
# 3.9e-2 in 100 s), bound 1e-2. bias 0: symplectic Euler keeps the energy
# error bounded, oscillating at O(ω0·dt) of the swing (measured 7.4e-4),
# bound 2e-3. Any damping < 1 (e.g. 0.999, 2% of the energy in 10 s) fails.
ENERGY_DRIFT_BOUND = {"pin": 1e-2, "pin-bias0": 2e-3, "pin-bias0-iter50": 2e-3}


def _bead_energy_drift(variant, **options):
    scene = catalog.build("bead", {"duration": 10.0})
    run = ENGINE.simulate(scene, 1e-3, variant=variant, options=options)
    assert run.info.status == "ok"
    energy = total_energy(scene, run.positions, run.velocities)
    return float(np.abs(energy - energy[0]).max()) / scene.characteristic_energy


@pytest.mark.parametrize("variant", VARIANTS)
def test_bead_energy_drift_is_bounded(variant):
    assert _bead_energy_drift(variant) < ENERGY_DRIFT_BOUND[variant]


def test_energy_bound_catches_damping():
    # The bound above must fail if pymunk's damping (1 = none) were changed.
    assert _bead_energy_drift("pin-bias0", damping=0.999) > ENERGY_DRIFT_BOUND["pin-bias0"]


@pytest.mark.parametrize("mode", [0, 1], ids=["slow-mode", "fast-mode"])
def test_double_pendulum_normal_mode_frequency(mode):
    omegas, shapes = normal_modes([1.0, 1.0], [1.0, 1.0], G)
    amplitude, dt = 0.002, 1e-3  # rad (largest link angle), s
    angles = np.degrees(amplitude * shapes[:, mode])
    duration = 4 * 2 * math.pi / omegas[mode]
    scene = catalog.double_pendulum(1.0, 1.0, 1.0, 1.0, angles[0], angles[1], 0.0, 0.0, G, duration)
    run = ENGINE.simulate(scene, dt, variant="pin-bias0", sample_interval=dt)
    p = run.positions
    upper = np.arctan2(p[:, 0, 0], -p[:, 0, 2])
    lower = np.arctan2(p[:, 1, 0] - p[:, 0, 0], p[:, 0, 2] - p[:, 1, 2])
    # Relative frequency error: first-order drift term ω·dt·ε², the phase
    # error of symplectic Euler (ω·dt)², and the nonlinear shift of a finite
    # amplitude, ≲ ε² (measured 0.92·ε² for the fast mode). Bounds with
    # ε = 0.002: 9.8e-6 (slow), 3.8e-5 (fast); measured 7e-8 and −2.3e-6.
    w = omegas[mode]
    tolerance = w * dt * amplitude**2 + (w * dt) ** 2 + amplitude**2
    for angle in (upper, lower):
        measured = math.pi / half_period(run.t, angle)
        assert abs(measured - w) / w < tolerance
    # Both links swing in the mode's shape: the other mode stays unexcited.
    # Its modal coordinate (mass-orthogonal projection) stays below 1e-3 of
    # the amplitude (measured 1.3e-5).
    other = shapes[:, 1 - mode]
    mass = np.array([[2.0, 1.0], [1.0, 1.0]])  # chain_mass_matrix for unit masses and lengths
    leak = np.stack([upper, lower], axis=1) @ mass @ other / (other @ mass @ other)
    assert np.abs(leak).max() < 1e-3 * amplitude


def test_spherical_pendulum_is_refused_with_reason():
    scene = catalog.build("spherical-pendulum")
    with pytest.raises(Unsupported, match=r"pymunk is 2-D and cannot express the 3-D scene 'spherical-pendulum'"):
        ENGINE.simulate(scene, 1e-3)
    with pytest.raises(Unsupported, match="2-D"):
        ENGINE.check(scene, "pin-bias0")


@pytest.mark.parametrize("variant", VARIANTS)
def test_bead_tension_matches_reference(variant):
    dt = 1e-3
    # 1 s of the 60° swing (period 2.15 s) sweeps the whole tension range, 4.9-19.6 N.
    scene = catalog.build("bead", {"duration": 1.0})
    run = ENGINE.simulate(scene, dt, variant=variant)
    reference_positions, _, reference_forces = solve(scene).at(run.t)
    expected = tensions(scene, reference_positions, reference_forces)[1:, 0]
    measured = tensions(scene, run.positions, run.constraint_forces)[1:, 0]
    # impulse/dt is the mean force over the step that ends at the sample,
    # i.e. the force half a step earlier: a lag error ≤ max|dT/dt|·dt/2
    # (0.022 N here). Allow twice that for the first-order trajectory error:
    # max|dT/dt|·dt = 0.043 N (measured 0.022 N with bias 0). The default
    # bias stretches the pendulum and slows it by a further first-order
    # amount: 1.5x that bound for `pin` (measured 0.036 N).
    rate = np.abs(np.gradient(expected, run.t[1:])).max()
    factor = 1.5 if variant == "pin" else 1.0
    assert np.abs(measured - expected).max() < factor * rate * dt


@pytest.mark.parametrize("variant", VARIANTS)
def test_double_pendulum_tensions_match_reference(variant, double_pendulum):
    scene, solution = double_pendulum
    dt = 1e-4
    run = ENGINE.simulate(scene, dt, variant=variant)
    reference_positions, _, reference_forces = solution.at(run.t)
    expected = tensions(scene, reference_positions, reference_forces)[1:]
    measured = tensions(scene, run.positions, run.constraint_forces)[1:]
    # The bead's bound, per rod: max|dT/dt|·dt (0.056 N upper, 0.039 N
    # lower), 1.5x for the default bias. Measured: 0.032 / 0.022 N with
    # bias 0, 0.068 / 0.046 N for pin, on tensions up to 42 / 17 N.
    rate = np.abs(np.gradient(expected, run.t[1:], axis=0)).max(axis=0)
    factor = 1.5 if variant == "pin" else 1.0
    assert (np.abs(measured - expected).max(axis=0) < factor * rate * dt).all()


def test_pushing_constraints_have_negative_tension():
    # Upside-down double pendulum at rest (unstable equilibrium, growth rate
    # ~sqrt(g/L) ≈ 3/s, so 0.1 s from a 1e-16 offset stays still): the upper
    # rod pushes with 2·m·g, the lower with m·g. pymunk reports |impulse|, so
    # this checks the adapter recovers the sign. Tolerance 1e-6 relative:
    # the state barely moves, the only error is rounding.
    scene = catalog.build("double-pendulum", {"theta1": 180.0, "theta2": 180.0, "duration": 0.1})
    run = ENGINE.simulate(scene, 1e-3, variant="pin-bias0")
    measured = tensions(scene, run.positions, run.constraint_forces)
    np.testing.assert_allclose(measured, np.broadcast_to([-2 * G, -G], measured.shape), rtol=1e-6)


def test_constraint_order_and_orientation_do_not_matter():
    # The double pendulum with its particles listed bottom-up: the Pin holds
    # particle 1 and the Rod's first particle is the lower one, so the rod's
    # force is reported on the lower mass. Same physics, same bounds as
    # above: positions within 5e-4·L (measured 2.2e-4 m), force vectors
    # within max|dT/dt|·dt of the reference's (measured 0.028 N).
    base = catalog.build("double-pendulum", {"duration": 0.5})
    scene = Scene(
        "double-pendulum-bottom-up",
        base.particles[::-1],
        (Pin(1, base.constraints[0].anchor, 1.0), Rod(0, 1, 1.0)),
        base.gravity,
        0.5,
    )
    dt = 1e-4
    run = ENGINE.simulate(scene, dt, variant="pin-bias0")
    positions, _, forces = solve(scene).at(run.t)
    assert np.linalg.norm(run.positions - positions, axis=2).max() < 5e-4 * scene.characteristic_length
    rate = np.abs(np.gradient(tensions(scene, positions, forces)[1:], run.t[1:], axis=0)).max()
    assert np.linalg.norm(run.constraint_forces - forces, axis=2)[1:].max() < rate * dt


def test_frame_and_constraint_error():
    scene = catalog.build("chain", {"duration": 1.0})
    run = ENGINE.simulate(scene, 1e-3, variant="pin-bias0")
    assert run.positions.shape == (run.n_samples, 4, 3)
    assert run.constraint_forces.shape == (run.n_samples, 4, 3)
    # Planar scenes come back in the x–z plane with y exactly 0.
    assert not run.positions[:, :, 1].any() and not run.velocities[:, :, 1].any()
    # Full correction each step leaves only the drift of one step,
    # v²·dt²/(2·l) ≈ 25·1e-6/0.5 = 5e-5 m at most for these 0.25 m links
    # (measured 6e-5 m over a 1 s swing): bound 2e-4 m.
    assert max_constraint_error(scene, run.positions).max() < 2e-4
    assert run.info.settings["override.PinJoint.distance"].startswith("the scene's length")
    assert run.info.wall_time > 0 and run.info.steps == 1000


def test_blow_up_ends_unstable_with_samples_so_far():
    # The scene language refuses speeds past 1e6 m/s (engines/scene/limits.py), so the bead is made to run
    # away instead: the fastest spin and strongest gravity allowed, with pymunk's error correction off.
    scene = catalog.build("bead", {"omega0": 1e6, "radius": 1e-6, "g": 1e6, "duration": 0.1})
    run = ENGINE.simulate(scene, 1e-3, variant="pin", options={"error_bias": 1.0})
    assert run.info.status == "unstable"
    assert run.n_samples >= 1 and np.isfinite(run.positions).all()


@pytest.mark.parametrize(
    "options, message",
    [
        ({"error_bias": 1.5}, r"error_bias must be in \[0, 1\]"),
        ({"iterations": 0}, "iterations must be at least 1"),
        ({"damping": 0}, r"damping must be in \(0, 1\]"),
        ({"max_bias": -1}, "max_bias must be a number >= 0"),
        ({"error_bias": "x"}, "error_bias must be a finite number"),
    ],
)
def test_bad_options_name_the_option(options, message):
    scene = catalog.build("bead", {"duration": 0.1})
    with pytest.raises(UserError, match=message):
        ENGINE.simulate(scene, 1e-3, options=options)
