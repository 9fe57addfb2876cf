"""ours' own derivatives of its rigid bodies (ours/rigid/sensitivity.py, ours/rigid/tangent.py,
engines/ours/rigid_gradients.py): the tangent-linear rigid step (method analytic), checked against the complex step
through the compiled rigid step, on model files. Correct
against the reference (Pinocchio's derivatives under DOP853) at RK4's order on the KUKA iiwa and a cart-pole (a prismatic joint), self-consistent with differences of
its own rollouts for every method and integrator."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from compare.gradients.measure import engine_case
from conftest import RIGID_COMPILE, run_xval
from engines import registry
from engines.gradients import STEP, finite_difference_jacobian
from engines.model.scene import model_scene
from engines.reference.sensitivity import bound_sensitivity, reference_jacobian, relative_error
from ours import OursError
from ours.rigid import initial_state, simulate, valid_pairs
from ours.rigid.sensitivity import complex_step_sensitivities, forward_sensitivities
from rigid_support import compound_double_pendulum

pytestmark = RIGID_COMPILE

KUKA_WRT = ["q0.lbr_iiwa_joint_2", "v0.lbr_iiwa_joint_4", "q0.lbr_iiwa_joint_6"]


@pytest.fixture(scope="module")
def kuka():
    """The KUKA iiwa as tests/test_gradients_engines.py differentiates it, with the reference's bound."""
    scene = model_scene("kuka", "pybullet_data:kuka_iiwa/model.urdf",
                        q0={"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}, duration=1.0)
    return scene, bound_sensitivity(scene, KUKA_WRT)


def test_kuka_rk4_is_analytic_correct_to_1e_6_and_self_consistent(kuka):
    """The issue's bar for ours on the KUKA: RK4 at dt 1e-3 over 1 s, method analytic (the tangent-linear step),
    class correct, error ≤ 1e-6 (measured 9.1e-7, RK4's truncation: differences of ours' rollouts give the same), self-consistency ≤ 1e-6
    (measured 4.7e-8, the differences' own O(h⁴) truncation at the harness's step h = 1e-4)."""
    scene, bound = kuka
    engine, variant = registry.resolve("ours/baumgarte-rk4")
    case = engine_case(engine, variant, None, scene, 1e-3, KUKA_WRT, bound)
    assert case.method == "analytic" and case.klass == "correct"
    assert case.error <= 1e-6 and case.self_consistency is not None and case.self_consistency <= 1e-6
    assert case.times is not None and len(case.times) == 101 and case.error_over_time is not None
    assert np.all(case.error_over_time <= 1e-6)


def test_kuka_rk4_gradient_error_falls_at_fourth_order(kuka):
    """The error against the reference at dt 2e-3, 1e-3 and 5e-4 s falls at RK4's order: log2 of each ratio
    within 4 ± 0.5 (measured 4.08 and 4.05)."""
    scene, bound = kuka
    engine, variant = registry.resolve("ours/baumgarte-rk4")
    reference = bound.sensitivity.jacobian(np.array([1.0]))[0]
    errors = [relative_error(engine.jacobian(scene, variant, None, dt, KUKA_WRT)[0], reference)
              for dt in (2e-3, 1e-3, 5e-4)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(3.5 <= order <= 4.5 for order in orders), (errors, orders)


@pytest.mark.parametrize("method", ["plain", "baumgarte", "projection"])
@pytest.mark.parametrize("integrator, order", [("midpoint", 2), ("rk4", 4)])
def test_every_method_converges_at_its_integrators_order_on_the_kuka(kuka, method, integrator, order):
    """From dt 1e-3 to 5e-4 s the error against the reference falls at the integrator's order within 0.3 (measured
    1.99 to 2.04 for midpoint, 4.01 to 4.05 for RK4), whatever the drift cure. The first-order steps are left out:
    on this arm they are not yet in their asymptotic range at these steps."""
    scene, bound = kuka
    variant = f"{method}-{integrator}"
    engine, _ = registry.resolve(f"ours/{variant}")
    reference = bound.sensitivity.jacobian(np.array([1.0]))[0]
    coarse, fine = (relative_error(engine.jacobian(scene, variant, None, dt, KUKA_WRT)[0], reference)
                    for dt in (1e-3, 5e-4))
    assert abs(math.log2(coarse / fine) - order) <= 0.3, (coarse, fine)


@pytest.mark.parametrize("method, integrator", valid_pairs())
def test_every_method_and_integrator_is_self_consistent_on_the_kuka(method, integrator):
    """Against central differences (with Richardson) of ours' own rollouts at a quarter of the harness's step:
    ≤ 1e-7 (measured 2.2e-10 to 1.7e-8). At the harness's step (h = 1e-4) the first-order steps' differences are
    themselves off by up to 4.5e-6 (projection-symplectic-euler): the gap falls 16-fold per halving of h, O(h⁴),
    so it is the differences', not the complex step's."""
    scene = model_scene("kuka", "pybullet_data:kuka_iiwa/model.urdf",
                        q0={"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}, duration=1.0)
    variant = f"{method}-{integrator}"
    engine, _ = registry.resolve(f"ours/{variant}")
    own = engine.jacobian(scene, variant, None, 1e-3, KUKA_WRT)
    assert own is not None and own[1] == "analytic"
    differences = finite_difference_jacobian(engine, scene, variant, None, 1e-3, KUKA_WRT, relative=STEP / 4)
    assert relative_error(own[0], differences.jacobian) <= 1e-7


def test_a_prismatic_joint_is_correct_and_self_consistent():
    """The cart-pole (a prismatic slider, a continuous hinge), every parameter: RK4 within 1e-9 of the reference
    (measured 6.4e-11) and self-consistent to 1e-9 (2.5e-11)."""
    scene = model_scene("cart-pole", "models/cart_pole.urdf", q0={"slider": 0.1, "hinge": 60}, v0={"slider": 0.5},
                        duration=1.0)
    engine, variant = registry.resolve("ours/baumgarte-rk4")
    case = engine_case(engine, variant, None, scene, 1e-3, ["q0.slider", "q0.hinge", "v0.slider", "v0.hinge"])
    assert case.method == "analytic" and case.klass == "correct"
    assert case.error <= 1e-9 and case.self_consistency is not None and case.self_consistency <= 1e-9


def test_the_complex_runs_real_parts_are_the_real_run():
    """Every branch goes as in the run being differentiated: the complex run's real parts are ours.rigid.simulate's
    states to round-off (a fused multiply-add may meet a complex product differently in the last bit), and its
    steps and status are the same."""
    mech = compound_double_pendulum()
    y0 = initial_state(mech, {"shoulder": 1.0, "elbow": -0.5}, {"elbow": 0.3})
    direction = np.random.default_rng(1).normal(size=(2, y0.size))
    for method, integrator in (("baumgarte", "rk4"), ("projection", "symplectic-euler"), ("plain", "midpoint")):
        run = simulate(mech, y0, 2e-3, 300, 100, method=method, integrator=integrator)
        carried = complex_step_sensitivities(mech, y0, direction, 2e-3, 300, 100, method=method, integrator=integrator)
        assert carried.status == run.status == "ok" and carried.steps == run.steps
        assert np.array_equal(carried.t, run.t) and carried.dy.shape == (len(run.t), 2, y0.size)
        assert np.abs(carried.y - run.y).max() <= 1e-12 * np.abs(run.y).max()
        assert np.allclose(carried.dy[0], direction, rtol=1e-15, atol=0.0)  # (h d) / h, h = 1e-30: to the last bit


@pytest.mark.parametrize("carry", [forward_sensitivities, complex_step_sensitivities])
def test_bad_directions_are_refused_naming_the_shape(carry):
    mech = compound_double_pendulum()
    y0 = initial_state(mech)
    with pytest.raises(OursError, match=r"dy0: expected k ≥ 1 directions of 26 finite numbers each, \(k, 13 nb\), "
                                        r"got shape \(1, 25\)"):
        carry(mech, y0, np.zeros((1, 25)), 1e-3, 10)


@pytest.mark.parametrize("model, variant", [("models/cart_pole.urdf", "baumgarte-rk4"),
                                            ("models/double_pendulum.urdf", "baumgarte-rk4")])
def test_a_floating_base_is_left_to_differences_of_rollouts(model, variant):
    """ours' own derivatives cover fixed bases; a floating base (or a model ours refuses: the double pendulum's
    massless support, floating) answers None, and the harness differentiates its rollouts."""
    scene = model_scene("floating", model, duration=1.0, root_joint="floating")
    engine, _ = registry.resolve(f"ours/{variant}")
    assert engine.jacobian(scene, variant, None, 1e-3, [f"q0.{scene.joint_names[0]}"]) is None


def test_a_variant_rigid_bodies_refuse_answers_none():
    scene = model_scene("cart-pole", "models/cart_pole.urdf", duration=1.0)
    for variant in ("rattle", "lagrangian-rk4"):
        engine, _ = registry.resolve(f"ours/{variant}")
        assert engine.jacobian(scene, variant, None, 1e-3, ["q0.hinge"]) is None


def test_the_reference_and_ours_agree_on_the_cart_pole_at_every_sample():
    """J over time, not only at T: at each of the 101 samples of 1 s, within 1e-9 of the reference's (relative to
    the reference's norm at that sample)."""
    scene = model_scene("cart-pole", "models/cart_pole.urdf", q0={"hinge": 30}, duration=1.0)
    wrt = ["q0.hinge", "v0.slider"]
    engine, variant = registry.resolve("ours/baumgarte-rk4")
    own = engine.jacobian(scene, variant, None, 1e-3, wrt)
    assert own is not None
    _, _, times, over_time = own
    assert np.allclose(times, np.arange(101) * 0.01)
    reference = np.array([reference_jacobian(scene, wrt, t) for t in times[1::20]])
    assert np.all(relative_error(over_time[1::20], reference) <= 1e-9)


def test_xval_grad_on_a_model_file_answers_with_ours_own_derivatives():
    """The command a user runs: ``xval grad --model FILE --engine ours``, its JSON naming method analytic (measured
    on the cart-pole: error 6.4e-11, self-consistency 2.0e-11). The timeout covers a first compile of the
    tangent-linear kernel in a fresh cache."""
    done = run_xval("grad", "--model", "models/cart_pole.urdf", "--engine", "ours", "--dt", "1e-3", "--duration", "1",
                    "--param", "q0.hinge=60", "--wrt", "q0.hinge,v0.slider", "--format", "json", timeout=900)
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["engine"] == "ours/baumgarte-rk4" and answer["method"] == "analytic" and answer["class"] == "correct"
    assert answer["outputs"] == ["q_slider", "q_hinge", "v_slider", "v_hinge"]
    assert answer["wrt"] == ["q0.hinge", "v0.slider"]
    assert answer["error"] <= 1e-9 and answer["self_consistency"] <= 1e-9


def _kuka_and_cart_pole():
    """(name, mechanism, y0) of the KUKA iiwa (q0 0.3 rad and v0 0.1 rad/s at every joint) and the cart-pole
    (slider 0.1 m at 0.5 m/s, hinge 1 rad at −0.7 rad/s), as ours translates their files."""
    from engines.model.source import resolve
    from engines.model.urdf import read
    from engines.ours.model import translate

    out = []
    for name, path, q0, v0 in (
            ("kuka", "pybullet_data:kuka_iiwa/model.urdf", 0.3, 0.1),
            ("cart-pole", "models/cart_pole.urdf", {"slider": 0.1, "hinge": 1.0}, {"slider": 0.5, "hinge": -0.7})):
        description = read(resolve(path))
        mech = translate(description).mechanism
        names = [j.name for j in description.moving_joints]
        q = q0 if isinstance(q0, dict) else dict.fromkeys(names, q0)
        v = v0 if isinstance(v0, dict) else dict.fromkeys(names, v0)
        out.append((name, mech, initial_state(mech, q, v)))
    return out


@pytest.fixture(scope="module")
def systems():
    """The KUKA iiwa, the cart-pole (a prismatic joint) and the compound double pendulum, each with its start."""
    pendulum = compound_double_pendulum()
    return [*_kuka_and_cart_pole(),
            ("double pendulum", pendulum, initial_state(pendulum, {"shoulder": 1.0, "elbow": -0.5}, {"elbow": 0.3}))]


@pytest.mark.parametrize("method, integrator", valid_pairs())
def test_the_tangent_step_is_the_complex_step_at_every_sample(systems, method, integrator):
    """The tangent-linear step (each direction's derivative by hand, the solve's through the real factor) against the
    complex step through the compiled step (independent: no code shared but the real run's): at every sample of 1 s
    at dt 1e-3 s (100 samples), along three random directions of the whole state (the joints pulled apart too),
    within 1e-10 of the complex step's largest entry at that sample (measured at most 4.5e-12). Projection's
    iterations are differentiated iterate by iterate, as the complex step does. Its real run is ours.rigid.simulate's
    bit for bit, with the same steps and status."""
    for name, mech, y0 in systems:
        directions = np.random.default_rng(7).normal(size=(3, y0.size))
        options = dict(method=method, integrator=integrator)
        run = simulate(mech, y0, 1e-3, 1000, 10, **options)
        tangent = forward_sensitivities(mech, y0, directions, 1e-3, 1000, 10, **options)
        complex_step = complex_step_sensitivities(mech, y0, directions, 1e-3, 1000, 10, **options)
        assert tangent.status == complex_step.status == run.status == "ok", name
        assert tangent.steps == run.steps == 1000 and np.array_equal(tangent.t, run.t), name
        # The real step is the kernel's own, compiled into a second module: bit for bit here, but a compiler may
        # fuse a multiply-add differently there, so the bound is round-off, not equality.
        assert np.abs(tangent.y - run.y).max() <= 1e-12 * np.abs(run.y).max(), name
        assert tangent.dy.shape == complex_step.dy.shape == (101, 3, y0.size), name
        scale = np.abs(complex_step.dy).max(axis=(1, 2))
        gap = np.abs(tangent.dy - complex_step.dy).max(axis=(1, 2)) / scale
        assert np.all(gap <= 1e-10), (name, gap.max())


def test_the_tangent_steps_stamp_is_the_kernels_digest():
    """ours/rigid/tangent.py's compiled step inlines the kernel's, and numba's cache of it follows tangent.py's stamp
    alone: the kernel's digest written there (python -m ours.rigid.generate) must be the kernel's."""
    from ours.rigid import generate, tangent

    assert tangent.KERNEL_DIGEST == generate.digest(generate.KERNEL.read_text(encoding="utf-8"))
