"""Mechanisms: the line and ellipse kinds, the three catalog scenes, and their references against closed forms.

- slider-pendulum: horizontal momentum conserved and the small-oscillation
  frequency √(g (M + m) / (M l)), both to 1e-9;
- four-bar: loop closure held to 1e-10 (also through a near-toggle pass) and
  the small-oscillation frequency against a linearised one-coordinate model
  built here from the geometry alone;
- bead-ellipse: with a = b, the circle bead to round-off.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from engines.scene import catalog
from engines.scene.catalog import four_bar_joint
from engines.errors import SceneError, Unsupported
from engines.reference.reference import model_for as model_for_check, solve
from engines.reference.mechanisms import EllipseBead, FourBar, SliderPendulum
from engines.scene.scene import Ellipse, Line, Particle, Rod, Scene, ellipse_distance
from engines.scene.trajectory import (
    constraint_errors,
    free_direction,
    linear_momentum,
    linear_momentum_drift,
    total_energy,
)


def _crossing_period(signal, t_end: float, n: int = 4000) -> tuple[float, int]:
    """Mean interval (s) between upward zero crossings of ``signal(times)``, each located by brentq."""
    ts = np.linspace(0.0, t_end, n)
    x = signal(ts)
    idx = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    roots = [brentq(lambda t: signal(np.array([t]))[0], ts[i], ts[i + 1], xtol=1e-15) for i in idx]
    return float(np.diff(roots).mean()), len(roots)


# -- the scene language ---------------------------------------------------------------------


def test_new_kinds_round_trip_through_json_exactly():
    scene = Scene(
        "mixed",
        (Particle(2.0, (0.3, 0.0, 0.0), (0.1, 0.0, 0.0)), Particle(1.0, (0.3, 0.0, -1.0)),
         Particle(1.0, (1.5, 0.0, 0.0))),
        (Line(0, (0.0, 0.0, 0.0), (3.0, 0.0, 0.0)), Rod(0, 1, 1.0), Ellipse(2, (0.0, 0.0, 0.0), 1.5, 0.5)),
        duration=1.0,
    )
    data = json.loads(scene.to_json())
    assert data["constraints"][0] == {"kind": "line", "particle": 0, "point": [0.0, 0.0, 0.0],
                                      "direction": [3.0, 0.0, 0.0]}
    assert data["constraints"][2] == {"kind": "ellipse", "particle": 2, "centre": [0.0, 0.0, 0.0],
                                      "semi_x": 1.5, "semi_z": 0.5}
    again = Scene.from_dict(data)
    assert again == scene and again.content_hash == scene.content_hash
    assert again.constraints[0].direction == (3.0, 0.0, 0.0)  # kept as given, not normalised
    # A Line adds no length; an Ellipse its larger semi-axis.
    assert scene.characteristic_length == pytest.approx(1.0 + 1.5)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: Line(0, (0, 0, 0), (0, 0, 0)), r"^line\.direction: must be a nonzero vector"),
        (lambda: Line(0, (0, 0, 0), (1, 0, math.inf)), r"^line\.direction: every component must be finite"),
        (lambda: Ellipse(0, (0, 0, 0), 0.0, 1.0), r"^ellipse\.semi_x: must be positive and finite, got 0\.0$"),
        (lambda: Ellipse(0, (0, 0, 0), 1.0, -2.0), r"^ellipse\.semi_z: must be positive and finite"),
        (lambda: Line(1.5, (0, 0, 0), (1, 0, 0)), r"^line\.particle: must be a particle index"),
    ],
)
def test_bad_constraint_fields_are_named(build, message):
    with pytest.raises(SceneError, match=message):
        build()


def test_a_particle_off_its_curve_or_leaving_it_is_refused():
    with pytest.raises(SceneError, match=r"^constraints\[0\] \(line\): particle 0 starts 0\.1 m off the line; place it on the line$"):
        Scene("s", (Particle(1.0, (0.0, 0.0, 0.1)),), (Line(0, (0, 0, 0), (1, 0, 0)),))
    with pytest.raises(SceneError, match=r"initial velocity of particle 0 leaves the ellipse"):
        Scene("s", (Particle(1.0, (0.0, 0.0, -0.5), (0.0, 0.0, 1.0)),), (Ellipse(0, (0, 0, 0), 2.0, 0.5),))
    with pytest.raises(SceneError, match=r"unknown kind 'spline'; use one of \['ellipse', 'line', 'pin', 'rod'\]"):
        Scene.from_dict({"name": "s", "particles": [{"mass": 1, "position": [0, 0, 0]}],
                         "constraints": [{"kind": "spline"}]})


def test_ellipse_distance_is_exact_against_a_refined_search():
    u = np.linspace(0.0, 2.0 * np.pi, 20_001)
    rng = np.random.default_rng(3)
    points = np.vstack([rng.normal(size=(60, 2)), [[0.0, 0.0], [0.5, 0.0], [0.0, 0.3], [2.0, 0.0], [0.0, 2.0]]])
    for a, b in ((1.3, 0.6), (0.6, 1.3)):
        expected = []
        for x, z in points:
            gap = lambda w: math.hypot(a * math.cos(w) - x, b * math.sin(w) - z)  # noqa: E731, B023 (used at once)
            best = u[np.argmin(np.hypot(a * np.cos(u) - x, b * np.sin(u) - z))]
            step = u[1] - u[0]
            expected.append(minimize_scalar(gap, bounds=(best - step, best + step), method="bounded",
                                            options={"xatol": 1e-13}).fun)
        np.testing.assert_allclose(ellipse_distance(points[:, 0], points[:, 1], a, b), expected, rtol=0, atol=1e-11)
    on = np.stack([1.3 * np.cos(u[::97]), 0.6 * np.sin(u[::97])])
    assert ellipse_distance(on[0], on[1], 1.3, 0.6).max() < 1e-15


# -- the catalog --------------------------------------------------------------------------------


def test_four_bar_refuses_only_a_loop_that_cannot_close_naming_the_rule():
    # b = 2.5: the crank tip at 30° is 0.87 m from the rocker pivot, nearer than |b − c| = 1.7.
    expected = (
        "four-bar: lengths a=0.4, b=2.5, c=0.8, d=1 cannot close at theta0 = 30 deg (crank tip 0.8718 m from "
        "the rocker pivot): the coupler b and the rocker c close the loop only when the crank tip's distance "
        "from the rocker pivot lies strictly between |b - c| and b + c"
    )
    with pytest.raises(SceneError, match="^" + re.escape(expected) + "$"):
        catalog.build("four-bar", {"b": 2.5})
    with pytest.raises(SceneError, match=r"^four-bar: parameter branch must be \+1 or -1"):
        catalog.build("four-bar", {"branch": 0})
    # Not Grashof, but closed at theta0: accepted (a triple-rocker; no link turns fully).
    catalog.build("four-bar", {"a": 0.5, "b": 1.0, "c": 0.8, "d": 0.6})


def test_a_triple_rocker_passes_its_dead_points_conserving_energy_with_ours_converging_to_it():
    from engines.ours.adapter import ENGINE as OURS
    from engines.reference.reference import solve
    from engines.scene.trajectory import max_constraint_error, total_energy

    # a = 0.5, b = 1, c = 0.8, d = 0.6: no Grashof crank. Thrown at 6 rad/s from 30°, the crank swings until
    # coupler and rocker fold (its tip |b − c| = 0.2 m from the rocker pivot: the dead point, where a crank
    # angle coordinate is singular) and comes back.
    scene = catalog.build("four-bar", {"a": 0.5, "b": 1.0, "c": 0.8, "d": 0.6, "theta0": 30, "omega0": 6,
                                       "duration": 2})
    t = np.linspace(0.0, 2.0, 201)
    p, v, _ = solve(scene).at(t)
    reach = np.hypot(p[:, 0, 0] - 0.6, p[:, 0, 2])
    assert reach.min() < 0.2 + 1e-4  # measured 0.2000081: at the dead point ...
    crank_rate = p[:, 0, 0] * v[:, 0, 2] - p[:, 0, 2] * v[:, 0, 0]
    assert np.sum(np.diff(np.sign(crank_rate)) != 0) == 1  # ... where the crank turns back
    # Independent checks: energy (measured 1.9e-12 E*) and the loop (6.5e-12 m) hold through it ...
    energy = total_energy(scene, p, v)
    assert np.abs(energy - energy[0]).max() < 1e-9 * scene.characteristic_energy
    assert max_constraint_error(scene, p).max() < 1e-9
    # ... and ours/rattle, second order, converges to it: 5.25e-4 m at dt 1e-3, 1.31e-4 m at 5e-4 (order 2.00).
    errors = []
    for dt in (1e-3, 5e-4):
        run = OURS.simulate(scene, dt, variant="rattle")
        assert run.info.status == "ok"
        errors.append(np.linalg.norm(run.positions - p[: run.n_samples], axis=2).max())
    assert errors[1] < 3e-4 and math.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.2)


@pytest.mark.parametrize("name, field", [("bead-ellipse", "a"), ("bead-ellipse", "b"), ("slider-pendulum", "l")])
def test_a_zero_axis_or_length_is_refused_in_one_line(name, field):
    with pytest.raises(SceneError, match=rf"^{name}: parameter {field} must be positive, got 0$"):
        catalog.build(name, {field: 0})


def test_momentum_is_conserved_only_along_a_free_rail():
    slider = catalog.build("slider-pendulum")
    np.testing.assert_array_equal(free_direction(slider), [1.0, 0.0, 0.0])
    assert free_direction(catalog.build("four-bar")) is None
    assert free_direction(catalog.build("bead-ellipse")) is None
    assert linear_momentum_drift(catalog.build("bead"), np.zeros((3, 1, 3))) is None
    v = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]]])
    np.testing.assert_allclose(linear_momentum(slider, v), [[1.0, 0.0, 2.0]])


# -- the references ---------------------------------------------------------------------------------


def test_slider_pendulum_reference_conserves_momentum_and_energy():
    scene = catalog.build("slider-pendulum", {"theta0": 70, "omega0": 1.5, "M": 0.7, "duration": 10})
    assert isinstance(model_for_check(scene), SliderPendulum)
    positions, velocities, _ = solve(scene).at(np.linspace(0.0, scene.duration, 1001))
    assert linear_momentum_drift(scene, velocities) < 1e-9
    energy = total_energy(scene, positions, velocities)
    assert np.abs(energy - energy[0]).max() < 1e-9 * scene.characteristic_energy
    assert constraint_errors(scene, positions).max() < 1e-12


def test_slider_pendulum_small_oscillation_frequency_to_1e9():
    M, m, l, g = 2.0, 1.0, 0.7, 9.81
    scene = catalog.build("slider-pendulum", {"M": M, "m": m, "l": l, "theta0": 1e-3, "duration": 12})
    solution = solve(scene, rtol=1e-13, atol=1e-16)

    def swing(t):
        q = solution.at(t)[0]
        return q[:, 1, 0] - q[:, 0, 0]  # the bob's offset from the slider

    period, crossings = _crossing_period(swing, scene.duration)
    assert crossings >= 5
    assert 2.0 * math.pi / period / math.sqrt(g * (M + m) / (M * l)) - 1.0 == pytest.approx(0.0, abs=1e-9)


def _four_bar_linearised(a, b, c, d, m0, m1, g, branch=-1):
    """(equilibrium crank angle rad, ω rad/s) of the one-coordinate model: ω² = V''(φ*) / I(φ*).

    Built from the loop geometry alone (catalog.four_bar_joint), with V and ψ differentiated
    numerically: I(φ) = m0 a² + m1 c² (dψ/dφ)², V(φ) = g (m0 z0 + m1 z1).
    """

    def tips(phi):
        p0 = (a * math.sin(phi), -a * math.cos(phi))
        return p0, four_bar_joint(p0, (d, 0.0), b, c, branch)[0]

    def potential(phi):
        p0, p1 = tips(phi)
        return g * (m0 * p0[1] + m1 * p1[1])

    def rocker(phi):
        p1 = tips(phi)[1]
        return math.atan2(p1[0] - d, -p1[1])

    h = 1e-4
    slope = lambda phi: (potential(phi + h) - potential(phi - h)) / (2 * h)  # noqa: E731
    grid = np.linspace(-math.pi, math.pi, 721)
    values = [slope(p) for p in grid]
    start = next(i for i in range(720) if values[i] < 0 <= values[i + 1])
    phi_eq = brentq(slope, grid[start], grid[start + 1], xtol=1e-14)
    h2 = 1e-3
    curvature = (potential(phi_eq + h2) - 2 * potential(phi_eq) + potential(phi_eq - h2)) / h2**2
    k = (rocker(phi_eq + 1e-6) - rocker(phi_eq - 1e-6)) / 2e-6
    return phi_eq, math.sqrt(curvature / (m0 * a * a + m1 * c * c * k * k))


def test_four_bar_small_oscillation_matches_the_linearised_one_coordinate_model():
    a, b, c, d, m0, m1, g = 0.4, 1.2, 0.8, 1.0, 1.0, 1.5, 9.81
    phi_eq, omega = _four_bar_linearised(a, b, c, d, m0, m1, g)
    scene = catalog.build("four-bar", {"m1": m1, "theta0": math.degrees(phi_eq) + 0.1, "duration": 8})
    solution = solve(scene, rtol=1e-13, atol=1e-16)

    def crank(t):
        q = solution.at(np.atleast_1d(t))[0]
        return np.arctan2(q[:, 0, 0], -q[:, 0, 2]) - phi_eq

    period, crossings = _crossing_period(crank, scene.duration)
    assert crossings >= 4
    # The finite differences above limit the model to ~1e-7; an error in the reference's
    # k(φ) or h(φ) would show at the 1e-2 level.
    assert 2.0 * math.pi / period / omega - 1.0 == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    "overrides",
    [{"omega0": 3.0}, {"b": 1.39, "theta0": 0.0, "omega0": 8.0}],
    ids=["turning", "near-toggle"],
)
def test_four_bar_reference_holds_the_loop_closed_to_1e10(overrides):
    scene = catalog.build("four-bar", {**overrides, "duration": 4})
    model = model_for_check(scene)
    assert isinstance(model, FourBar) and model.branch == -1.0
    positions, velocities, forces = solve(scene).at(np.linspace(0.0, scene.duration, 801))
    assert constraint_errors(scene, positions).max() < 1e-10
    energy = total_energy(scene, positions, velocities)
    assert np.abs(energy - energy[0]).max() < 1e-9 * scene.characteristic_energy
    if "b" in overrides:
        # The crank turns through the near-toggle configuration (crank, coupler and rocker almost in one
        # line): J's smallest singular value drops to ~0.04 m there and the loop's forces peak at ~85× the weight.
        crank = np.unwrap(np.arctan2(positions[:, 0, 0], -positions[:, 0, 2]))
        assert crank.max() - crank.min() > 2 * math.pi
        assert _smallest_singular_value(scene, positions).min() < 0.05
        assert np.abs(forces).max() > 50 * 9.81 * scene.masses.sum()


def _smallest_singular_value(scene, positions):
    """(n,) m: σ_min of the four-bar's distance-form Jacobian (rows d₀, d₁, coupler) at each sample."""
    pin0, rod, pin1 = scene.constraints
    out = []
    for q in positions[:, :, [0, 2]]:
        J = np.zeros((3, 4))
        J[0, :2] = q[0] - np.asarray(pin0.anchor)[[0, 2]]
        J[1, :2], J[1, 2:] = q[0] - q[1], q[1] - q[0]
        J[2, 2:] = q[1] - np.asarray(pin1.anchor)[[0, 2]]
        out.append(np.linalg.svd(J, compute_uv=False).min())
    return np.array(out)


