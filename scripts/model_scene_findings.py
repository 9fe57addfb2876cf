"""Model scenes stepped by every engine that loads models, against the Pinocchio reference (docs/models.md,
"Models as scenes").

Run:  .venv/bin/python scripts/model_scene_findings.py      (about half a minute)

For the compound double pendulum fixture (models/double_pendulum.urdf, q0 = 30°, −20°) and KUKA iiwa
(pybullet_data, q0 joint 2 = 30°, joint 4 = −45°), 2 s at dt = 1e-3: each engine variant's largest
link-frame position error (m) against the reference, its energy drift max |E − E0| / E* (rotational
kinetic energy included) and its constraint error (m: ours' joint gap; 0 for joint coordinates). KUKA is
left out of the quick run the docs test makes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, report  # noqa: E402

from engines.model.scene import model_scene  # noqa: E402
from engines.reference.reference import ENGINE as REFERENCE  # noqa: E402
from engines.registry import resolve  # noqa: E402
from engines.scene.trajectory import trajectory_constraint_error, trajectory_energy  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENES = {
    "double": (str(ROOT / "models" / "double_pendulum.urdf"), {"shoulder": 30, "elbow": -20}),
    "kuka": ("pybullet_data:kuka_iiwa/model.urdf", {"lbr_iiwa_joint_2": 30, "lbr_iiwa_joint_4": -45}),
}
ENGINES = ("mujoco/hinge", "mujoco/hinge-rk4", "pybullet/multibody", "drake/semi-explicit-euler", "drake/rk2",
           "dart/world", "dart/rk4", "ours/baumgarte-rk4", "ours/projection-rk4", "ours/projection-symplectic-euler")
METRICS = ("error", "drift", "gap")
DT = 1e-3
QUICK_SKIP = ("kuka",)


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    for key, (model, q0) in SCENES.items():
        if quick and key in QUICK_SKIP:
            continue
        scene = model_scene(key, model, q0=q0, duration=2.0)
        reference = REFERENCE.simulate(scene, DT)
        for engine_id in ENGINES:
            engine, variant = resolve(engine_id)
            run = engine.simulate(scene, DT, variant=variant)
            energy = trajectory_energy(scene, run)
            f[f"{key}|{engine_id}|error"] = float(np.linalg.norm(run.positions - reference.positions, axis=2).max())
            f[f"{key}|{engine_id}|drift"] = float(np.abs(energy - energy[0]).max() / scene.characteristic_energy)
            f[f"{key}|{engine_id}|gap"] = float(trajectory_constraint_error(scene, run).max())
    return f


D = "docs/models.md"
HEADING = "## Models as scenes"
ROWS = [Row(D, f"`{e}`", tuple(f"{s}|{e}|{m}" for s in SCENES for m in METRICS), HEADING)
        for e in ENGINES]
QUOTES: list[Quote] = []
SLOW = {f"kuka|{e}|{m}" for e in ENGINES for m in METRICS}


def main() -> None:
    f = figures()
    print("| engine | double pendulum error (m) | drift (E*) | constraint error (m) | KUKA iiwa error (m) | drift (E*) "
          "| constraint error (m) |")
    print("|---|---|---|---|---|---|---|")
    for e in ENGINES:
        cells = " | ".join(f"{f[f'{s}|{e}|{m}']:.2g}" for s in SCENES for m in METRICS)
        print(f"| `{e}` | {cells} |")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
