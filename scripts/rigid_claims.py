"""Figures and numbers of docs/ours.md's rigid-body chapter (``ours.rigid``), measured here.

Run:  .venv/bin/python scripts/rigid_claims.py
Writes docs/figures/ours/rigid_*.svg and prints every quoted figure against the doc
(tests/test_docs_figures.py checks the quotes). The compound double pendulum and its
reduced-coordinate solution are tests/rigid_support.py's (one definition of each).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

from ours.rigid import (  # noqa: E402
    Body, Mechanism, angular_momentum, energy, frames, initial_state, joint_errors, simulate,
)
from quoted import Row, load_quotes, report  # noqa: E402
from rigid_support import compound_double_pendulum, reduced_double_pendulum  # noqa: E402

OUT = HERE.parent / "docs" / "figures" / "ours"
SLOW: set[str] = set()
THETA, OMEGA = [0.9, -0.6], [0.3, 1.1]
PAIRS = [("plain", "rk4"), ("plain", "symplectic-euler"), ("baumgarte", "rk4"), ("baumgarte", "symplectic-euler"),
         ("projection", "rk4"), ("projection", "symplectic-euler")]
ORDER_DTS = [4e-3, 2e-3, 1e-3]


def _double_start():
    mech = compound_double_pendulum()
    names = ("shoulder", "elbow")
    return mech, initial_state(mech, dict(zip(names, THETA)), dict(zip(names, OMEGA)))


def drift(f: dict, series: dict, duration: float = 20.0, dt: float = 1e-3) -> None:
    """Joint violation and energy error of each pair on the double pendulum over ``duration`` s."""
    mech, y0 = _double_start()
    e0 = energy(mech, y0)
    n = int(round(duration / dt))
    for method, integrator in PAIRS:
        run = simulate(mech, y0, dt, n, 20, method=method, integrator=integrator)
        distance, angle = joint_errors(mech, run.y)
        key = f"{method}_{integrator}".replace("-", "_")
        f[f"off_{key}_20s"] = float(distance.max())
        f[f"angle_{key}_20s"] = float(angle.max())
        f[f"energy_{key}_20s"] = float(np.abs(energy(mech, run.y) - e0).max())
        series[f"{method}-{integrator}"] = (run.t, distance)
        if (method, integrator) == ("plain", "rk4"):
            norms = np.linalg.norm(run.y.reshape(len(run.y), -1, 13)[..., 3:7], axis=-1)
            f["quaternion_norm_plain_rk4_20s"] = float(np.abs(norms - 1.0).max())


def orders(f: dict, series: dict) -> None:
    """Largest link-frame distance from the reduced solution over 2 s, and its observed order."""
    mech, y0 = _double_start()
    times = np.linspace(0.0, 2.0, 51)
    reference = reduced_double_pendulum(THETA, OMEGA, 2.0, times)
    for method, integrator in [("baumgarte", "euler"), ("baumgarte", "symplectic-euler"), ("baumgarte", "midpoint"),
                               ("baumgarte", "rk4"), ("projection", "rk4")]:
        errors = []
        for dt in ORDER_DTS:
            n = int(round(2.0 / dt))
            run = simulate(mech, y0, dt, n, n // 50, method=method, integrator=integrator)
            errors.append(np.linalg.norm(frames(mech, run.y)[0] - reference, axis=-1).max())
        key = f"{method}_{integrator}".replace("-", "_")
        f[f"order_{key}"] = float(np.polyfit(np.log(ORDER_DTS), np.log(errors), 1)[0])
        f[f"error_{key}_dt1e-3"] = float(errors[-1])
        series[f"{method}-{integrator}"] = (ORDER_DTS, errors)


SPINNER_INERTIA = (1.0, 2.0, 3.0)  # kg·m², principal; spun about the intermediate (y) axis
SPINNER_OMEGA = (0.01, 1.0, 0.0)  # rad/s, world = body at t = 0


def spinner(f: dict) -> None:
    """The torque-free body spun about its intermediate axis: energy and momentum errors over 20 s at 1 ms,
    and when it first flips (RK4), against Euler's equations solved by DOP853."""
    mech = Mechanism((Body("box", 1.0, np.zeros(3), np.diag(SPINNER_INERTIA)),), (), np.zeros(3))
    y0 = np.zeros(13)
    y0[3], y0[10:13] = 1.0, SPINNER_OMEGA
    for integrator in ("euler", "symplectic-euler", "midpoint", "rk4"):
        run = simulate(mech, y0, 1e-3, 20_000, 10, method="plain", integrator=integrator)
        key = integrator.replace("-", "_")
        f[f"spinner_energy_{key}"] = float(np.abs(energy(mech, run.y) - energy(mech, y0)).max())
        f[f"spinner_momentum_{key}"] = float(np.linalg.norm(angular_momentum(mech, run.y) - angular_momentum(mech, y0),
                                                             axis=-1).max())
        if integrator == "rk4":
            _, R = frames(mech, run.y)
            f["spinner_flip_rk4"] = first_flip(run.t, np.einsum("sji,sj->si", R[:, 0], run.y[:, 10:13])[:, 1])
    f["spinner_flip_euler_equations"] = euler_equations_flip()


