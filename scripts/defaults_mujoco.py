"""Measure what each MuJoCo default costs when left in place (numbers quoted in docs/engines.md).

Run: ``.venv/bin/python scripts/defaults_mujoco.py`` (about 10 s). Prints one
Markdown table per question: each row is an adapter variant plus options, run
on the bead (θ0 = 60°, 10 s) and the double pendulum (θ1 = 120°, θ2 = −10°,
2 s), both at dt = 1e-3 unless the row says otherwise. Columns:

- constraint error: max |‖a − b‖ − l| (m) over the run;
- energy drift: max |E(t) − E(0)| / E* (E* = m·g·L);
- position error: max distance (m) from the reference (DOP853, rtol 1e-12);
- tension error: max |tension − reference tension| (N) on the double pendulum.
"""

from __future__ import annotations

import numpy as np

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Row, load_quotes, report  # noqa: E402

from compare.results.metrics import constraint_error, energy_drift, position_error  # noqa: E402
from engines.scene import catalog
from engines.mujoco.adapter import ENGINE
from engines.reference.reference import solve
from engines.scene.trajectory import tensions

BEAD = catalog.build("bead", {"duration": 10})
DOUBLE = catalog.build("double-pendulum", {"duration": 2})


def measure(scene, reference, variant, options, dt=1e-3):
    run = ENGINE.simulate(scene, dt, variant=variant, options=options)
    positions, _, forces = reference.at(run.t)
    tension = np.nan
    if run.constraint_forces is not None:
        tension = np.abs(
            tensions(scene, run.positions, run.constraint_forces) - tensions(scene, positions, forces)
        ).max()
    return {
        "status": run.info.status,
        "cerr": constraint_error(scene, run.positions),
        "drift": energy_drift(scene, run.positions, run.velocities),
        "perr": position_error(run.positions, positions).max(),
        "terr": tension,
    }


COLUMNS = ("bead.cerr", "bead.drift", "double.cerr", "double.drift", "double.perr", "double.terr")

TABLES = [
    ("connect softness (Euler, dt = 1e-3)", [
        ("`connect`: MuJoCo's solref 0.02,1 and solimp 0.9,0.95,…", "connect", {}, 1e-3),
        ("solref time constant 2·dt, default solimp", "connect", {"timeconst_steps": 2}, 1e-3),
        ("default solref, solimp 0.9999", "connect", {"solimp": "0.9999,0.9999,0.001"}, 1e-3),
        ("`connect-stiff`: both", "connect-stiff", {}, 1e-3),
        ("`connect-stiff` at dt = 1e-4", "connect-stiff", {}, 1e-4),
        ("`connect` at dt = 1e-4", "connect", {}, 1e-4),
    ]),
    ("refsafe (connect-stiff, Euler): solref's time constant below 2·dt", [
        ("time constant 1·dt, refsafe on (clamped to 2·dt)", "connect-stiff", {"timeconst_steps": 1}, 1e-3),
        ("time constant 1·dt, refsafe off", "connect-stiff", {"timeconst_steps": 1, "refsafe": False}, 1e-3),
        ("time constant 0.5·dt, refsafe off", "connect-stiff", {"timeconst_steps": 0.5, "refsafe": False}, 1e-3),
    ]),
    ("integrator (hinge, dt = 1e-3)", [
        ("`hinge`: Euler (MuJoCo's default)", "hinge", {}, 1e-3),
        ("implicitfast", "hinge-implicitfast", {}, 1e-3),
        ("implicit", "hinge-implicit", {}, 1e-3),
        ("RK4", "hinge-rk4", {}, 1e-3),
        ("`connect-rk4`: RK4 with the default softness", "connect-rk4", {}, 1e-3),
        ("`connect-rk4-stiff`", "connect-rk4-stiff", {}, 1e-3),
    ]),
    ("point-mass inertia (RK4, dt = 1e-4)", [
        ("hinge-rk4, inertia 1e-6·m·L²", "hinge-rk4", {"inertia_ratio": 1e-6}, 1e-4),
        ("hinge-rk4, inertia 1e-9·m·L²", "hinge-rk4", {"inertia_ratio": 1e-9}, 1e-4),
        ("hinge-rk4, inertia 1e-12·m·L² (the hinge default)", "hinge-rk4", {}, 1e-4),
        ("connect-rk4-stiff, inertia 1e-6·m·L²", "connect-rk4-stiff", {"inertia_ratio": 1e-6}, 1e-4),
        ("connect-rk4-stiff, inertia 1e-9·m·L² (the connect default)", "connect-rk4-stiff", {}, 1e-4),
    ]),
]
#: Short keys for the rows docs/engines.md quotes.
KEYS = {
    "`connect`: MuJoCo's solref 0.02,1 and solimp 0.9,0.95,…": "connect",
    "solref time constant 2·dt, default solimp": "timeconst2",
    "default solref, solimp 0.9999": "solimp",
    "`connect-stiff`: both": "stiff",
    "`connect-stiff` at dt = 1e-4": "stiff_1e-4",
    "`connect` at dt = 1e-4": "connect_1e-4",
    "`hinge`: Euler (MuJoCo's default)": "hinge",
    "implicitfast": "implicitfast",
    "implicit": "implicit",
    "RK4": "rk4",
    "`connect-rk4`: RK4 with the default softness": "connect_rk4",
    "`connect-rk4-stiff`": "connect_rk4_stiff",
    "hinge-rk4, inertia 1e-6·m·L²": "inertia_hinge_1e-6",
    "connect-rk4-stiff, inertia 1e-6·m·L²": "inertia_connect_1e-6",
    "connect-rk4-stiff, inertia 1e-9·m·L² (the connect default)": "inertia_connect_1e-9",
}
SLOW: set[str] = set()


