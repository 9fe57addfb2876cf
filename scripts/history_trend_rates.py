"""How often the trend page's step rule (compare.history.trend.steps) marks a step in pure noise, and how often it finds a real one.

Series of 12 runs of a timing (cost per simulated second) with log-normal
noise of the stated size; "step" series multiply the last 6 runs by the
factor. A step is "found" when exactly one is marked, at run 7. Seeded, so
it prints the same figures every time; docs/history.md quotes them.

    .venv/bin/python scripts/history_trend_rates.py
"""

from __future__ import annotations

import numpy as np

from compare.history.trend import SIGMAS, steps
from compare.results.declared import METRICS, TIMING_METRIC

RUNS = 12
TRIALS = 2000


def main() -> None:
    rng = np.random.default_rng(20261201)
    metric = METRICS[TIMING_METRIC]
    print(f"step rule: SIGMAS = {SIGMAS:g}, {RUNS} runs per series, {TRIALS} series per row")
    print(f"{'noise':>6} {'step':>5} {'false alarms':>13} {'found':>7}")
    for noise, factor in ((0.05, 1.3), (0.10, 1.5), (0.20, 2.0)):
        false_alarms = found = 0
        step = np.r_[np.ones(RUNS // 2), factor * np.ones(RUNS - RUNS // 2)]
        for _ in range(TRIALS):
            values = 1e-2 * np.exp(noise * rng.standard_normal(RUNS))
            false_alarms += bool(steps(list(values), metric))
            marked = steps(list(values * step), metric)
            found += len(marked) == 1 and marked[0].index == RUNS // 2
        print(f"{noise:>6.0%} {factor:>4.1f}× {false_alarms / TRIALS:>13.1%} {found / TRIALS:>7.1%}")


if __name__ == "__main__":
    main()
