"""Text from files shown on a terminal or in Markdown, made inert.

A suite's labels, a scene's name, a case file's message are data: one that
holds ANSI escape sequences (``\\x1b[2J`` clears the screen, ``\\x1b]8;;`` makes
links) or other control characters must print as visible text, not act on the
terminal. :func:`inert` replaces each control character (C0 but tab and
newline, DEL, C1) with its ``\\xNN`` escape. The CLI passes everything it
prints on stdout, and its error lines, through it (compare/cli.py).
"""

from __future__ import annotations

import re
from typing import Any

#: C0 controls except tab (\t) and newline (\n), DEL, and the C1 controls (which some terminals obey too).
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def inert(text: str) -> str:
    """``text`` with every control character (ESC, CR, BEL, ...) written as its visible ``\\xNN`` escape."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


class InertStream:
    """A text stream that writes :func:`inert` text to ``stream``; everything else is ``stream``'s."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        self._stream.write(inert(text))
        return len(text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)
