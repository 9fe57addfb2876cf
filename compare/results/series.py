"""A case's stored time series: at most MAX_SERIES_POINTS samples, rounded to SERIES_DIGITS digits.

The runner keeps each series as a rounded float array (:func:`round_each`); a
record it holds in memory reads them through :class:`SeriesView`, as nested
lists of floats the way the written file gives them.
"""

from __future__ import annotations

import functools
from typing import Any, Iterator, Mapping

import numpy as np

#: Most points kept per stored time series (evenly spaced, first and last kept).
MAX_SERIES_POINTS = 100
#: Significant digits kept in stored series (metrics keep full precision).
SERIES_DIGITS = 6


@functools.lru_cache(maxsize=256)
def downsample_indices(n: int, limit: int = MAX_SERIES_POINTS) -> np.ndarray:
    """At most ``limit`` indices into n samples, evenly spaced, always including the first and last.
    (Cached, as every case of a dt asks for the same ones: the array is read-only.)"""
    indices = np.arange(n) if n <= limit else np.unique(np.round(np.linspace(0, n - 1, limit)).astype(int))
    indices.flags.writeable = False
    return indices


def as_json_list(values: np.ndarray) -> list:
    """``values`` as nested lists of Python floats, None where a value is not finite (as JSON has it)."""
    array = np.asarray(values, dtype=float)
    finite = np.isfinite(array)
    if finite.all():
        return array.tolist()
    kept = array.astype(object)  # Python floats, so the non-finite entries can become None
    kept[~finite] = None
    return kept.tolist()


class SeriesView(Mapping[str, Any]):
    """A record's stored series (name -> rounded float array) read as the file gives them: nested lists
    of floats, None where a value is not finite.

    A run keeps the records it wrote in memory for its summary, which does not
    read their series; the lists (about five thousand Python floats a record,
    a fifth of the CPU of writing it) are made only for a reader that asks,
    one series at a time, and kept.
    """

    def __init__(self, arrays: Mapping[str, np.ndarray]) -> None:
        self._arrays = dict(arrays)
        self._lists: dict[str, list] = {}

    def __getitem__(self, name: str) -> list:
        if name not in self._lists:
            self._lists[name] = as_json_list(self._arrays[name])
        return self._lists[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._arrays)

    def __len__(self) -> int:
        return len(self._arrays)

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """The rounded float arrays themselves, for a writer that serialises numpy (orjson)."""
        return dict(self._arrays)


#: The largest power of ten a float64 holds exactly (10**22 < 2**53 · 2**22): scaling by it is exact.
_EXACT_POWER = 22
#: 10.0**k for k = 0 .. _EXACT_POWER, each exact.
_POWERS_OF_TEN = np.array([10.0**k for k in range(_EXACT_POWER + 1)])
#: How close (relative to the scaled value) to a half a scaled value is formatted rather than
#: rounded: four times the scaling's worst rounding error (2**-53).
_TIE_MARGIN = 4 * 2.0**-53


def round_significant(values: np.ndarray, digits: int = SERIES_DIGITS) -> np.ndarray:
    """``values`` (any shape) rounded to ``digits`` significant digits, as a float64 array of that shape.

    Each value is exactly what ``float(format(x, f".{digits}g"))`` gives, computed
    with array arithmetic (far faster than formatting each number,
    which was most of the CPU a run spent writing its records): x is scaled by an
    exact power of ten 10**k so that ``digits`` digits lie before the point,
    rounded to an integer m, and m / 10**k is the float nearest that decimal,
    which is what parsing the formatted string gives. The scaling is the one
    inexact step (relative error 1.1e-16), so a value whose scaled form lies
    that close to a half (a decimal tie: 1.0000050 to 6 digits) is formatted
    instead, as are zeros' neighbours below 10**-(22 - digits + 1) and values
    past 10**(22 + digits - 1) that no exact power can scale. Zeros and
    non-finite values come back as they are.
    """
    array = np.asarray(values, dtype=float)
    magnitude = np.abs(array)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # floor(log10) can be one off only within an ulp of a power of ten, where both exponents
        # round to the same decimal (that power), so no correction is needed. Zeros and non-finite
        # values give a non-finite shift and are kept as they are below.
        shift = (digits - 1) - np.floor(np.log10(magnitude))
        up = shift >= 0
        # 10**|shift| from a table of the exact powers (a lookup, not a pow per value); a shift past
        # the table is not exact anyway, and its value comes from formatting below.
        powers = np.abs(shift)
        scale = _POWERS_OF_TEN[np.where(powers <= _EXACT_POWER, powers, 0).astype(np.intp)]
        scaled = np.where(up, array * scale, array / scale)
        mantissa = np.rint(scaled)
        value = np.where(up, mantissa / scale, mantissa * scale)
        fraction = scaled - np.floor(scaled)
        exact = (np.abs(shift) <= _EXACT_POWER) & (np.abs(fraction - 0.5) > _TIE_MARGIN * np.abs(scaled))
    out = np.where(exact, value, array)
    rest = np.isfinite(array) & (magnitude > 0) & ~exact
    if rest.any():
        spec = f".{digits}g"
        out[rest] = [float(format(x, spec)) for x in array[rest].tolist()]
    return out


def round_each(arrays: Mapping[str, np.ndarray], digits: int = SERIES_DIGITS) -> dict[str, np.ndarray]:
    """Each array rounded by :func:`round_significant`, in one call over all their values (a record's
    series are a few small arrays: one call, not one each), each back in its own shape."""
    arrays = {name: np.asarray(values, dtype=float) for name, values in arrays.items()}
    if not arrays:
        return {}
    rounded = round_significant(np.concatenate([a.ravel() for a in arrays.values()]), digits)
    out, start = {}, 0
    for name, array in arrays.items():
        out[name] = rounded[start:start + array.size].reshape(array.shape)
        start += array.size
    return out
