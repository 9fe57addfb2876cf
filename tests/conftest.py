"""What the tests share: the xval command (and :func:`run_xval`), the environment its processes need,
one poller, and fixtures.

The test-only modules beside this file (compare_engines, plugin_engines, gate_support, ...) and the
scripts are importable because pyproject.toml's ``[tool.pytest.ini_options] pythonpath`` puts tests/
and scripts/ on the path: no test edits ``sys.path``. A process a test starts gets them through
:data:`XVAL_ENV`'s ``PYTHONPATH``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, TypeVar

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: The xval command line, run by this interpreter (the tree under test, not an installed xval).
XVAL = [sys.executable, "-c", "from compare.cli import main; main()"]
#: The environment of an xval process a test starts: the tree and the test-only modules importable.
XVAL_ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), str(ROOT)])}

T = TypeVar("T")

#: Marks of a test that needs ours' complex- or tangent-typed rigid kernel, which takes minutes of CPU to compile
#: in a fresh numba cache: all of them run in one worker (one xdist group, the Makefile's --dist loadgroup), which
#: compiles it once while the others load it from the cache, with a limit that allows that compile under load.
RIGID_COMPILE = [pytest.mark.xdist_group("ours-rigid-compile"), pytest.mark.timeout(1500)]


def run_xval(*args: object, timeout: float = 120, cwd: Path = ROOT, **options) -> subprocess.CompletedProcess:
    """``xval ARGS...`` in a process of its own, from ``cwd`` (the repository root unless given) with
    :data:`XVAL_ENV`: its exit code and output as text (``options`` go to subprocess.run)."""
    return subprocess.run(XVAL + [str(a) for a in args], cwd=cwd, env=XVAL_ENV, capture_output=True, text=True,
                          timeout=timeout, **options)


def wait_for(predicate: Callable[[], T], seconds: float, what: str, interval: float = 0.05) -> T:
    """The first truthy value of ``predicate()``, polled every ``interval`` s; AssertionError after ``seconds``."""
    deadline = time.monotonic() + seconds
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {seconds} s waiting for {what}")
        time.sleep(interval)


@pytest.fixture(scope="session")
def double_pendulum():
    """(scene, reference solution): the catalog's double pendulum for 0.5 s, solved once per session."""
    from engines.scene import catalog
    from engines.reference.reference import solve

    scene = catalog.build("double-pendulum", {"duration": 0.5})
    return scene, solve(scene)
