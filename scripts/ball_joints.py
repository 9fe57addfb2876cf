"""PyBullet and ball joints: what its calculateMassMatrix gives, and its stepping's order (docs/models.md).

Run:  .venv/bin/python scripts/ball_joints.py      (a few seconds)

``calculateMassMatrix`` on tests/fixtures/urdf/ball_chain.urdf (two spherical joints), handed each ball's
position as PyBullet's own quaternion (xval's mapped into the child's inertial axes, as
engines/pybullet/model.py does): its largest difference from the reference's M (Pinocchio), over three
states, relative to M's largest entry. Then the chain as a model scene (1 s) stepped by PyBullet at dt 1e-3
and 5e-4: the ratio of its largest link-frame errors against the reference (2 for first order).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import load_quotes, report  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
URDF = ROOT / "tests" / "fixtures" / "urdf" / "ball_chain.urdf"
SLOW: set[str] = set()


def mass_matrix_difference() -> float:
    """max over 3 states of max |T⁻ᵀ M_pb T⁻¹ − M_ref| / max |M_ref|, M_pb PyBullet's calculateMassMatrix."""
    from scipy.spatial.transform import Rotation

    from compare.model.parity import read_description
    from engines.model.importers import importer
    from engines.pybullet.library import pb

    source, model = read_description(str(URDF))
    reference, loaded = importer("pinocchio").load(source, model), importer("pybullet").load(source, model)
    balls = loaded.balls
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(3):
        q = model.neutral()
        for joint in model.moving_joints:
            where = model.slots[joint.name][0]
            q[where] = Rotation.random(random_state=rng).as_quat() if joint.type == "ball" else rng.uniform(-1, 1)
        positions = [x for part in balls._entries(q, True) for x in part]
        engine = np.array(pb.calculateMassMatrix(loaded.body, positions, physicsClientId=loaded.client))
        inverse = np.linalg.inv(balls.T)
        expected = reference.mass_matrix(q)
        worst = max(worst, float(np.abs(inverse.T @ engine @ inverse - expected).max() / np.abs(expected).max()))
    return worst


def first_order_errors() -> list[float]:
    """PyBullet's largest link-frame error (m) at dt 1e-3 and 5e-4 against the reference (the URDF chain, 1 s)."""
    from engines.model.scene import model_scene
    from engines.reference.reference import ENGINE as REFERENCE
    from engines.registry import resolve

    scene = model_scene("chain", str(URDF), q0={"shoulder": [0.3, 0.1, 0.2, 0.9], "elbow": 40, "wrist": [0, 0.3, 0, 1]},
                        v0={"shoulder": [1.0, -0.5, 2.0], "elbow": -1.0, "wrist": [0, 0, 3]}, duration=1.0)
    engine, variant = resolve("pybullet")
    errors = []
    for dt in (1e-3, 5e-4):
        reference = REFERENCE.simulate(scene, dt)
        run = engine.simulate(scene, dt, variant=variant)
        errors.append(float(np.abs(run.positions - reference.positions).max()))
    return errors


def figures(quick: bool = False) -> dict[str, float]:
    errors = first_order_errors()
    found = {"pybullet_mass_matrix_percent": 100 * mass_matrix_difference(),
             "pybullet_first_order_ratio": errors[0] / errors[1]}
    for key, value in found.items():
        print(f"{key}: {value:.4g}")
    return found


QUOTES, ROWS = load_quotes(__file__), []


def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
