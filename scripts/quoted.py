"""Figures quoted in docs/, tied to the script that produces them.

Every script in scripts/ that docs quote defines

- ``figures(quick=False) -> dict[str, float]``: each figure it measures, by key;
  ``quick`` leaves out the expensive ones (named in its ``SLOW`` set);
- ``QUOTES``: :class:`Quote` records, one number as a doc quotes it (data, kept in
  ``scripts/quotes/<script>.toml`` and read by :func:`load_quotes`), and
  ``ROWS``: :class:`Row` records, one Markdown table row of a doc against keys;

and its ``main()`` prints its tables and then :func:`report` (every quoted figure,
measured against quoted). tests/test_docs_figures.py calls ``figures(quick=True)``
and fails when a doc no longer contains a quote, or a quoted number is not what the
script measures now within the quote's :class:`Tolerance`: by default the digits the
doc shows (:func:`shown`); a quote whose figure moves with round-off (an estimate
from a chaotic orbit, a time near a horizon) declares how far it may move and why.
The same test runs each script again with the initial states moved by a few ulps
(``XVAL_ROUNDOFF_ULPS``, engines/scene/catalog.py), a second machine inside CI.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

ROOT = Path(__file__).resolve().parent.parent

_NUMBER = re.compile(r"[−-]?\d[\d,]*(?:\.\d+)?(?:\s*[eE×]\s*[−-]?\d+|·10\^?[−-]?\d+)?")
#: The digits after the decimal point, and the power of ten, of a number as _NUMBER matches it.
_DECIMALS = re.compile(r"\.(\d+)")
_EXPONENT = re.compile(r"(?:[eE×]|·10\^?)\s*([−-]?\d+)$")


@dataclass(frozen=True)
class Tolerance:
    """How far a measured figure may be from its quote, and why (``why``: one sentence, required).

    relative : a fraction of the quoted number; absolute : in the quote's own units; interval :
    (low, high), the figure must lie in it (an estimate quoted with its spread). A figure holds
    when it is within the relative or the absolute tolerance of the quote (or inside the interval).
    """

    why: str
    relative: float = 0.0
    absolute: float = 0.0
    interval: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not self.why.strip():
            raise ValueError("a tolerance must say why the figure may move that far")
        if self.interval is not None:
            object.__setattr__(self, "interval", (float(self.interval[0]), float(self.interval[1])))
        elif not (self.relative > 0 or self.absolute > 0):
            raise ValueError("a tolerance needs relative > 0, absolute > 0 or an interval")

    def holds(self, measured: float, quoted: float) -> bool:
        """Whether ``measured`` (in the quote's units) is within this tolerance of ``quoted``."""
        if not math.isfinite(measured) or not math.isfinite(quoted):
            return measured == quoted
        if self.interval is not None:
            return self.interval[0] <= measured <= self.interval[1]
        return abs(measured - quoted) <= max(self.relative * abs(quoted), self.absolute) * (1 + 1e-9)

    def describe(self) -> str:
        if self.interval is not None:
            return f"within [{self.interval[0]:g}, {self.interval[1]:g}]"
        parts = ([f"±{self.relative:.3g} relative"] if self.relative else []) + (
            [f"±{self.absolute:g}"] if self.absolute else [])
        return "within " + " or ".join(parts)


#: What a quote without a tolerance of its own is held to: the digits the doc shows. Such a figure is
#: deterministic and far from any chaotic horizon (round-off moves it ~1e-15 relative), so the second,
#: perturbed pass of the quote test keeps it at the same digits on any machine.
DIGITS_SHOWN = "rounds to the digits the doc shows"


def within(measured: float, text: str, tolerance: Tolerance | None = None, unit: float = 1.0) -> bool:
    """Whether ``measured`` (the quoted number × ``unit``) holds against the quote ``text``: within
    ``tolerance``, or when there is none, rounding to ``text`` at the digits it shows (:func:`shown`)."""
    if tolerance is None:
        return shown(measured, text, unit)
    return tolerance.holds(measured / unit, number(text))


@dataclass(frozen=True)
class Quote:
    """``text`` (a number, as written, e.g. "3.8e-2" or "0.86%") appears in ``doc`` and is figure ``key``."""

    doc: str
    text: str
    key: str
    context: str = ""  # words around it in the doc ("{}" marks the number), when the bare number is ambiguous
    unit: float = 1.0  # the figure is the quoted number times this (0.01 for a figure in m quoted in cm)
    tolerance: Tolerance | None = None  # how far the figure may move, and why; None: DIGITS_SHOWN


@dataclass(frozen=True)
class Case:
    """A scene of the catalog (``scene`` with ``parameters``) and a time step ``dt`` (s) a script measures on."""

    label: str
    scene: str
    parameters: Mapping[str, Any]
    dt: float


@dataclass(frozen=True)
class Row:
    """The table row of ``doc`` whose first cell starts with ``label``: its numeric cells are ``keys`` in order.

    A key of None skips that cell (a timing, or a cell that is not a number); a tuple of keys
    reads the cell's numbers in order ("6.6e-3 m / 0.015").
    """

    doc: str
    label: str
    keys: tuple[str | None | tuple[str | None, ...], ...]
    after: str = ""  # look for the row only after this text (a heading), when labels repeat in the doc
    #: How far a cell's figure may move, and why, by its key; a key not here: DIGITS_SHOWN.
    tolerances: Mapping[str, Tolerance] = field(default_factory=dict)


def load_quotes(script: str | Path) -> list[Quote]:
    """The quotes of ``script`` (its ``__file__``): the ``[[quote]]`` tables of ``scripts/quotes/<name>.toml``;
    a quote's ``tolerance = {why = "...", relative = 0.1}`` (or ``absolute``, ``interval = [low, high]``)."""
    path = Path(script).resolve().parent / "quotes" / f"{Path(script).stem}.toml"
    with path.open("rb") as handle:
        entries = tomllib.load(handle)["quote"]
    return [Quote(**{**entry, "tolerance": Tolerance(**entry["tolerance"])} if "tolerance" in entry else entry)
            for entry in entries]


def number(text: str) -> float:
    """The value of a number as docs write it: "3.8e-2", "−1.3e-6", "1,000", "0.86%" (→ 0.0086), "2.6 m", "true" (1)."""
    word = text.strip().strip("*`").lower()
    if word in ("true", "yes"):
        return 1.0
    if word in ("false", "no"):
        return 0.0
    if word in ("none", "never"):  # a horizon or a divergence time that never came
        return math.inf
    match = _NUMBER.search(text.replace("\u2212", "-"))
    if match is None:
        raise ValueError(f"no number in {text!r}")
    raw = match.group(0).replace(",", "").replace(" ", "").replace("×", "e").replace("−", "-")
    value = float(raw)
    if text.strip().endswith("%"):
        value /= 100.0
    return value


def half_step(text: str) -> float:
    """Half a unit in the last digit ``text`` shows, in the units :func:`number` reads it in: "3.8e-2" → 5e-4,
    "0.86%" → 5e-5, "1,000 s" → 0.5; 0 for the words (true, none, ...), which must match exactly."""
    match = _NUMBER.search(text.replace("\u2212", "-"))
    if match is None or text.strip().strip("*`").lower() in ("true", "yes", "false", "no", "none", "never"):
        return 0.0
    raw = match.group(0)
    exponent = _EXPONENT.search(raw)
    mantissa = raw[: exponent.start()] if exponent else raw
    decimals = _DECIMALS.search(mantissa)
    step = 10.0 ** (-(len(decimals.group(1)) if decimals else 0) + (int(exponent.group(1).replace("−", "-")) if exponent else 0))
    return 0.5 * step / (100.0 if text.strip().endswith("%") else 1.0)


def shown(measured: float, text: str, unit: float = 1.0) -> bool:
    """Whether ``measured`` (a figure, = the quoted number × ``unit``) rounds to ``text`` at the digits it shows."""
    quoted = number(text)
    if not math.isfinite(quoted) or not math.isfinite(measured):
        return measured == quoted * unit
    # A relative 1e-9 for the binary round-off of the quote's own decimal digits (0.15 is not exact).
    return abs(measured / unit - quoted) <= half_step(text) * (1 + 1e-9) + 1e-12 * abs(quoted)


def row_cells(doc_text: str, label: str, after: str = "") -> list[str] | None:
    """The cells after the first of the first table row in ``doc_text`` (past ``after``) whose first cell is
    ``label``, or else starts with it."""
    start = doc_text.find(after) if after else 0
    if start < 0:
        return None
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in doc_text[start:].splitlines() if line.startswith("|")]
    # A label with "|" in it names the first cells together ("| error_bias = 0" for a row whose
    # first cell is empty; use ``after`` to say below which row to look).
    n = label.count("|") + 1
    label = label.strip()
    for exact in (True, False):  # a row whose first cells are exactly ``label`` win over a longer one
        for cells in rows:
            head = " | ".join(cells[:n]).strip()
            if cells and (head == label if exact else head.startswith(label)):
                return cells[n:]
    return None