def test_reference_forces_obey_newton_on_every_particle():
    for name, overrides in (("slider-pendulum", {"theta0": 70}), ("four-bar", {"omega0": 3}), ("bead-ellipse", {})):
        scene = catalog.build(name, {**overrides, "duration": 2})
        solution = solve(scene)
        t, h = np.linspace(0.5, 1.5, 11), 1e-5
        _, _, forces = solution.at(t)
        acceleration = (solution.at(t + h)[1] - solution.at(t - h)[1]) / (2 * h)
        net = scene.masses[None, :, None] * (acceleration - np.asarray(scene.gravity))
        applied = np.zeros_like(net)
        for k, c in enumerate(scene.constraints):
            if isinstance(c, Rod):
                applied[:, c.a] += forces[:, k]
                applied[:, c.b] -= forces[:, k]
            else:
                applied[:, c.particle] += forces[:, k]
        np.testing.assert_allclose(applied, net, atol=1e-6 * np.abs(net).max())


def test_ellipse_with_equal_axes_is_the_circle_bead_to_round_off():
    for radius in (1.0, 0.7):
        bead = catalog.build("bead", {"radius": radius, "theta0": 60, "omega0": 0.5, "duration": 10})
        wire = catalog.build("bead-ellipse", {"a": radius, "b": radius, "theta0": 60,
                                              "omega0": 0.5, "duration": 10})
        assert isinstance(model_for_check(wire), EllipseBead)
        t = np.linspace(0.0, 10.0, 1001)
        for ours, theirs in zip(solve(bead).at(t), solve(wire).at(t)):
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12)


def test_reference_refuses_a_line_or_ellipse_it_has_no_form_for():
    three_d = Scene("rail-3d", (Particle(1.0, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),),
                    (Line(0, (0, 0, 0), (0, 1, 0)),), duration=1.0)
    with pytest.raises(Unsupported, match="the reference expresses a line only as a planar slider"):
        solve(three_d)
