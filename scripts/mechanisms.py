"""What a closed loop, its near-singular (toggle) pass and a rail do to each engine.

Runs every engine variant that can express each mechanism (plus MuJoCo's hinge
with the stiff loop equality) at one time step and prints Markdown tables:

1. four-bar (a Grashof crank-rocker turning, ``omega0 = 3``) and the
   near-toggle four-bar (coupler 0.01 m short of the change point, ``b = 1.39,
   theta0 = 0, omega0 = 8``: once a turn crank, coupler and rocker come close
   to one line, where J W Jᵀ is nearly singular and the loop's forces peak):
   status, position error (max over the run, m), constraint error (m), energy
   drift (E*), crank turns (the engine's against the reference's), samples on
   the other assembly branch (%: the rocker tip on the wrong side of the line
   from the crank tip to the ground pivot), and the peak constraint force over
   the reference's peak (engines that report forces);
2. slider-pendulum: horizontal momentum drift (max |ΔPₓ| / (M √(g L))) at two
   time steps — exactly conserved by the true motion.

Everything is measured against the reference (DOP853 at rtol = atol = 1e-12).
docs/findings.md ("## Mechanisms") quotes this script's output:

    .venv/bin/python scripts/mechanisms.py            # dt = 1e-3, 2 s
    .venv/bin/python scripts/mechanisms.py --dt 1e-2
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from engines import registry
from engines.scene import catalog
from engines.errors import Unsupported
from engines.mujoco.options import STIFF
from engines.reference.reference import solve
from engines.scene.trajectory import constraint_errors, linear_momentum_drift, total_energy

ENGINES = ("ours", "mujoco", "pybullet", "pymunk")
STIFF_LOOP = {"timeconst_steps": 2.0, "solimp": STIFF["solimp"]}

FOUR_BARS = {
    "four-bar": {"omega0": 3.0},
    "four-bar near toggle": {"b": 1.39, "theta0": 0.0, "omega0": 8.0},
}


def variants():
    """(label, engine, variant, options) for every built-in variant, plus mujoco's hinge with a stiff loop."""
    out = []
    for name in ENGINES:
        engine = registry.get_engine(name)
        out += [(f"{name}/{v}", engine, v, {}) for v in engine.variants]
        if name == "mujoco":
            out += [(f"mujoco/{v}-stiffloop", engine, v, STIFF_LOOP) for v in ("hinge", "hinge-rk4")]
    return out


def _side(scene, positions):
    """(n,) m²: cross((pivot − p0), (p1 − p0)) in the x–z plane; its sign is the assembly branch."""
    pivot = np.asarray(scene.constraints[2].anchor)[[0, 2]]
    p0, p1 = positions[:, 0, [0, 2]], positions[:, 1, [0, 2]]
    u, w = pivot - p0, p1 - p0
    return u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]


def _turns(positions):
    crank = np.unwrap(np.arctan2(positions[:, 0, 0], -positions[:, 0, 2]))
    return (crank[-1] - crank[0]) / (2 * math.pi)


def four_bar_table(title, overrides, dt, duration):
    scene = catalog.build("four-bar", {**overrides, "duration": duration})
    reference = solve(scene)
    print(f"\n### {title} ({', '.join(f'{k} = {v:g}' for k, v in overrides.items())}), dt = {dt:g} s, {duration:g} s\n")
    t = np.linspace(0.0, duration, int(round(duration / 0.01)) + 1)
    q_ref, v_ref, f_ref = reference.at(t)
    energy = total_energy(scene, q_ref, v_ref)
    print(f"reference: crank turns {_turns(q_ref):.2f}, loop closure {constraint_errors(scene, q_ref).max():.1e} m, "
          f"energy drift {np.abs(energy - energy[0]).max() / scene.characteristic_energy:.1e} E*, "
          f"peak constraint force {np.abs(f_ref).max():.3g} N\n")
    print("| variant | status | position error (m) | constraint error (m) | energy drift (E*) "
          "| crank turns | other branch | peak force / reference |")
    print("|---|---|---|---|---|---|---|---|")
    for label, engine, variant, options in variants():
        try:
            engine.check(scene, variant, options)
        except Unsupported:
            continue
        run = engine.simulate(scene, dt, variant=variant, options=options)
        n = run.n_samples
        q, v = run.positions, run.velocities
        error = np.linalg.norm(q - reference.at(run.t)[0], axis=2).max()
        energy = total_energy(scene, q, v)
        drift = np.abs(energy - energy[0]).max() / scene.characteristic_energy
        ref_side, side = _side(scene, q_ref[:n]), _side(scene, q)
        clear = (np.abs(ref_side) > 1e-3) & (np.abs(side) > 1e-3)
        other = 100.0 * np.mean(np.sign(side[clear]) != np.sign(ref_side[clear])) if clear.any() else float("nan")
        peak = "—"
        if run.constraint_forces is not None and np.isfinite(run.constraint_forces).all():
            peak = f"{np.abs(run.constraint_forces).max() / np.abs(f_ref).max():.3g}"
        status = run.info.status if n == len(t) else f"{run.info.status} at {run.t[-1]:.2f} s"
        print(f"| {label} | {status} | {error:.2e} | {constraint_errors(scene, q).max():.2e} | {drift:.2e} "
              f"| {_turns(q):.2f} | {other:.0f} % | {peak} |")


def slider_table(dts, duration):
    scene = catalog.build("slider-pendulum", {"theta0": 70.0, "omega0": 1.0, "duration": duration})
    print(f"\n### slider-pendulum (theta0 = 70, omega0 = 1), {duration:g} s: horizontal momentum drift\n")
    print("| variant | " + " | ".join(f"dt = {dt:g} s" for dt in dts) + " |")
    print("|---|" + "---|" * len(dts))
    for label, engine, variant, options in variants():
        if options:
            continue
        try:
            engine.check(scene, variant, options)
        except Unsupported:
            continue
        cells = []
        for dt in dts:
            run = engine.simulate(scene, dt, variant=variant)
            drift = linear_momentum_drift(scene, run.velocities)
            cells.append(f"{drift:.1e}" + ("" if run.info.status == "ok" else f" ({run.info.status})"))
        print(f"| {label} | " + " | ".join(cells) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dt", type=float, default=1e-3, help="time step of the four-bar tables, s")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time, s")
    args = parser.parse_args()
    for title, overrides in FOUR_BARS.items():
        four_bar_table(title, overrides, args.dt, args.duration)
    slider_table((1e-2, 1e-3), args.duration)


if __name__ == "__main__":
    main()
