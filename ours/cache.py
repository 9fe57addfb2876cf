"""Where numba keeps what it compiles for ours: the user cache directory (:func:`ours.files.cache_dir`).

:func:`configure_numba` points numba's on-disk cache at ``<cache>/numba``
unless ``NUMBA_CACHE_DIR`` is already set, so compiled code is kept across
runs whether or not the source tree is writable; it imports nothing heavy.
"""

from __future__ import annotations

import os
import sys

from ours.files import cache_dir


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
