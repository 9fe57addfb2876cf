"""Every figure docs/ours.md quotes (timings aside: those come from ``make bench``), measured and printed.

Run:  .venv/bin/python scripts/ours_claims.py      (about 10 s)

The bead is the catalog's (1 kg, r = 1 m, released at rest at 60°, g = 9.81); energies are
in m g r (= E*), distances in metres. tests/test_docs_figures.py regenerates these
(``figures(quick=True)``) and checks them against the quotes below.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import load_quotes, report  # noqa: E402

import ours  # noqa: E402
from ours import System, Wire, simulate  # noqa: E402

G = 9.81
THETA0 = math.radians(60.0)
BEAD = System((1.0,), (0.0, -G), (Wire(0, (0.0, 0.0), 1.0),))
Q0 = np.array([[math.sin(THETA0), -math.cos(THETA0)]])
V0 = np.zeros((1, 2))
#: Critical limits of h·√k_s at k_d = 2√k_s (docs/ours.md, compare/stability/gainmap.py).
LIMITS = {"euler": 2.0, "symplectic-euler": 2 * (math.sqrt(2) - 1), "midpoint": 2.0, "rk4": 2.785}
SLOW: set[str] = set()


def _energy(run) -> np.ndarray:
    """(n,) J/(m g r): energy relative to the start, in m g r."""
    e = 0.5 * np.sum(run.v[:, 0] ** 2, axis=1) + G * run.q[:, 0, 1]
    return (e - e[0]) / G


def _off(run) -> np.ndarray:
    return np.abs(np.linalg.norm(run.q[:, 0], axis=1) - 1.0)


def _up_to(run, series, t_end):
    return float(series[: np.searchsorted(run.t, t_end + 1e-9) + 1].max())


def drift(f: dict) -> None:
    """Why a bead drifts off its wire, and what each cure leaves (20 s at dt = 1 ms)."""
    run = simulate(BEAD, Q0, V0, 1e-3, 20_000, 1, method="plain", integrator="euler")
    off = _off(run)
    f["plain_euler_off_5s"] = _up_to(run, off, 5.0)
    f["plain_euler_off_20s"] = float(off.max())
    # The straight-step mechanism, h²|ẋ|²/(2r) per step, summed over the run:
    v2 = np.sum(run.v[:-1, 0] ** 2, axis=1)
    f["straight_step_share"] = float(np.sum(v2) * 1e-6 / 2) / float(off[-1])
    rk4 = simulate(BEAD, Q0, V0, 1e-3, 80_000, 100, method="plain", integrator="rk4")
    f["plain_rk4_off_20s"] = _up_to(rk4, _off(rk4), 20.0)
    times = np.array([10.0, 20.0, 40.0, 80.0])
    e = np.abs(_energy(rk4))
    f["plain_rk4_energy_20s"] = _up_to(rk4, e, 20.0)
    f["plain_rk4_energy_slope"] = float(np.polyfit(np.log(times), np.log([_up_to(rk4, e, t) for t in times]), 1)[0])
    f["plain_rk4_off_slope"] = float(
        np.polyfit(np.log(times), np.log([_up_to(rk4, _off(rk4), t) for t in times]), 1)[0]
    )
    for method, integrator, key in [
        ("baumgarte", "symplectic-euler", "baumgarte_symplectic_euler"), ("baumgarte", "rk4", "baumgarte_rk4"),
        ("projection", "symplectic-euler", "projection"), ("rattle", None, "rattle"), ("lagrangian", "rk4", "lagrangian"),
    ]:
        run = simulate(BEAD, Q0, V0, 1e-3, 20_000, 20, method=method, integrator=integrator)
        f[f"{key}_off_20s"] = float(_off(run).max())
        f[f"{key}_energy_20s"] = float(np.abs(_energy(run)).max())
        f[f"{key}_energy_final_20s"] = float(_energy(run)[-1])


def projection_budget(f: dict) -> None:
    """Split projection-symplectic-Euler's energy change over 20 s into its steps and its projections.

    Each step is replayed from the stored state without the projection (one plain step): the
    plain step's change is the step's, the rest is the projection's.
    """
    run = simulate(BEAD, Q0, V0, 1e-3, 20_000, 1, method="projection", integrator="symplectic-euler")

    def energy(q, v):
        return 0.5 * float(v @ v) + G * float(q[1])

    steps = jumps = 0.0
    for i in range(len(run.t) - 1):
        q, v = run.q[i : i + 1, 0], run.v[i : i + 1, 0]
        plain = simulate(BEAD, q, v, 1e-3, 1, 1, method="plain", integrator="symplectic-euler")
        before, after_step = energy(q[0], v[0]), energy(plain.q[-1, 0], plain.v[-1, 0])
        steps += after_step - before
        jumps += energy(run.q[i + 1, 0], run.v[i + 1, 0]) - after_step
    f["projection_steps_energy_20s"] = steps / G
    f["projection_jumps_energy_20s"] = -jumps / G  # removed: a positive number


#: The convergence study on the bead: (method, integrator, figure key) and its six steps (s).
ORDER_METHODS = [("baumgarte", "euler", "euler"), ("baumgarte", "symplectic-euler", "symplectic_euler"),
                 ("baumgarte", "midpoint", "midpoint"), ("baumgarte", "rk4", "rk4"),
                 ("rattle", None, "rattle"), ("lagrangian", "rk4", "lagrangian_rk4")]
ORDER_DTS = np.array([2e-2, 1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4])


def bead_convergence() -> list[tuple[str, str | None, str, np.ndarray, float]]:
    """Per ORDER_METHODS entry: (method, integrator, key, the position error (m) at t = 1 s at each of
    ORDER_DTS, the slope of log error against log dt over the finest four with an error above 1e-13).
    scripts/ours_figures.py plots what this measures."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda t, y: [y[1], -G * math.sin(y[0])], (0, 1.0), [THETA0, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-13)
    exact = np.array([math.sin(sol.y[0, -1]), -math.cos(sol.y[0, -1])])
    out = []
    for method, integrator, key in ORDER_METHODS:
        errors = []
        for dt in ORDER_DTS:
            n = round(1.0 / dt)
            run = simulate(BEAD, Q0, V0, dt, n, n, method=method, integrator=integrator)
            errors.append(np.abs(run.q[-1, 0] - exact).max())
        errors = np.array(errors)
        fit = errors > 1e-13
        slope = float(np.polyfit(np.log(ORDER_DTS[fit][-4:]), np.log(errors[fit][-4:]), 1)[0])
        out.append((method, integrator, key, errors, slope))
    return out


