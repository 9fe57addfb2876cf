"""Colours and shapes: one hue and one marker shape per engine family, one dash per variant, the same in every report.

The hues are Okabe and Ito's colour-blind-safe set (distinct under the common red–green and blue–yellow
deficiencies), yellow replaced by Paul Tol's olive, which reads on white. A family's hue and its marker
shape share one slot, picked by a stable hash of its name (SHA-1, not Python's salted ``hash``), never by
the order traces happen to be drawn in, so ``mujoco`` is the same colour and shape in every report of every
suite. Two families whose hashes collide in one report are told apart by moving the later one (in name order)
to the next free slot; only then can a family's look depend on which others are present. Within a family the
variants differ by line style (dash) and slightly by lightness, from a hash of the whole label, so colour is
never the only cue. The reference is always translucent black.
"""

from __future__ import annotations

import colorsys
import hashlib
from typing import Iterable

#: Base hues: Okabe–Ito without black (the reference's) and with Tol's olive for their yellow.
FAMILY_COLOURS = ("#0072b2", "#e69f00", "#009e73", "#d55e00", "#cc79a7", "#56b4e9", "#999933")
#: One marker shape per family slot (plotly names; reports.svgplot draws the same shapes), so a family is
#: told by its shape without colour.
FAMILY_SYMBOLS = ("circle", "square", "diamond", "triangle-up", "triangle-down", "cross", "x")
#: Lightness offsets of a family's variants around its base (HLS): shades close enough to keep the hue's identity.
SHADES = (0.0, -0.08, 0.06, -0.04, 0.10, -0.12, 0.03, -0.02)
#: Dashes a variant may get: within a family, the line style tells the variants apart.
DASHES = ("solid", "dash", "dot", "dashdot", "longdash")
REFERENCE_COLOUR = "rgba(0,0,0,0.45)"
#: Colour of a variant a plot mutes (one the verdict does not name: reports.emphasis).
GREY = "#c4c4c4"
#: Prefix of every hashed name. Any fixed prefix gives stable slots; this one (found by trying prefixes in
#: turn) gives the built-in families and the ones planned (drake, dart, mjx) a slot each without a collision,
#: the four built-in ones the first four (the most distinct hues and shapes).
SALT = "xval104:"


def _digest(text: str) -> int:
    return int.from_bytes(hashlib.sha1((SALT + text).encode("utf-8")).digest()[:8], "big")


def family_of(engine: str) -> str:
    """The family of a variant label: the part before the first ``/``."""
    return engine.split("/", 1)[0]


def family_slots(families: Iterable[str]) -> dict[str, int]:
    """Family -> slot in FAMILY_COLOURS / FAMILY_SYMBOLS for the families of one report (see the module docstring)."""
    taken: dict[int, str] = {}
    result: dict[str, int] = {}
    for name in sorted(set(families)):
        slot = _digest(name) % len(FAMILY_COLOURS)
        for step in range(len(FAMILY_COLOURS)):
            candidate = (slot + step) % len(FAMILY_COLOURS)
            if candidate not in taken:
                slot = candidate
                break
        taken[slot] = name
        result[name] = slot
    return result


def family_colours(families: Iterable[str]) -> dict[str, str]:
    """Family -> base colour (hex) for the families of one report."""
    return {name: FAMILY_COLOURS[slot] for name, slot in family_slots(families).items()}


def shade(base: str, offset: float) -> str:
    """``base`` (#rrggbb) with its HLS lightness moved by ``offset`` (kept within 0.2–0.75), hue and saturation kept."""
    r, g, b = (int(base[i:i + 2], 16) / 255 for i in (1, 3, 5))
    h, lightness, s = colorsys.rgb_to_hls(r, g, b)
    r, g, b = colorsys.hls_to_rgb(h, min(max(lightness + offset, 0.2), 0.75), s)
    return "#" + "".join(f"{round(c * 255):02x}" for c in (r, g, b))


class Palette:
    """Line styles of a report's variants: ``palette.style(label)`` -> {"color", "dash"}."""

    def __init__(self, engines: Iterable[str]) -> None:
        engines = list(engines)
        self.slots = family_slots(family_of(e) for e in engines if family_of(e) != "reference")
        self.families = {name: FAMILY_COLOURS[slot] for name, slot in self.slots.items()}

    def _slot(self, family: str) -> int:
        slot = self.slots.get(family)
        return slot if slot is not None else _digest(family) % len(FAMILY_COLOURS)

    def colour(self, engine: str) -> str:
        base = FAMILY_COLOURS[self._slot(family_of(engine))]
        return shade(base, SHADES[_digest(engine) % len(SHADES)])

    def family_colour(self, family: str) -> str:
        return FAMILY_COLOURS[self._slot(family)]

    def symbol(self, engine: str) -> str:
        """The marker shape of a variant: its family's (one shape per family, FAMILY_SYMBOLS)."""
        return FAMILY_SYMBOLS[self._slot(family_of(engine))]

    def style(self, engine: str) -> dict[str, str]:
        if family_of(engine) == "reference":
            return {"color": REFERENCE_COLOUR, "dash": "solid"}
        return {"color": self.colour(engine), "dash": DASHES[(_digest(engine) >> 16) % len(DASHES)]}
