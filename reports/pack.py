"""Packing for the self-contained pages (the report and the history's trend page): one packer for both.

A page carries its bulk — plotly.js, figure specs, tables shown on demand —
gzip-compressed inside ``<script type="application/octet-stream">`` elements,
written as text seven bits to a character (:func:`seven_bit`: 8/7 of the
gzip size, where base64 is 4/3; plotly.js 7.1's 4.8 MB are 1.47 MB of gzip,
1.68 MB as text). The page unpacks an element with the browser's own
DecompressionStream (``templates/unpack.js.j2``, included by both templates)
only when it needs it, so the page is interactive before plotly.js is even
unpacked. ``mtime`` 0 keeps the bytes identical from run to run.
"""

from __future__ import annotations

import functools
import gzip
import json
from typing import Any

import numpy as np
from markupsafe import Markup

#: The ``data-encoding`` of every packed element (the page's decoder dispatches on it).
ENCODING = "gzip-7bit"
#: 7-bit values that may not appear as themselves in a script element's text: NUL and CR (the HTML
#: parser replaces them) and "<" (it could close the element). Each is written as one character of
#: ``PAIRED`` + 128·k + the next value (two UTF-8 bytes for 14 bits), or ``LAST`` + k at the end.
ILLEGAL = (0, 13, 60)
PAIRED, LAST = 0x100, 0x280
_WEIGHTS = np.array([64, 32, 16, 8, 4, 2, 1], dtype=np.uint32)


def seven_bit(data: bytes) -> str:
    """``data`` as text, seven bits per character (big-endian bit order, zero-padded), safe in a script element."""
    bits = np.unpackbits(np.frombuffer(data, dtype=np.uint8))
    bits = np.concatenate([bits, np.zeros(-len(bits) % 7, dtype=np.uint8)])
    values = bits.reshape(-1, 7).astype(np.uint32) @ _WEIGHTS
    codes, keep = values.copy(), np.ones(len(values), dtype=bool)
    skip = -1
    for i in np.flatnonzero(np.isin(values, ILLEGAL)).tolist():  # ~3 in 128 of the values
        if i == skip:  # already carried by the character before it
            continue
        k = ILLEGAL.index(int(values[i]))
        if i + 1 < len(values):
            codes[i], keep[i + 1], skip = PAIRED + 128 * k + values[i + 1], False, i + 1
        else:
            codes[i] = LAST + k
    return codes[keep].astype("<u4").tobytes().decode("utf-32-le")


def from_seven_bit(text: str) -> bytes:
    """The bytes :func:`seven_bit` wrote (the page's decoder in Python, for tests and readers)."""
    values: list[int] = []
    for c in map(ord, text):
        if c < 128:
            values.append(c)
        elif c >= LAST:
            values.append(ILLEGAL[c - LAST])
        else:
            values += [ILLEGAL[(c - PAIRED) >> 7], (c - PAIRED) & 127]
    bits = ((np.array(values, dtype=np.uint32)[:, None] >> np.arange(6, -1, -1, dtype=np.uint32)) & 1).ravel()
    return np.packbits(bits[: len(bits) // 8 * 8].astype(np.uint8)).tobytes()


def packed_text(text: str) -> Markup:
    """``text`` gzip-compressed (mtime 0: the same bytes every time) and written seven bits to a character."""
    return Markup(seven_bit(gzip.compress(text.encode("utf-8"), compresslevel=9, mtime=0)))


def unpacked(text: str) -> str:
    """The text :func:`packed_text` packed."""
    return gzip.decompress(from_seven_bit(text)).decode("utf-8")


def pack(items: dict[str, Any]) -> Markup:
    """Figure specs or other data (DOM id -> JSON value), packed (see :func:`packed_text`)."""
    return packed_text(json.dumps(items, separators=(",", ":"), allow_nan=False))


@functools.lru_cache(maxsize=1)
def plotly_js() -> Markup:
    """The plotly.js bundle shipped with the plotly package, packed (see :func:`packed_text`)."""
    from plotly.offline import get_plotlyjs

    return packed_text(get_plotlyjs())


def template_values() -> dict[str, Any]:
    """What both page templates need from the packer: plotly.js packed, and the encoding's constants
    for the page's decoder (``templates/unpack.js.j2``)."""
    return {"plotly_js": plotly_js(), "pack_encoding": ENCODING, "pack_illegal": ILLEGAL, "pack_paired": PAIRED,
            "pack_last": LAST}
