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

from compare.results.metrics import constraint_error, energy_drift, position_error
from engines import catalog
from engines.mujoco import ENGINE
from engines.reference import solve
from engines.trajectory import tensions

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


def table(title, rows, references):
    print(f"\n### {title}\n")
    print("| setting | bead constraint error (m) | bead energy drift | double constraint error (m) "
          "| double energy drift | double position error (m) | double tension error (N) |")
    print("|---|---|---|---|---|---|---|")
    for label, variant, options, dt in rows:
        b = measure(BEAD, references[0], variant, options, dt)
        d = measure(DOUBLE, references[1], variant, options, dt)
        flag = "" if b["status"] == d["status"] == "ok" else f" ({b['status']}/{d['status']})"
        print(f"| {label}{flag} | {b['cerr']:.1e} | {b['drift']:.1e} | {d['cerr']:.1e} | {d['drift']:.1e} "
              f"| {d['perr']:.1e} | {d['terr']:.2g} |")


def main() -> None:
    references = (solve(BEAD), solve(DOUBLE))
    table("connect softness (Euler, dt = 1e-3)", [
        ("`connect`: MuJoCo's solref 0.02,1 and solimp 0.9,0.95,…", "connect", {}, 1e-3),
        ("solref time constant 2·dt, default solimp", "connect", {"timeconst_steps": 2}, 1e-3),
        ("default solref, solimp 0.9999", "connect", {"solimp": "0.9999,0.9999,0.001"}, 1e-3),
        ("`connect-stiff`: both", "connect-stiff", {}, 1e-3),
        ("`connect-stiff` at dt = 1e-4", "connect-stiff", {}, 1e-4),
        ("`connect` at dt = 1e-4", "connect", {}, 1e-4),
    ], references)
    table("refsafe (connect-stiff, Euler): solref's time constant below 2·dt", [
        ("time constant 1·dt, refsafe on (clamped to 2·dt)", "connect-stiff", {"timeconst_steps": 1}, 1e-3),
        ("time constant 1·dt, refsafe off", "connect-stiff", {"timeconst_steps": 1, "refsafe": False}, 1e-3),
        ("time constant 0.5·dt, refsafe off", "connect-stiff", {"timeconst_steps": 0.5, "refsafe": False}, 1e-3),
    ], references)
    table("integrator (hinge, dt = 1e-3)", [
        ("`hinge`: Euler (MuJoCo's default)", "hinge", {}, 1e-3),
        ("implicitfast", "hinge-implicitfast", {}, 1e-3),
        ("implicit", "hinge-implicit", {}, 1e-3),
        ("RK4", "hinge-rk4", {}, 1e-3),
        ("`connect-rk4`: RK4 with the default softness", "connect-rk4", {}, 1e-3),
        ("`connect-rk4-stiff`", "connect-rk4-stiff", {}, 1e-3),
    ], references)
    table("point-mass inertia (RK4, dt = 1e-4)", [
        ("hinge-rk4, inertia 1e-6·m·L²", "hinge-rk4", {"inertia_ratio": 1e-6}, 1e-4),
        ("hinge-rk4, inertia 1e-9·m·L² (adapter default)", "hinge-rk4", {}, 1e-4),
        ("connect-rk4-stiff, inertia 1e-6·m·L²", "connect-rk4-stiff", {"inertia_ratio": 1e-6}, 1e-4),
        ("connect-rk4-stiff, inertia 1e-9·m·L²", "connect-rk4-stiff", {}, 1e-4),
    ], references)


if __name__ == "__main__":
    main()
