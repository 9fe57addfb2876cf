"""The DART adapter against closed forms, the reference and MuJoCo, with the real engine.

DART is installed with the test extras (``make test`` installs ``xval[all]``); these tests need it.
Numbers in comments were measured with dartpy 6.20.0
(``.venv/bin/python -m pytest tests/test_engine_dart.py -q -p no:xdist``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from engines.scene import catalog
from engines.reference.closed_form import pendulum_period
from engines.dart.adapter import ENGINE as DART
from engines.errors import Unsupported, UserError
from engines.mujoco.adapter import ENGINE as MUJOCO
from engines.reference.reference import ENGINE as REFERENCE
from engines.registry import resolve

G = 9.81


def crossing_times(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Upward zero crossings of x(t), linearly interpolated between samples."""
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def energy(scene, run) -> np.ndarray:
    """(n,) J: kinetic plus potential energy of the point masses at each sample."""
    m = scene.masses
    kinetic = 0.5 * (m * (run.velocities**2).sum(axis=-1)).sum(axis=1)
    return kinetic + (m * G * run.positions[..., 2]).sum(axis=1)


def position_error(run, reference) -> float:
    return float(np.abs(run.positions - reference.positions).max())


def test_dart_is_registered_with_its_variants():
    engine, variant = resolve("dart/rk4")
    assert engine is DART and variant == "rk4"
    assert DART.variant_ids() == ["dart/world", "dart/rk4"]


# -- the bead's period ---------------------------------------------------------------------


@pytest.mark.parametrize("variant, dt, bound", [
    # Semi-implicit Euler's period error is second order (a phase error): below ω·dt = 3.1e-3.
    ("world", 1e-3, 3.2e-3),
    # RK4: below (ω·dt)^4 ≈ 1e-10 at dt = 1e-3; judged to 1e-6, about what the samples' linear
    # interpolation of the crossings resolves.
    ("rk4", 1e-3, 1e-6),
])
def test_bead_period_matches_the_elliptic_integral(variant, dt, bound):
    scene = catalog.build("bead", {"theta0": 10, "duration": 6.5})  # three full periods
    run = DART.simulate(scene, dt, variant=variant, sample_interval=1e-3)
    assert run.info.status == "ok", run.info.message
    crossings = crossing_times(run.t, run.positions[:, 0, 0])
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert abs(period / pendulum_period(1.0, G, math.radians(10)) - 1) < bound


# -- agreement with the reference and with MuJoCo ---------------------------------------------------


def test_world_step_is_mujoco_hinge_euler():
    # DART's World.step (forward dynamics, velocities, then positions) is MuJoCo's Euler in joint
    # coordinates: with the same point-mass inertia they agree to round-off (measured 4.0e-15 m,
    # 2.0e-14 m/s on the double pendulum over 2 s).
    for name, params in (("double-pendulum", {}), ("chain", {"n": 8})):
        scene = catalog.build(name, {"duration": 2, **params})
        dart = DART.simulate(scene, 1e-3, variant="world", options={"inertia_ratio": 1e-9})
        mujoco = MUJOCO.simulate(scene, 1e-3, variant="hinge", options={"inertia_ratio": 1e-9})
        assert dart.info.status == "ok" and dart.info.steps == 2000
        assert position_error(dart, mujoco) < 1e-12
        assert np.abs(dart.velocities - mujoco.velocities).max() < 1e-11


def test_rk4_agrees_with_the_reference_and_with_mujoco_hinge_rk4():
    # Double pendulum, 2 s at dt = 1e-3: DART RK4 is 2.1e-10 m off the reference (measured), and equal
    # to MuJoCo's RK4 given MuJoCo's inertia (3.2e-15 m): the same tableau over the same dynamics.
    scene = catalog.build("double-pendulum", {"duration": 2})
    reference = REFERENCE.simulate(scene, 1e-3)
    exact = DART.simulate(scene, 1e-3, variant="rk4")
    assert exact.info.settings["point_mass_inertia"] == [0.0, 0.0]
    assert position_error(exact, reference) < 1e-9
    dart = DART.simulate(scene, 1e-3, variant="rk4", options={"inertia_ratio": 1e-12})
    mujoco = MUJOCO.simulate(scene, 1e-3, variant="hinge-rk4")
    assert position_error(dart, mujoco) < 1e-13