def first_flip(t: np.ndarray, omega_y: np.ndarray) -> float:
    """s: the first time the body-frame ω_y (rad/s) changes sign, linear between samples: the intermediate
    axis has turned over, since (R e_y)·L = I₂ ω_y with L the (constant) angular momentum."""
    k = int(np.argmax(omega_y < 0.0))
    return float(t[k - 1] + (t[k] - t[k - 1]) * omega_y[k - 1] / (omega_y[k - 1] - omega_y[k]))


def euler_equations_flip() -> float:
    """s: the first sign change of ω_y under Euler's equations I ω̇ = (I ω) × ω (body frame), DOP853 at
    rtol 1e-12: the spinner's flip, independent of ours."""
    from scipy.integrate import solve_ivp

    inertia = np.array(SPINNER_INERTIA)

    def crossing(_t, w):
        return w[1]

    crossing.terminal, crossing.direction = True, -1  # type: ignore[attr-defined]
    sol = solve_ivp(lambda _t, w: np.cross(inertia * w, w) / inertia, (0.0, 20.0), SPINNER_OMEGA, method="DOP853",
                    rtol=1e-12, atol=1e-14, events=crossing)
    return float(sol.t_events[0][0])


MODEL = HERE.parent / "models" / "double_pendulum.urdf"


def model_joints(f: dict) -> None:
    """ours' joint gap on a model scene as the constraint-error metric reads it (engines/ours/model.py): the
    double pendulum fixture, q0 = 30°, −20°, 2 s; largest gap at dt = 1 ms and the slope over 4, 2, 1 ms."""
    from engines.model.scene import model_scene
    from engines.registry import resolve
    from engines.scene.trajectory import trajectory_constraint_error

    scene = model_scene("double", str(MODEL), q0={"shoulder": 30, "elbow": -20}, duration=2.0)
    for variant in ("plain-rk4", "baumgarte-rk4", "baumgarte-symplectic-euler", "projection-rk4",
                    "projection-symplectic-euler", "hinge-rk4"):
        engine_id = f"{'mujoco' if variant.startswith('hinge') else 'ours'}/{variant}"
        engine, name = resolve(engine_id)
        errors = [float(trajectory_constraint_error(scene, engine.simulate(scene, dt, variant=name)).max())
                  for dt in (ORDER_DTS if variant.startswith(("plain", "baumgarte")) else ORDER_DTS[-1:])]
        key = engine_id.replace("/", "_").replace("-", "_")
        f[f"model_gap_{key}"] = errors[-1]
        if len(errors) > 1:
            f[f"model_gap_order_{key}"] = float(np.polyfit(np.log(ORDER_DTS), np.log(errors), 1)[0])


def figures(quick: bool = False, series: dict | None = None) -> dict[str, float]:
    f: dict[str, float] = {}
    series = {} if series is None else series
    series.setdefault("drift", {})
    series.setdefault("orders", {})
    drift(f, series["drift"])
    orders(f, series["orders"])
    spinner(f)
    model_joints(f)
    return f


D = "docs/ours.md"
DRIFT = "### Drift on SO(3)"
QUOTES = load_quotes(__file__)
ROWS = [Row(D, f"{m}-{i}", (f"off_{m}_{i}_20s".replace("-", "_"), f"energy_{m}_{i}_20s".replace("-", "_")), DRIFT)
        for m, i in PAIRS]


def main() -> None:
    from ours_figures import line_plot

    series: dict = {}
    f = figures(series=series)
    OUT.mkdir(parents=True, exist_ok=True)
    line_plot(OUT / "rigid_drift.svg", "compound double pendulum, dt = 1 ms: largest joint gap",
              [(k, t, d) for k, (t, d) in series["drift"].items()], "t (s)", "joint gap (m)", logy=True, floor=1e-17)
    line_plot(OUT / "rigid_orders.svg", "distance from the reduced solution over 2 s",
              [(k, x, y) for k, (x, y) in series["orders"].items()], "dt (s)", "largest frame distance (m)",
              logx=True, logy=True)
    for key in sorted(f):
        print(f"{key:<48} {f[key]:.3g}")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
