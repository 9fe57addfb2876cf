"""Numbers for people: SI prefixes instead of exponents (``2.0 µm``, ``1.3 ms/s``), as the report prints them.

The report's tables keep one exponent format per column (so magnitudes line up down a column); the summary and
the verdict's sentences read better with a prefix. The text never breaks inside a number: the space between
value and unit is a no-break space (U+00A0).
"""

from __future__ import annotations

import math

#: (power of ten, prefix), largest first: from tera down to femto.
PREFIXES = ((12, "T"), (9, "G"), (6, "M"), (3, "k"), (0, ""), (-3, "m"), (-6, "µ"), (-9, "n"), (-12, "p"), (-15, "f"))
#: Between a value and its unit: a no-break space, so "12 µm" never wraps.
NBSP = "\u00a0"


def si(value: float | None, unit: str, digits: int = 2, missing: str = "–") -> str:
    """``value`` (in ``unit``) with an SI prefix and ``digits`` significant digits: si(1.28e-3, "s/s") ->
    "1.3 ms/s"; zero -> "0 unit"; outside fT–T the plain exponent form; ``missing`` for None or non-finite."""
    if value is None or not math.isfinite(value):
        return missing
    if value == 0:
        return f"0{NBSP}{unit}"
    rounded = float(f"{value:.{digits}g}")  # round first, so 999.96 m reads "1 km", not "1e+03 m"
    power = math.floor(math.log10(abs(rounded)))
    for exponent, prefix in PREFIXES:
        if power >= exponent:
            scaled = float(f"{rounded / 10.0 ** exponent:.{digits}g}")
            return f"{scaled:g}{NBSP}{prefix}{unit}"  # :g after rounding: 280, never 2.8e+02
    return f"{value:.{digits}g}{NBSP}{unit}"
