"""The figures of docs/gradients.md on ours' own derivatives of its rigid bodies (a model file).

Run:  .venv/bin/python scripts/rigid_gradient_figures.py      (about a minute once compiled)

The KUKA iiwa (pybullet_data:kuka_iiwa/model.urdf, q0 joint 2 = 30°, joint 4 = −45°), T = 1 s,
d (q, v)(T) / d (q0.lbr_iiwa_joint_2, v0.lbr_iiwa_joint_4, q0.lbr_iiwa_joint_6), ours/baumgarte-rk4 by its
tangent-linear rigid step (engines/ours/rigid_gradients.py; projection's by complex step): the relative Frobenius error against
the reference's variational equations (Pinocchio's derivatives under DOP853) at dt 2e-3, 1e-3 and 5e-4 s, the
observed orders between them, and its self-consistency: against central differences of its own rollouts at the
harness's step (h = 1e-4, engines.gradients.parameter_step) and at a quarter of it. The errors are RK4's
truncation (1e-8 to 1e-5), far above round-off (the reference's own error is 7e-12), so their two digits hold
on any machine; the self-consistency is the differences' own O(h⁴) truncation (it falls 4⁴-fold with h/4
until round-off), quoted with an interval. Then the same two self-consistencies for every method and integrator
ours' rigid bodies offer, the worst of each, and the range of observed orders from dt 1e-3 to 5e-4 s over the
three cures with midpoint and with RK4 (truncation errors of 1e-8 to 1e-2: two decimals hold anywhere).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, load_quotes, report  # noqa: E402

import numpy as np  # noqa: E402

from compare.gradients.measure import engine_case  # noqa: E402
from engines import registry  # noqa: E402
from engines.gradients import STEP, finite_difference_jacobian  # noqa: E402
from engines.model.scene import model_scene  # noqa: E402
from engines.reference.sensitivity import bound_sensitivity, relative_error  # noqa: E402
from ours.rigid import valid_pairs  # noqa: E402

MODEL = "pybullet_data:kuka_iiwa/model.urdf"
Q0 = {"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}
WRT = ["q0.lbr_iiwa_joint_2", "v0.lbr_iiwa_joint_4", "q0.lbr_iiwa_joint_6"]
VARIANT = "ours/baumgarte-rk4"
DTS = (2e-3, 1e-3, 5e-4)


def kuka():
    return model_scene("kuka", MODEL, q0=Q0, duration=1.0)


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    scene = kuka()
    bound = bound_sensitivity(scene, WRT)
    engine, variant = registry.resolve(VARIANT)
    for dt in DTS[:2]:  # each case runs at dt and dt/2: 2e-3 and 1e-3 cover all three steps
        case = engine_case(engine, variant, None, scene, dt, WRT, bound)
        f[f"method_analytic|{dt:g}"] = float(case.method == "analytic")
        f[f"error|{dt:g}"], f[f"error|{dt / 2:g}"] = case.error, case.error_half
        f[f"correct|{dt:g}"] = float(case.klass == "correct")
        if dt == 1e-3:
            f["self_consistency"] = case.self_consistency
            own = engine.jacobian(scene, variant, None, dt, WRT)[0]
            fine = finite_difference_jacobian(engine, scene, variant, None, dt, WRT, relative=STEP / 4).jacobian
            f["self_consistency_quarter_step"] = relative_error(own, fine)
    if quick:  # every pair's self-consistency and orders: tests/test_gradients_ours_rigid.py asserts them
        f["order|2e-3"] = math.log2(f["error|0.002"] / f["error|0.001"])
        f["order|1e-3"] = math.log2(f["error|0.001"] / f["error|0.0005"])
        return f
    harness, quarter = [], []
    for method, integrator in valid_pairs():  # every method and integrator: own derivatives against own differences
        engine, variant = registry.resolve(f"ours/{method}-{integrator}")
        own = engine.jacobian(scene, variant, None, 1e-3, WRT)[0]
        harness.append(relative_error(own, finite_difference_jacobian(engine, scene, variant, None, 1e-3,
                                                                      WRT).jacobian))
        quarter.append(relative_error(own, finite_difference_jacobian(engine, scene, variant, None, 1e-3, WRT,
                                                                      relative=STEP / 4).jacobian))
    f["pairs|self_consistency_worst"], f["pairs|self_consistency_quarter_step_worst"] = max(harness), max(quarter)
    reference = bound.sensitivity.jacobian(np.array([1.0]))[0]
    for integrator in ("midpoint", "rk4"):  # each cure's observed order from dt 1e-3 to 5e-4 s
        orders = []
        for method in ("plain", "baumgarte", "projection"):
            engine, variant = registry.resolve(f"ours/{method}-{integrator}")
            coarse, fine = (relative_error(engine.jacobian(scene, variant, None, dt, WRT)[0], reference)
                            for dt in (1e-3, 5e-4))
            orders.append(math.log2(coarse / fine))
        f[f"orders|{integrator}_low"], f[f"orders|{integrator}_high"] = min(orders), max(orders)
    f["order|2e-3"] = math.log2(f["error|0.002"] / f["error|0.001"])
    f["order|1e-3"] = math.log2(f["error|0.001"] / f["error|0.0005"])
    return f


D = "docs/gradients.md"
ROWS: list[Row] = []
QUOTES: list[Quote] = load_quotes(__file__)
#: Left out of ``figures(quick=True)``: every method and integrator, twelve Jacobians and 24 difference sweeps.
SLOW: set[str] = {"pairs|self_consistency_worst", "pairs|self_consistency_quarter_step_worst", "orders|midpoint_low",
                  "orders|midpoint_high", "orders|rk4_low", "orders|rk4_high"}


def main() -> None:
    f = figures()
    lines = [f"{VARIANT} on the KUKA iiwa, T = 1 s, d (q, v)(T) / d ({', '.join(WRT)}):",
             *(f"  dt {dt:g} s: error {f[f'error|{dt:g}']:.2g}" for dt in DTS),
             f"  observed order {f['order|2e-3']:.2f} (2e-3 to 1e-3 s), {f['order|1e-3']:.2f} (1e-3 to 5e-4 s); class "
             f"correct at 1e-3: {bool(f['correct|0.001'])}, method analytic: {bool(f['method_analytic|0.001'])}",
             f"  self-consistency at dt 1e-3: {f['self_consistency']:.2g} against differences at h = 1e-4 (the "
             f"harness's), {f['self_consistency_quarter_step']:.2g} at h = 2.5e-5",
             f"  every method and integrator: self-consistency at most {f['pairs|self_consistency_worst']:.2g} at "
             f"h = 1e-4, {f['pairs|self_consistency_quarter_step_worst']:.2g} at h = 2.5e-5",
             *(f"  every method with {i}: observed order {f[f'orders|{i}_low']:.2f} to {f[f'orders|{i}_high']:.2f} "
               f"(dt 1e-3 to 5e-4 s)" for i in ("midpoint", "rk4"))]
    print("\n".join(lines))
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
