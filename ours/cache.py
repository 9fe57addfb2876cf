"""Where ours keeps what it generates and what numba compiles: a user cache directory.

``cache_dir()`` is ``$XVAL_CACHE_DIR``, else ``$XDG_CACHE_HOME/xval``, else
``~/.cache/xval`` (a temporary folder when none of them can be created).
:func:`configure_numba` points numba's on-disk cache at ``<cache>/numba``
unless ``NUMBA_CACHE_DIR`` is already set, so compiled code is kept across
runs whether or not the source tree is writable; it imports nothing heavy.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path


def cache_dir() -> Path:
    """The user cache directory of xval (created if missing)."""
    explicit = os.environ.get("XVAL_CACHE_DIR")
    if explicit:
        candidates = [Path(explicit)]
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        candidates = [Path(base) / "xval"]
    candidates.append(Path(tempfile.gettempdir()) / f"xval-cache-{os.getuid() if hasattr(os, 'getuid') else 0}")
    for folder in candidates:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return folder
    return candidates[-1]


def configure_numba() -> None:
    """Send numba's cache to ``<cache>/numba`` unless NUMBA_CACHE_DIR says otherwise.

    Call before numba is imported; if it already is, its config is updated too.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    folder = str(cache_dir() / "numba")
    os.environ["NUMBA_CACHE_DIR"] = folder
    config = sys.modules.get("numba.core.config")
    if config is not None and not getattr(config, "CACHE_DIR", ""):
        config.CACHE_DIR = folder  # type: ignore[attr-defined]  # numba's settings module, read as it compiles


def write_whole(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all: a temporary file beside it (this process's own
    name), renamed into place, so a concurrent reader sees the old file or the new one; the temporary
    is removed if the write fails. Raises OSError (the caller decides whether a cache that cannot be
    written matters)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        temporary.write_bytes(data)
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
