"""Measure the model-import findings quoted in docs/models.md.

Run: ``.venv/bin/python scripts/model_findings.py`` (about half a minute). Prints:

1. ``xval model check`` (100 states, seed 0) of pybullet_data's KUKA iiwa, Franka Panda and xArm6, and of
   models/pitfalls/no_inertial.urdf: per engine the largest relative difference of M, bias and
   forward dynamics against Pinocchio's, and the diagnosis;
2. on the Panda: each diagonal entry of MuJoCo's M minus Pinocchio's over the states (kg·m²), the
   same check with MuJoCo's fusestatic off, and the gravity torques at q = 0 (N·m).
3. pybullet_data's r2d2: the largest |bias| at 100 states (round-off: every joint turns about a vertical axis).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, report  # noqa: E402

from compare.model.parity import QUANTITIES, check, evaluate, read_description, relative_difference, sample_states  # noqa: E402
from engines.model.importers import importer  # noqa: E402

DOC = "docs/models.md"
MODELS = {
    "kuka": "pybullet_data:kuka_iiwa/model.urdf",
    "panda": "pybullet_data:franka_panda/panda.urdf",
    "xarm": "pybullet_data:xarm/xarm6_robot.urdf",
    "no_inertial": str(Path(__file__).resolve().parent.parent / "models/pitfalls/no_inertial.urdf"),
}
SLOW: set[str] = set()


def parity(figures: dict[str, float]) -> None:
    for key, model in MODELS.items():
        report_ = check(model, states=100, seed=0)
        print(f"\n### {model}\n\n| engine | M | bias | forward | agrees |\n|---|---|---|---|---|")
        for e in report_.engines:
            cells = " | ".join("-" if getattr(e, q) is None else f"{getattr(e, q):.2g}" for q in QUANTITIES)
            print(f"| {e.engine} | {cells} | {'yes' if e.agrees else 'no'} |" + (f" {e.message}" if e.message else ""))
            for q in QUANTITIES:
                if getattr(e, q) is not None:  # None: the engine refused the file
                    figures[f"{key}.{e.engine}.{q}"] = getattr(e, q)
        for line in report_.diagnosis:
            print(f"\n{line}")


def panda(figures: dict[str, float]) -> None:
    source, model = read_description(MODELS["panda"])
    reference = importer("pinocchio").load(source, model)
    states = sample_states(model, reference, 100, 0)
    expected = evaluate(reference, states)["mass_matrix"]
    mujoco = importer("mujoco").load(source, model)
    diagonal = np.array([np.diag(m - r) for m, r in zip(evaluate(mujoco, states)["mass_matrix"], expected)])
    arm = diagonal[:, :7]
    print(f"\nPanda, MuJoCo M − Pinocchio M on the diagonal (arm joints), over 100 states: "
          f"min {arm.min():.6f}, max {arm.max():.6f} kg·m²; finger joints: largest |·| {np.abs(diagonal[:, 7:]).max():.1e}")
    figures["panda.mujoco.diagonal"] = float(arm.mean())
    unfused = importer("mujoco").load(source, model, fusestatic=False)
    figures["panda.mujoco_unfused.mass_matrix"] = relative_difference(evaluate(unfused, states)["mass_matrix"], expected)
    print(f"Panda, MuJoCo with fusestatic=\"false\": M relative difference "
          f"{figures['panda.mujoco_unfused.mass_matrix']:.1e}")
    zero = np.zeros(model.nq)
    for engine in ("pinocchio", "mujoco", "pybullet", "drake", "dart"):
        torque = importer(engine).load(source, model).bias(zero, zero)[1]
        figures[f"panda.{engine}.gravity_joint2"] = abs(float(torque))
        print(f"Panda at q = 0, gravity torque on panda_joint2: {engine} {torque:.4f} N·m")


def round_off_bias(figures: dict[str, float]) -> None:
    """r2d2's joints all turn about vertical axes: its bias is round-off, why bias differences are floored."""
    source, model = read_description("pybullet_data:r2d2.urdf")
    reference = importer("pinocchio").load(source, model)
    states = sample_states(model, reference, 100, 0)
    figures["r2d2.bias"] = float(np.abs(evaluate(reference, states)["bias"]).max())
    figures["r2d2.tau"] = float(np.abs(states.tau).max())
    print(f"\nr2d2 (100 states): largest |b| {figures['r2d2.bias']:.2g} N·m, largest |tau| {figures['r2d2.tau']:.2g} N·m")


def figures(quick: bool = False) -> dict[str, float]:
    found: dict[str, float] = {}
    parity(found)
    panda(found)
    round_off_bias(found)
    return found


QUOTES = [
    Quote(DOC, "4.7e-02", "panda.mujoco.mass_matrix", context="M {}"),
    Quote(DOC, "9.3e-03", "panda.mujoco.bias", context="bias {}"),
    Quote(DOC, "0.33", "panda.drake.mass_matrix", context="M {}"),
    Quote(DOC, "0.33", "panda.drake.bias", context="bias {}"),
    Quote(DOC, "−0.200000", "panda.mujoco.diagonal", context="exactly {} kg·m²"),
    Quote(DOC, "2.8261", "panda.pinocchio.gravity_joint2", context="{} N·m"),
    Quote(DOC, "4.5526", "panda.drake.gravity_joint2", context="{} N·m"),
    Quote(DOC, "0.022", "xarm.pybullet.mass_matrix", context="M {}"),
    Quote(DOC, "0.69", "xarm.pybullet.forward", context="forward {}"),
    Quote(DOC, "7.9e-18", "r2d2.bias", context="|b| ≤ {} N·m"),
    Quote(DOC, "0.91", "no_inertial.pybullet.mass_matrix", context="M {}"),
    Quote(DOC, "0.27", "no_inertial.pybullet.bias", context="bias {}"),
]
ROWS: list[Row] = []


def main() -> None:
    found = figures()
    report(found, QUOTES, ROWS)


if __name__ == "__main__":
    main()
