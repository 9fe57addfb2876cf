"""ours' tangent-linear step (ours/tangent.py, ours.sensitivity.forward_sensitivities) held to the complex step
through the kernel's own step (complex_step_sensitivities), an independent computation of the same derivative:
every cure and integrator, initial conditions and physical parameters (g, masses, lengths), on the bead, the
double pendulum and a chain of 8."""

from __future__ import annotations

import numpy as np
import pytest

import ours
from engines import registry
from engines.ours.adapter import _to_system
from engines.ours.gradients import directions
from engines.scene.catalog import build
from ours.constraint import Ellipse, Line, Pin, Rod
from ours.sensitivity import ModelDirections, complex_step_sensitivities, forward_sensitivities

#: Each scene with every parameter it has (initial conditions and physical ones), over 0.5 s.
SCENES = {"bead": ("bead", {"duration": 0.5}, ["theta0", "omega0", "g", "m", "radius"]),
          "double-pendulum": ("double-pendulum", {"duration": 0.5},
                              ["theta1", "omega2", "g", "m1", "m2", "l1", "l2"]),
          "chain-8": ("chain", {"n": 8, "duration": 0.5}, ["theta0", "g", "mass", "length"])}
#: Every cure with each of its integrators (ours.valid_pairs), lagrangian aside (its own kernel, not differentiated).
VARIANTS = [name for name in registry.resolve("ours/rattle")[0].variants if not name.startswith("lagrangian")]
DT = 1e-3


def _within(a: np.ndarray, b: np.ndarray, tolerance: float = 1e-10) -> bool:
    """‖a − b‖ ≤ tolerance ‖b‖ (Frobenius): relative, and exact where b is zero (a state at rest)."""
    return bool(np.linalg.norm(a - b) <= tolerance * np.linalg.norm(b))


def _both(key: str, variant: str):
    name, parameters, wrt = SCENES[key]
    scene = build(name, parameters)
    system, q0, v0, dq0, dv0, dmodel, _ = directions(scene, wrt, _to_system)
    engine, _ = registry.resolve(f"ours/{variant}")
    s = engine.resolve(variant, None)
    settings = dict(dmodel=dmodel, method=s["method"], integrator=s["integrator"], k_s=s["k_s"], k_d=s["k_d"],
                    tolerance=s["tolerance"], max_iterations=s["max_iterations"], sample_every=100)
    steps = round(scene.duration / DT)
    return (forward_sensitivities(system, q0, v0, dq0, dv0, DT, steps, **settings),
            complex_step_sensitivities(system, q0, v0, dq0, dv0, DT, steps, **settings))


@pytest.mark.parametrize("key", list(SCENES))
@pytest.mark.parametrize("variant", VARIANTS)
def test_the_tangent_linear_step_is_the_complex_step_to_round_off(variant, key):
    """d (q, v)(t) / d p at every sample, every parameter of the scene: within 1e-10 relative of the complex step
    (both exact to round-off), and the real state the same to round-off (a complex product's real part may round
    its last bit otherwise where LLVM fuses a multiply and an add)."""
    tangent, complex_step = _both(key, variant)
    assert tangent.status == complex_step.status == "ok"
    assert _within(tangent.q, complex_step.q, 1e-11) and _within(tangent.v, complex_step.v, 1e-11)
    for s in range(len(tangent.sample_steps)):
        assert _within(tangent.sample_dq[s], complex_step.sample_dq[s])
        assert _within(tangent.sample_dv[s], complex_step.sample_dv[s])


