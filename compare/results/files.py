"""Writing files so that a reader never sees half of one, and refusing unwritable paths up front."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from engines.errors import UserError


def check_writable(path: str | os.PathLike, flag: str = "--output") -> Path:
    """Raise UserError now, before any work, when ``path`` cannot be written."""
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise UserError(f"{flag}: {target} is a directory; give a file name")
    if not parent.is_dir():
        raise UserError(f"{flag}: directory {parent} does not exist; create it or choose another path")
    if not os.access(parent, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise UserError(f"{flag}: {target} is not writable; choose a path you can write")
    return target


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, fsync it, then rename it into place."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