@pytest.mark.parametrize("variant, steps, order", [
    ("world", (5e-3, 2.5e-3, 1.25e-3), 1),  # measured slope 1.00
    ("rk4", (4e-2, 2e-2, 1e-2), 4),  # measured slope 4.03
])
def test_observed_order(variant, steps, order):
    scene = catalog.build("bead", {"theta0": 60, "duration": 1})
    errors = []
    for dt in steps:
        run = DART.simulate(scene, dt, variant=variant)
        assert run.info.steps == round(1 / dt)
        errors.append(position_error(run, REFERENCE.simulate(scene, dt)))
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.2


# -- energy -----------------------------------------------------------------------------------------


def test_energy_world_loses_it_in_proportion_to_dt_and_rk4_keeps_it():
    # Semi-implicit Euler in joint coordinates is not symplectic when the mass matrix depends on the
    # configuration: the double pendulum loses energy, max |E − E0| / E* = 6.6e-3, 3.3e-3 at
    # dt = 1e-3, 5e-4 (measured: first order, as MuJoCo hinge). RK4 at dt = 5e-3: 2.7e-7, at 2.5e-3:
    # 1.8e-8 (fourth order).
    scene = catalog.build("double-pendulum", {"duration": 2})
    scale = scene.characteristic_energy

    def drift(variant: str, dt: float) -> tuple[float, float]:
        e = energy(scene, DART.simulate(scene, dt, variant=variant))
        return float(np.abs(e - e[0]).max() / scale), float((e[-1] - e[0]) / scale)

    (coarse, coarse_final), (fine, fine_final) = drift("world", 1e-3), drift("world", 5e-4)
    assert 1e-3 < coarse < 2e-2 and coarse_final < 0 and fine_final < 0  # lost, not gained
    assert 1.8 < coarse / fine < 2.2
    rk4_coarse, rk4_fine = drift("rk4", 5e-3)[0], drift("rk4", 2.5e-3)[0]
    assert rk4_coarse < 1e-6 and 10 < rk4_coarse / rk4_fine < 20


def test_spherical_pendulum_keeps_its_vertical_angular_momentum():
    # A ball joint (exponential coordinates, 1e-9 inertia): World.step keeps L_z to 8.4e-9 (the
    # inertia's share), the position error is first order (1.34e-3, 6.7e-4 m at dt = 1e-3, 5e-4).
    scene = catalog.build("spherical-pendulum", {"duration": 2})
    errors = []
    for dt in (1e-3, 5e-4):
        run = DART.simulate(scene, dt)
        assert run.info.status == "ok" and run.info.settings["joints"] == ["BallJoint"]
        lz = np.cross(run.positions[:, 0], run.velocities[:, 0])[:, 2]
        assert np.abs(lz - lz[0]).max() < 1e-7
        errors.append(position_error(run, REFERENCE.simulate(scene, dt)))
    assert errors[0] < 2e-3 and 1.8 < errors[0] / errors[1] < 2.2


def test_slider_pendulum_on_a_prismatic_joint():
    # The slider on its line is a prismatic joint: RK4 keeps the horizontal momentum to 2.5e-12 and
    # follows the reference to 4.8e-12 m at dt = 1e-3 (measured).
    scene = catalog.build("slider-pendulum", {"duration": 2})
    run = DART.simulate(scene, 1e-3, variant="rk4")
    assert run.info.settings["joints"] == ["PrismaticJoint", "RevoluteJoint"]
    momentum = (scene.masses * run.velocities[..., 0]).sum(axis=1)
    assert np.abs(momentum - momentum[0]).max() < 1e-9
    assert position_error(run, REFERENCE.simulate(scene, 1e-3)) < 1e-9


# -- what it refuses --------------------------------------------------------------------------------


def test_refusals_name_the_reason():
    with pytest.raises(Unsupported, match=r"dart: constraint 1 closes a loop; the adapter builds a tree of joints"):
        DART.check(catalog.build("four-bar"))
    with pytest.raises(Unsupported, match=r"dart: no DART joint moves a point on an ellipse .*constraints\[0\]"):
        DART.check(catalog.build("bead-ellipse"))
    with pytest.raises(Unsupported, match=r"dart/rk4: a ball joint's positions are a rotation vector"):
        DART.check(catalog.build("spherical-pendulum"), "rk4")
    with pytest.raises(UserError, match=r"dart: option inertia_ratio = -1.0 is outside the allowed range >= 0"):
        DART.simulate(catalog.build("bead"), 1e-3, options={"inertia_ratio": -1})