def problems(figures: Mapping[str, float], quotes: Iterable[Quote], rows: Iterable[Row]) -> list[str]:
    """Every quote or row cell that is missing from its doc or is not the figure at the digits shown; [] when all hold.

    Quotes and rows whose key is not in ``figures`` (left out by a quick run) are checked for
    presence in the doc only.
    """
    out: list[str] = []
    docs: dict[str, str] = {}

    def text_of(doc: str) -> str:
        if doc not in docs:
            docs[doc] = (ROOT / doc).read_text()
        return docs[doc]

    for q in quotes:
        where = text_of(q.doc)
        needle = q.context.replace("{}", q.text) if q.context else q.text
        if needle not in where:
            out.append(f"{q.doc}: quote {needle!r} ({q.key}) is not in the doc")
            continue
        if q.key in figures and not within(figures[q.key], q.text, q.tolerance, q.unit):
            out.append(f"{q.doc}: {q.key} is quoted as {q.text} but measures {figures[q.key] / q.unit:.6g}"
                       f" ({q.tolerance.describe() if q.tolerance else DIGITS_SHOWN} expected)")
    for r in rows:
        cells = row_cells(text_of(r.doc), r.label, r.after)
        if cells is None:
            out.append(f"{r.doc}: no table row starting {r.label!r}")
            continue
        for key, cell in zip(r.keys, cells):
            # A tuple of keys: the cell holds several numbers ("6.6e-3 m / 0.015"), one key each.
            pairs = zip(key, [m.group(0) for m in _NUMBER.finditer(cell.replace("\u2212", "-"))]) \
                if isinstance(key, tuple) else [(key, cell)]
            for one, text in pairs:
                if one is None or one not in figures:
                    continue
                tolerance = r.tolerances.get(one)
                if not within(figures[one], text, tolerance):
                    out.append(f"{r.doc}: row {r.label!r}: {one} is quoted as {text} but measures {figures[one]:.6g}"
                               f" ({tolerance.describe() if tolerance else DIGITS_SHOWN} expected)")
    return out


def report(figures: Mapping[str, float], quotes: Iterable[Quote], rows: Iterable[Row]) -> None:
    """Print every figure (key = value) and then any quote that no longer holds."""
    print("\n## Figures\n")
    for key in sorted(figures):
        print(f"{key} = {figures[key]:.4g}")
    found = problems(figures, quotes, rows)
    print("\n" + ("\n".join(found) if found else "every quoted figure is what this run measured, within its tolerance"))
