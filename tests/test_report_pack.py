"""The packer both pages share (reports/pack.py): what it writes is safe in a script element and unpacks
to the bytes it packed, at every length and whatever the bytes (the escapes at the end included)."""

from __future__ import annotations

import numpy as np

from reports.pack import ILLEGAL, from_seven_bit, packed_text, seven_bit, unpacked


def test_seven_bit_text_round_trips_and_holds_no_character_a_script_element_would_change():
    rng = np.random.default_rng(5)
    samples = [b"", b"\x00", b"<", b"\r", b"\x00" * 9, b"<" * 8, bytes(range(256))]
    samples += [rng.integers(0, 256, size=n, dtype=np.uint8).tobytes() for n in range(1, 80)]
    for data in samples:
        text = seven_bit(data)
        assert from_seven_bit(text) == data
        assert not set(text) & {"\x00", "\r", "<"}
        assert all(ord(c) < 128 or 0x100 <= ord(c) < 0x283 for c in text)
        assert len(text) == -(-len(data) * 8 // 7) - sum(ord(c) >= 0x100 and ord(c) < 0x280 for c in text)
    assert ILLEGAL == (0, 13, 60)


def test_packed_text_unpacks_to_the_text():
    text = "plot <script> & ünïcode " * 50
    assert unpacked(packed_text(text)) == text
    # Deterministic: the same text packs to the same characters (gzip's mtime is 0).
    assert packed_text(text) == packed_text(text)
