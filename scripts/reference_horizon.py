"""The reference's own error bar, horizon and Lyapunov exponent for each catalog scene (docs/findings.md).

Run:  .venv/bin/python scripts/reference_horizon.py      (a few seconds)

Each scene (catalog defaults, 40 s) is solved at the suites' tolerance (DOP853, rtol = atol = 1e-12)
and 100× tighter (floored at the 2.2e-14 DOP853 accepts): ``reference_error`` is the largest
distance between the two over the run, ``reference_horizon`` the first time it exceeds 0.1 of
the reference's stated accuracy (1e-9 L), i.e. 1e-10 L (engines/reference/reference.py: bound), with
its interval (the horizons of a reference half and twice as accurate). The Lyapunov exponent is an
ensemble's estimate with its interval: the median and the range of 12 Benettin runs over 40 s that
differ in separation, direction, renormalisation interval and start time (engines/reference/ensemble.py).
One orbit's estimate moves by ±15 % with round-off; the ensemble's median stays inside its interval.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, report  # noqa: E402

from engines.scene import catalog  # noqa: E402
from engines.reference.reference import lyapunov_ensemble  # noqa: E402
from engines.reference.reference import bound, solve  # noqa: E402
from quoted import Tolerance  # noqa: E402

DURATION = 40.0
#: Left out of a quick run: the 4-link chain's Lyapunov estimate is the costliest.
QUICK_SKIP = ("chain",)
#: The scenes docs/findings.md quotes (a quick run measures only these).
QUOTED_SCENES = ("bead", "double-pendulum", "chain", "spherical-pendulum")


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    for name in catalog.scene_names():
        if quick and (name in QUICK_SKIP or name not in QUOTED_SCENES):
            continue
        scene = catalog.build(name, {"duration": DURATION})
        b = bound(scene)
        f[f"{name}|reference_error"] = b.reference_error / scene.characteristic_length
        f[f"{name}|reference_horizon"] = math.inf if b.reference_horizon is None else b.reference_horizon
        if b.horizon_interval is not None:
            f[f"{name}|reference_horizon_low"], f[f"{name}|reference_horizon_high"] = b.horizon_interval
        rate = lyapunov_ensemble(scene, solve(scene))
        f[f"{name}|lyapunov"], f[f"{name}|lyapunov_low"], f[f"{name}|lyapunov_high"] = rate.value, rate.low, rate.high
    rate = lyapunov_ensemble(catalog.build("double-pendulum"))
    f["double-pendulum|lyapunov_10s"], f["double-pendulum|lyapunov_10s_low"], f["double-pendulum|lyapunov_10s_high"] = (
        rate.value, rate.low, rate.high)
    return f

D = "docs/findings.md"
HEADING = "## The reference's own error bar and horizon"
REGULAR = ("bead", "spherical-pendulum")
CHAOTIC = ("double-pendulum", "chain")
#: An ensemble's estimate and the ends of its range move with round-off as its members do (each by up to
#: ±15 %); the second pass of the quote test measures how far.
ENDS = Tolerance("the ends of a 12-member range move as its members do with round-off", relative=0.25)
HORIZON = Tolerance("a chaotic scene's horizon moves by about ln 2/λ when round-off changes its reference's error",
                    relative=0.1)


def estimate(key: str, low: float, high: float) -> dict[str, Tolerance]:
    """An estimate quoted with its interval: it must stay inside the quoted interval, its ends within ENDS."""
    why = "an ensemble's median, quoted with the range of its members"
    return {key: Tolerance(why, interval=(low, high)), f"{key}_low": ENDS, f"{key}_high": ENDS}


# A chaotic scene's difference at 40 s is a different motion: its digits are not a figure to check. The
# horizon and the Lyapunov exponent are quoted as estimates with their intervals (cells "7.29 [5.83, 8.8]").
QUOTED = {"bead": (0.026, 0.093), "double-pendulum": (0.75, 1.1), "chain": (3.4, 4.5),
          "spherical-pendulum": (0.02, 0.1)}  # each scene's quoted Lyapunov interval (1/s)
ROWS = [Row(D, name, (f"{name}|reference_error" if name in REGULAR else None,
                      (f"{name}|reference_horizon", f"{name}|reference_horizon_low", f"{name}|reference_horizon_high")
                      if name in CHAOTIC else f"{name}|reference_horizon",
                      (f"{name}|lyapunov", f"{name}|lyapunov_low", f"{name}|lyapunov_high")), HEADING,
            {**estimate(f"{name}|lyapunov", *QUOTED[name]),
             **{f"{name}|reference_horizon{end}": HORIZON for end in ("", "_low", "_high")}})
        for name in QUOTED_SCENES]
QUOTES = [Quote(D, text, f"double-pendulum|lyapunov_10s{end}", context, tolerance=tolerance)
          for text, end, context, tolerance in (
              ("0.95", "", "pendulum is {} [0.55, 1.1] /s", Tolerance("an ensemble's median", interval=(0.55, 1.1))),
              ("0.55", "_low", "pendulum is 0.95 [{}, 1.1] /s", ENDS),
              ("1.1", "_high", "pendulum is 0.95 [0.55, {}] /s", ENDS))] + [
    Quote("docs/architecture.md", "0.95", "double-pendulum|lyapunov_10s", '("{} [0.55, 1.1] /s")',
          tolerance=Tolerance("an ensemble's median, quoted with the range of its members", interval=(0.55, 1.1)))]
SLOW = {k for r in ROWS for key in r.keys for k in (key if isinstance(key, tuple) else (key,))
        if k and k.split("|")[0] in QUICK_SKIP}

def main() -> None:
    f = figures()
    print("| scene | reference error (L) | reference horizon (s) | largest Lyapunov exponent (1/s) |")
    print("|---|---|---|---|")
    for name in catalog.scene_names():
        horizon = f[f"{name}|reference_horizon"]
        shown = "none" if math.isinf(horizon) else f"{horizon:.3g}"
        if f"{name}|reference_horizon_low" in f:
            shown += f" [{f[f'{name}|reference_horizon_low']:.3g}, {f[f'{name}|reference_horizon_high']:.3g}]"
        print(f"| {name} | {f[f'{name}|reference_error']:.2g} | {shown} "
              f"| {f[f'{name}|lyapunov']:#.2g} [{f[f'{name}|lyapunov_low']:#.2g}, {f[f'{name}|lyapunov_high']:#.2g}] |")
    print(f"\ndouble pendulum over 10 s: {f['double-pendulum|lyapunov_10s']:.2g} "
          f"[{f['double-pendulum|lyapunov_10s_low']:.2g}, {f['double-pendulum|lyapunov_10s_high']:.2g}] /s")
    report(f, QUOTES, ROWS)

if __name__ == "__main__":
    main()
