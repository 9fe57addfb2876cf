"""Colours: one hue per engine family, one shade (and dash) per variant, the same in every report.

A family's hue is picked from :data:`FAMILY_COLOURS` by a stable hash of its
name (SHA-1, not Python's salted ``hash``), never by the order traces happen
to be drawn in, so ``mujoco`` is the same colour in every report of every
suite. Two families whose hashes collide in one report are told apart by
moving the later one (in name order) to the next free hue; only then can a
family's colour depend on which others are present. A variant's shade
(lightness), dash and marker symbol come from a hash of its whole label the same way. The
reference is always translucent black.
"""

from __future__ import annotations

import colorsys
import hashlib
from typing import Iterable

#: Base hues (Tableau 10 without its grey): well apart, readable on white, fine for most colour-blind readers.
FAMILY_COLOURS = ("#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2", "#9c755f", "#edc948",
                  "#ff9da7")
#: Lightness levels of a family's variants (HLS lightness, 0 black – 1 white).
SHADES = (0.30, 0.40, 0.50, 0.60, 0.35, 0.45, 0.55, 0.65)
#: Dashes a variant may get, so two variants of one family differ even when their shades are close.
DASHES = ("solid", "dash", "dot", "dashdot", "longdash")
REFERENCE_COLOUR = "rgba(0,0,0,0.45)"
#: Colour of a variant a plot mutes (one the verdict does not name: reports.emphasis).
GREY = "#c4c4c4"
#: Marker symbols a variant may get (plotly names), so variants of one family differ in shape as well.
SYMBOLS = ("circle", "square", "diamond", "triangle-up", "triangle-down", "cross", "x", "star", "pentagon",
           "hexagon")


#: Prefix of every hashed name. Any fixed prefix gives stable colours; this one (found by trying prefixes in
#: turn) gives the built-in families and the ones planned (drake, mjx, command) distinct hues without a
#: collision, the four built-in ones the four most distinct.
SALT = "xval2554:"


def _digest(text: str) -> int:
    return int.from_bytes(hashlib.sha1((SALT + text).encode("utf-8")).digest()[:8], "big")


def family_of(engine: str) -> str:
    """The family of a variant label: the part before the first ``/``."""
    return engine.split("/", 1)[0]


def family_colours(families: Iterable[str]) -> dict[str, str]:
    """Family -> base colour (hex) for the families of one report (see the module docstring)."""
    taken: dict[int, str] = {}
    result: dict[str, str] = {}
    for name in sorted(set(families)):
        slot = _digest(name) % len(FAMILY_COLOURS)
        for step in range(len(FAMILY_COLOURS)):
            candidate = (slot + step) % len(FAMILY_COLOURS)
            if candidate not in taken:
                slot = candidate
                break
        taken[slot] = name
        result[name] = FAMILY_COLOURS[slot]
    return result


def shade(base: str, lightness: float) -> str:
    """``base`` (#rrggbb) at HLS ``lightness``, saturation kept."""
    r, g, b = (int(base[i:i + 2], 16) / 255 for i in (1, 3, 5))
    h, _, s = colorsys.rgb_to_hls(r, g, b)
    r, g, b = colorsys.hls_to_rgb(h, lightness, max(s, 0.45))
    return "#" + "".join(f"{round(c * 255):02x}" for c in (r, g, b))


class Palette:
    """Line styles of a report's variants: ``palette.style(label)`` -> {"color", "dash"}."""

    def __init__(self, engines: Iterable[str]) -> None:
        engines = list(engines)
        self.families = family_colours(family_of(e) for e in engines if family_of(e) != "reference")

    def colour(self, engine: str) -> str:
        base = self.families.get(family_of(engine)) or FAMILY_COLOURS[_digest(family_of(engine)) % len(FAMILY_COLOURS)]
        return shade(base, SHADES[_digest(engine) % len(SHADES)])

    def family_colour(self, family: str) -> str:
        return self.families.get(family) or FAMILY_COLOURS[_digest(family) % len(FAMILY_COLOURS)]

    def symbol(self, engine: str) -> str:
        """The marker symbol of a variant (from a hash of its label, independent of its shade and dash)."""
        return SYMBOLS[(_digest(engine) >> 32) % len(SYMBOLS)]

    def style(self, engine: str) -> dict[str, str]:
        if family_of(engine) == "reference":
            return {"color": REFERENCE_COLOUR, "dash": "solid"}
        return {"color": self.colour(engine), "dash": DASHES[(_digest(engine) >> 16) % len(DASHES)]}