def measure_row(variant, options, dt, references):
    b = measure(BEAD, references[0], variant, options, dt)
    d = measure(DOUBLE, references[1], variant, options, dt)
    values = (b["cerr"], b["drift"], d["cerr"], d["drift"], d["perr"], d["terr"])
    return b["status"], d["status"], values


def figures(quick: bool = False) -> dict[str, float]:
    references = (solve(BEAD), solve(DOUBLE))
    f: dict[str, float] = {}
    for _title, rows in TABLES:
        for label, variant, options, dt in rows:
            if label not in KEYS:
                continue
            _, _, values = measure_row(variant, options, dt, references)
            for column, value in zip(COLUMNS, values):
                f[f"{KEYS[label]}.{column}"] = float(value)
    f["stretch_ratio_timeconst"] = f["connect.double.cerr"] / f["timeconst2.double.cerr"]
    f["stretch_ratio_solimp"] = f["connect.double.cerr"] / f["solimp.double.cerr"]
    f["stiff_gain_1e-4"] = f["stiff.double.cerr"] / f["stiff_1e-4.double.cerr"]
    # The default connect's steady stretch under g, r = (1 − d)·g/(d·k), and the period it costs the 10° bead.
    from engines.mujoco.options import MUJOCO_SOLIMP, MUJOCO_SOLREF

    k = 1.0 / (MUJOCO_SOLIMP[1] * MUJOCO_SOLREF[0] * MUJOCO_SOLREF[1]) ** 2
    f["connect.stretch_under_g"] = (1 - MUJOCO_SOLIMP[0]) * 9.81 / (MUJOCO_SOLIMP[0] * k)
    f["connect.period_predicted"] = f["connect.stretch_under_g"] / 2
    f["connect.period_10deg"] = relative_period_error("connect")
    return f


def relative_period_error(variant: str, dt: float = 1e-3) -> float:
    """(T − T_exact)/T_exact of the 10° bead over three periods, from the zero crossings of x."""
    import math

    from engines.reference.closed_form import pendulum_period

    exact = pendulum_period(1.0, 9.81, math.radians(10.0))
    scene = catalog.build("bead", {"theta0": 10.0, "duration": 3.2 * exact})
    run = ENGINE.simulate(scene, dt, variant=variant, sample_interval=dt)
    x = run.positions[:, 0, 0]
    i = np.nonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))[0]
    crossings = run.t[i] - x[i] * dt / (x[i + 1] - x[i])
    return float((2 * np.polyfit(np.arange(len(crossings)), crossings, 1)[0] - exact) / exact)


def table(title, rows, references):
    print(f"\n### {title}\n")
    print("| setting | bead constraint error (m) | bead energy drift | double constraint error (m) "
          "| double energy drift | double position error (m) | double tension error (N) |")
    print("|---|---|---|---|---|---|---|")
    for label, variant, options, dt in rows:
        b_status, d_status, v = measure_row(variant, options, dt, references)
        flag = "" if b_status == d_status == "ok" else f" ({b_status}/{d_status})"
        print(f"| {label}{flag} | {v[0]:.1e} | {v[1]:.1e} | {v[2]:.1e} | {v[3]:.1e} | {v[4]:.1e} | {v[5]:.2g} |")


D = "docs/engines.md"
SOFTNESS = "**Softness left by MuJoCo's defaults**"
ROWS = [
    Row(D, "defaults (`connect`)", tuple(f"connect.{c}" for c in COLUMNS), SOFTNESS),
    Row(D, "time constant 2·dt only", tuple(f"timeconst2.{c}" for c in COLUMNS), SOFTNESS),
    Row(D, "solimp 0.9999 only", tuple(f"solimp.{c}" for c in COLUMNS), SOFTNESS),
    Row(D, "`connect-stiff`", tuple(f"stiff.{c}" for c in COLUMNS), SOFTNESS),
]
QUOTES = load_quotes(__file__)


def main() -> None:
    references = (solve(BEAD), solve(DOUBLE))
    for title, rows in TABLES:
        table(title, rows, references)
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
