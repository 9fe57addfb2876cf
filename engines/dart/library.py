"""The one import of DART (dartpy) in xval: ``dartpy()`` imports it on first use (0.6 s), and its version.

dartpy is imported where a skeleton is built, and by ``preload`` before a run forks; listing the engines
needs only to know it is installed.
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
from types import ModuleType

if importlib.util.find_spec("dartpy") is None:
    raise ImportError("No module named 'dartpy'")


@functools.cache
def dartpy() -> ModuleType:
    """The dartpy module."""
    import dartpy as dart

    return dart


def version() -> str:
    """dartpy's version, from the installed wheel's metadata (no import of dartpy needed)."""
    return importlib.metadata.version("dartpy")
