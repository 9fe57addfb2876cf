"""Time series thinned for drawing: at most :data:`MAX_POINTS` points per trace, peaks kept.

Largest-Triangle-Three-Buckets (Steinarsson 2013): the first and last
points are kept; the rest are cut into equal buckets, and from each the
point that makes the largest triangle with the previous pick and the next
bucket's mean is kept. Unlike taking every k-th sample it keeps the spikes
a blow-up or a constraint-force kick makes. Gaps (None, a non-finite
sample) are kept as gaps.
"""

from __future__ import annotations

import math
from typing import Sequence, TypeGuard

#: Most points drawn per trace.
MAX_POINTS = 2000


def _finite(value: object) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and math.isfinite(value)


def lttb_indices(x: Sequence[float], y: Sequence[float | None], limit: int = MAX_POINTS) -> list[int]:
    """Indices of at most ``limit`` (≥ 3) points of (x, y) chosen by LTTB, increasing; x (n,) increasing.

    A point whose y is None stays a gap: the first None after a finite run is kept, so the line breaks.
    """
    n = len(x)
    if n <= limit:
        return list(range(n))
    limit = max(limit, 3)
    keep = [0]
    every = (n - 2) / (limit - 2)
    values = [v if _finite(v) else math.nan for v in y]  # gaps as NaN: floats from here on
    a = 0
    for bucket in range(limit - 2):
        start = int(bucket * every) + 1
        stop = min(int((bucket + 1) * every) + 1, n - 1)
        nxt_start, nxt_stop = stop, min(int((bucket + 2) * every) + 1, n)
        nxt = [(x[i], values[i]) for i in range(nxt_start, nxt_stop) if math.isfinite(values[i])]
        if nxt:
            mean_x = sum(p[0] for p in nxt) / len(nxt)
            mean_y = sum(p[1] for p in nxt) / len(nxt)
        else:
            mean_x, mean_y = x[min(nxt_start, n - 1)], 0.0
        gap = next((i for i in range(start, stop) if not math.isfinite(values[i])), None)
        if gap is not None and math.isfinite(values[keep[-1]]):
            keep.append(gap)  # a break in the line must survive the thinning
            a = gap
            continue
        ya = values[a] if math.isfinite(values[a]) else 0.0
        best, area = start, -1.0
        for i in range(start, stop):
            if not math.isfinite(values[i]):
                continue
            value = abs((x[a] - mean_x) * (values[i] - ya) - (x[a] - x[i]) * (mean_y - ya))
            if value > area:
                best, area = i, value
        keep.append(best)
        a = best
    keep.append(n - 1)
    return sorted(set(keep))


def decimate(x: Sequence[float], *ys: Sequence[float | None], limit: int = MAX_POINTS) -> tuple[list, ...]:
    """(x, *ys) thinned to at most ``limit`` points, the indices chosen by LTTB on the first y."""
    if len(x) <= limit:
        return (list(x), *[list(y) for y in ys])
    index = lttb_indices(x, ys[0] if ys else [0.0] * len(x), limit)
    return ([x[i] for i in index], *[[y[i] for i in index] for y in ys])
