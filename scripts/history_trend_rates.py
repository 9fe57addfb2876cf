"""How often the trend page's step rule (compare.history.trend.steps) marks a step in pure noise, and how often it finds a real one.

Series of 12 runs of a timing (cost per simulated second) with log-normal
noise of the stated size; "step" series multiply the last 6 runs by the
factor. A step is "found" when exactly one is marked, at run 7. Seeded, so
it prints the same figures every time; docs/history.md quotes the table and
three of its rates in its module notes (scripts/quotes/history_trend_rates.toml,
checked by tests/test_docs_figures.py).

    .venv/bin/python scripts/history_trend_rates.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import load_quotes, report  # noqa: E402

from compare.history.trend import SIGMAS, steps  # noqa: E402
from compare.results.declared import METRICS, TIMING_METRIC  # noqa: E402

RUNS = 12
TRIALS = 2000
#: (log-normal noise, step factor) of each row of the printed table (quoted.py's ROWS are something else: doc table rows).
NOISE_AND_STEP = ((0.05, 1.3), (0.10, 1.5), (0.20, 2.0))
SLOW: set[str] = set()


def figures(quick: bool = False) -> dict[str, float]:
    """Per row, the fraction of noise-only series with a step marked (``false_alarms_<noise %>``) and of
    step series with exactly the right one (``found_<noise %>``). ``quick`` changes nothing (seconds)."""
    rng = np.random.default_rng(20261201)
    metric = METRICS[TIMING_METRIC]
    f: dict[str, float] = {}
    for noise, factor in NOISE_AND_STEP:
        false_alarms = found = 0
        step = np.r_[np.ones(RUNS // 2), factor * np.ones(RUNS - RUNS // 2)]
        for _ in range(TRIALS):
            values = 1e-2 * np.exp(noise * rng.standard_normal(RUNS))
            false_alarms += bool(steps(list(values), metric))
            marked = steps(list(values * step), metric)
            found += len(marked) == 1 and marked[0].index == RUNS // 2
        f[f"false_alarms_{noise:.0%}"] = false_alarms / TRIALS
        f[f"found_{noise:.0%}"] = found / TRIALS
    return f


QUOTES = load_quotes(__file__)
ROWS: list = []


def main() -> None:
    f = figures()
    print(f"step rule: SIGMAS = {SIGMAS:g}, {RUNS} runs per series, {TRIALS} series per row")
    print(f"{'noise':>6} {'step':>5} {'false alarms':>13} {'found':>7}")
    for noise, factor in NOISE_AND_STEP:
        print(f"{noise:>6.0%} {factor:>4.1f}× {f[f'false_alarms_{noise:.0%}']:>13.1%} {f[f'found_{noise:.0%}']:>7.1%}")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
