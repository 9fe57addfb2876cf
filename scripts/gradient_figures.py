"""The figures of docs/gradients.md: engines' Jacobians of their outputs at T against the reference's.

Run:  .venv/bin/python scripts/gradient_figures.py      (about a minute)

The double pendulum released at (90°, 0°), T = 1 s, d outputs(T) / d (theta1, omega2, g): each first-order
variant's relative Frobenius error against the reference's variational equations at dt 1e-3 and 5e-4 s, and
the observed order between them (compare/gradients/measure.py: engine_case). These are truncation errors of
first-order steps (1e-3 to 1e-2), far above any round-off, so their two digits hold on any machine; the
float64 RK4 variants' errors (1e-10 to 1e-8) are round-off and differences, asserted under 1e-6 by
tests/test_gradients_engines.py rather than quoted. Last, a bead solver that ignores the g it is given
(examples/python/bead.py with g fixed at 9.81): its d/dg is 0, so its error for g is exactly 1.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import ROOT, Quote, Row, load_quotes, report  # noqa: E402

from compare.gradients.measure import engine_case  # noqa: E402
from engines import registry  # noqa: E402
from engines.external.command import command_engine  # noqa: E402
from engines.scene.catalog import build  # noqa: E402

SCENE = {"theta1": 90.0, "theta2": 0.0, "duration": 1.0}
WRT = ["theta1", "omega2", "g"]
DT = 1e-3
#: The first-order variants in the table: (engine/variant, how it differentiates).
VARIANTS = ("mujoco/hinge", "mujoco/hinge-implicit", "pybullet/multibody", "dart/world", "pymunk/pin")


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    scene = build("double-pendulum", SCENE)
    for engine_id in VARIANTS:
        engine, variant = registry.resolve(engine_id)
        case = engine_case(engine, variant, None, scene, DT, WRT)
        f[f"{engine_id}|error"] = case.error
        f[f"{engine_id}|error_half"] = case.error_half
        f[f"{engine_id}|order"] = math.log2(case.error / case.error_half)
        f[f"{engine_id}|correct"] = float(case.klass == "correct")
    f["blind_g|error_g"], f["blind_g|error_theta0"] = _blind_bead()
    return f


def _blind_bead() -> tuple[float, float]:
    """(relative error of d/dg, of d/dtheta0) of a bead solver that ignores g, at dt 1e-3 over 1 s."""
    text = (ROOT / "examples" / "python" / "bead.py").read_text()
    with tempfile.TemporaryDirectory() as folder:
        program = Path(folder) / "blind_bead.py"
        program.write_text(text.replace('r, (gx, _, gz) = pin["length"], scene["gravity"]',
                                        'r, gx, gz = pin["length"], 0.0, -9.81'))
        engine = command_engine("blind_bead", [sys.executable, str(program)], Path(folder), capabilities=["3d"],
                                where="scripts/gradient_figures.py")
        case = engine_case(engine, None, None, build("bead", {"duration": 1.0}), DT, ["theta0", "g"])
    return case.column_errors[1], case.column_errors[0]


D = "docs/gradients.md"
ROWS = [Row(D, f"`{v}`", (None, f"{v}|error", f"{v}|error_half", f"{v}|order", f"{v}|correct")) for v in VARIANTS]
QUOTES: list[Quote] = load_quotes(__file__)
SLOW: set[str] = set()


def main() -> None:
    f = figures()
    print("| variant | method | error, dt 1e-3 s | error, dt 5e-4 s | observed order | correct |")
    print("|---|---|---|---|---|---|")
    for v in VARIANTS:
        print(f"| `{v}` | | {f[f'{v}|error']:.2g} | {f[f'{v}|error_half']:.2g} | {f[f'{v}|order']:.2f} | "
              f"{'true' if f[f'{v}|correct'] else 'false'} |")
    print(f"\nbead solver ignoring g: error for g {f['blind_g|error_g']:.6f}, for theta0 {f['blind_g|error_theta0']:.2g}")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
