"""The one import of PyBullet in xval (``pb``), its build-time print kept out of the caller's output, and
the installed version."""

from __future__ import annotations

import functools

from engines.stdio import quiet_output

with quiet_output():
    import pybullet as pb  # prints "pybullet build time: ..." at import


@functools.lru_cache(maxsize=1)
def version() -> str:
    """The installed pybullet's version (read from its metadata once: each read scans the installed
    distributions, and every run records it)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("pybullet")
    except PackageNotFoundError:
        return f"api {pb.getAPIVersion()}"
