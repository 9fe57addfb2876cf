"""The reference's own error bar, horizon and Lyapunov exponent for each catalog scene (docs/findings.md).

Run:  .venv/bin/python scripts/reference_horizon.py      (a few seconds)

Each scene (catalog defaults, 40 s) is solved at the suites' tolerance (DOP853, rtol = atol = 1e-12)
and 100× tighter (floored at the 2.2e-14 DOP853 accepts): ``reference_error`` is the largest
distance between the two over the run, ``reference_horizon`` the first time it exceeds 0.1 of
the reference's stated accuracy (1e-9 L), i.e. 1e-10 L (engines/reference/reference.py: bound). The
Lyapunov exponent is Benettin's estimate over the same 40 s (engines/reference/reference.py: lyapunov_exponent).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, report  # noqa: E402

from engines.scene import catalog  # noqa: E402
from engines.reference.reference import bound, lyapunov_exponent  # noqa: E402

DURATION = 40.0
#: Left out of a quick run: the 4-link chain's Lyapunov estimate is the costliest.
QUICK_SKIP = ("chain",)


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    for name in catalog.scene_names():
        if quick and name in QUICK_SKIP:
            continue
        scene = catalog.build(name, {"duration": DURATION})
        b = bound(scene)
        f[f"{name}|reference_error"] = b.reference_error / scene.characteristic_length
        f[f"{name}|reference_horizon"] = math.inf if b.reference_horizon is None else b.reference_horizon
        f[f"{name}|lyapunov"] = lyapunov_exponent(scene)
    f["double-pendulum|lyapunov_10s"] = lyapunov_exponent(catalog.build("double-pendulum"))
    return f


D = "docs/findings.md"
HEADING = "## The reference's own error bar and horizon"
REGULAR = ("bead", "spherical-pendulum")
# A chaotic scene's difference at 40 s is a different motion: its digits are not a figure to check.
ROWS = [Row(D, name, (f"{name}|reference_error" if name in REGULAR else None, f"{name}|reference_horizon",
                      f"{name}|lyapunov"), HEADING)
        for name in ("bead", "double-pendulum", "chain", "spherical-pendulum")]
QUOTES = [Quote(D, "0.99", "double-pendulum|lyapunov_10s", "The estimate for the double\npendulum is {} /s")]
SLOW = {k for r in ROWS for k in r.keys if k and k.split("|")[0] in QUICK_SKIP}


def main() -> None:
    f = figures()
    print("| scene | reference error (L) | reference horizon (s) | largest Lyapunov exponent (1/s) |")
    print("|---|---|---|---|")
    for name in catalog.scene_names():
        horizon = f[f"{name}|reference_horizon"]
        print(f"| {name} | {f[f'{name}|reference_error']:.2g} | {'none' if math.isinf(horizon) else f'{horizon:.3g}'} "
              f"| {f[f'{name}|lyapunov']:.2g} |")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