def test_the_tangent_run_is_the_real_run_to_round_off():
    """The tangent run's real state is ours.simulate's exactly, model moving or not: the derivative is that of the
    run itself, every branch (a Newton or SHAKE stop) taken as there."""
    system = ours.System((1.0, 2.0), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0), Rod(0, 1, 0.5)))
    q0, v0 = np.array([[1.0, 0.0], [1.0, -0.5]]), np.array([[0.0, 0.3], [0.1, 0.0]])
    moved = ModelDirections.of(lambda d: ours.System((1.0 + d, 2.0), (0.0, -9.81 + d),
                                                     (Pin(0, (0.0, 0.0), 1.0), Rod(0, 1, 0.5 + d))), 1e-4)
    for method, integrator in ours.valid_pairs():
        if method == "lagrangian":
            continue
        run = ours.simulate(system, q0, v0, 2e-3, 300, 300, method=method, integrator=integrator)
        for dmodel in (None, moved):
            carried = forward_sensitivities(system, q0, v0, np.ones((1, 2, 2)), np.zeros((1, 2, 2)), 2e-3, 300,
                                            dmodel=dmodel, method=method, integrator=integrator)
            assert carried.status == "ok"
            # The kernel's own functions, compiled into a second module: bit for bit on this machine, but a
            # compiler may fuse a multiply-add differently there, so the bound is round-off, not equality.
            scale = np.abs(run.q[-1]).max() + np.abs(run.v[-1]).max()
            assert np.abs(carried.q - run.q[-1]).max() <= 1e-12 * scale
            assert np.abs(carried.v - run.v[-1]).max() <= 1e-12 * scale


@pytest.mark.parametrize("method", ["baumgarte", "projection", "rattle"])
def test_curve_constraints_and_three_dimensions_match_the_complex_step(method):
    """A bead on a line and one on an ellipse (the curve kinds' closed forms), and a 3-D double pendulum, with the
    model moving (a mass, the gravity, the ellipse's axis): tangent against complex step ≤ 1e-10."""
    integrator = "rattle" if method == "rattle" else "rk4"
    cases = [
        (lambda d: ours.System((1.0 + d, 2.0), (0.0, -9.81 + d),
                               (Ellipse(0, (0.0, 0.0), (1.5 + d, 1.0)), Line(1, (0.0, -2.0), (1.0, 0.2 + d)))),
         np.array([[1.5, 0.0], [0.5, -1.9]]), np.array([[0.0, 0.4], [0.3, 0.06]])),
        (lambda d: ours.System((1.0, 1.0 + d), (0.0, 0.0, -9.81 + d),
                               (Pin(0, (0.0, 0.0, 0.0), 1.0 + d), Rod(0, 1, 1.0))),
         np.array([[1.0, 0.0, 0.0], [1.0, 0.0, -1.0]]), np.array([[0.0, 0.5, 0.0], [0.0, 0.5, 0.2]])),
    ]
    rng = np.random.default_rng(3)
    for build_system, q0, v0 in cases:
        system = build_system(0.0)
        dq0, dv0 = rng.standard_normal((2, *q0.shape)), rng.standard_normal((2, *q0.shape))
        dmodel = ModelDirections.stack([ModelDirections.zeros(system, 1), ModelDirections.of(build_system, 1e-4)])
        settings = dict(dmodel=dmodel, method=method, integrator=integrator, sample_every=200)
        tangent = forward_sensitivities(system, q0, v0, dq0, dv0, 1e-3, 400, **settings)
        complex_step = complex_step_sensitivities(system, q0, v0, dq0, dv0, 1e-3, 400, **settings)
        assert tangent.status == complex_step.status == "ok"
        assert _within(tangent.dq, complex_step.dq) and _within(tangent.dv, complex_step.dv)


def test_model_directions_of_the_wrong_shape_are_refused_in_one_line():
    system = ours.System((1.0,), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0),))
    with pytest.raises(ours.OursError, match=r"dmodel.inverse_mass: expected shape \(2, 1\) \(directions × the "
                                             r"packed array\), got \(1, 1\)"):
        forward_sensitivities(system, [[1.0, 0.0]], [[0.0, 0.0]], np.zeros((2, 1, 2)), np.zeros((2, 1, 2)), 1e-3, 10,
                              dmodel=ModelDirections.zeros(system, 1))