def orders(f: dict) -> None:
    """Slope of log error at t = 1 s against log dt, finest four of six steps (:func:`bead_convergence`)."""
    for _method, _integrator, key, _errors, slope in bead_convergence():
        f[f"order_{key}"] = slope


def long_runs(f: dict) -> None:
    """1,000 s of RATTLE and 100 s of Baumgarte–symplectic Euler at dt = 5 ms."""
    dt = 5e-3
    rattle = simulate(BEAD, Q0, V0, dt, round(1000 / dt), 20, method="rattle")
    e = np.abs(_energy(rattle))
    f["rattle_energy_first_100s"] = _up_to(rattle, e, 100.0)
    f["rattle_energy_last_100s"] = float(e[rattle.t >= 900.0].max())
    symp = simulate(BEAD, Q0, V0, dt, round(100 / dt), 20, method="baumgarte", integrator="symplectic-euler")
    f["baumgarte_symplectic_euler_energy_100s"] = float(np.abs(_energy(symp)).max())


def gains(f: dict) -> None:
    """Constraint error against k_s (k_d = 2√k_s), bead 20 s at dt = 1 ms."""
    for integrator, k_s, key in [("symplectic-euler", 1.0, "gain_se_1"), ("symplectic-euler", 10**5.5, "gain_se_3e5"),
                                 ("rk4", 10.0, "gain_rk4_10"), ("rk4", 10**6.5, "gain_rk4_3e6")]:
        run = simulate(BEAD, Q0, V0, 1e-3, 20_000, 10, method="baumgarte", integrator=integrator,
                       k_s=k_s, k_d=2 * math.sqrt(k_s))
        f[key] = float(_off(run).max())


def _stable(integrator: str, dt: float, k_s: float, theta0: float, duration: float = 2.0) -> bool:
    """ok and within the stiff suite's bounds (energy ≤ 1 E*, off the wire ≤ 0.1 L) over ``duration`` s."""
    q0 = np.array([[math.sin(theta0), -math.cos(theta0)]])
    run = simulate(BEAD, q0, V0, dt, round(duration / dt), 1, method="baumgarte", integrator=integrator,
                   k_s=k_s, k_d=2 * math.sqrt(k_s))
    if run.status != "ok":
        return False
    return bool(np.abs(_energy(run)).max() <= 1.0 and _off(run).max() <= 0.1)


def stability(f: dict) -> None:
    """Largest stable dt at k_s = 1e6, k_d = 2000 on the 60° bead (2 s), by the stability search's rule.

    The same search as ``xval stability`` (compare/stability/search.py: two trials per decade
    from 0.05 s down, then bisection to 10 %), run in this process on ours directly.
    """
    from compare.stability.trial import Trial
    from compare.stability.search import search
    from compare.suite.plans import SearchSettings

    settings = SearchSettings(dt_max=0.05, dt_min=1e-4)
    for integrator in ("euler", "symplectic-euler", "midpoint", "rk4"):
        _, largest, _, _ = search(lambda dt: Trial(dt, "ok" if _stable(integrator, dt, 1e6, THETA0) else "unstable"),  # noqa: B023
                                  settings)
        f[f"search_{integrator.replace('-', '_')}_ks1e6_ms"] = largest * 1e3
        f[f"theory_{integrator.replace('-', '_')}_ks1e6_ms"] = LIMITS[integrator] / 1e3 * 1e3
    # Inside the theoretical region but near its edge: the smallest fraction of the limit, on a
    # 1 % grid from 50 % to 99 %, at which the pair is unstable (1.0: none), at 60° and at 1°.
    for integrator in ("midpoint", "rk4"):
        for k_s, tag in ((1e6, "ks1e6"), (1e4, "ks1e4")):
            for theta_deg in (60.0, 1.0):
                grid = np.round(np.arange(0.50, 0.995, 0.01), 2)
                failing = [x for x in grid
                           if not _stable(integrator, x * LIMITS[integrator] / math.sqrt(k_s), k_s, math.radians(theta_deg))]
                f[f"edge_{integrator}_{tag}_{int(theta_deg)}deg"] = float(min(failing)) if failing else 1.0


QUOTES, ROWS = load_quotes(__file__), []  # what docs quote from this script


def figures(quick: bool = False) -> dict[str, float]:
    ours.compile_all()
    f: dict[str, float] = {}
    drift(f)
    projection_budget(f)
    orders(f)
    long_runs(f)
    gains(f)
    stability(f)
    f["rho_1.0005_500_steps"] = 1.0005**500
    return f



def main() -> None:
    f = figures()
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
