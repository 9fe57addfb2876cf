"""No test process holds JAX when it forks: a test that imports JAX into it, or forks with it loaded, fails.

JAX starts threads when imported, and a process with threads that forks may deadlock in the child (JAX
warns "os.fork() was called ... JAX is multithreaded"). Test processes fork all the time (case hosts,
the reference's solver), so JAX must stay out of them: the MJX tests run MJX in a spawned process
(tests/test_engine_mjx.py), and xval itself imports JAX only inside the case host running an MJX case
(tests/test_jax_fork.py).

Loaded for every pytest run (pyproject.toml: ``-p fork_guard``). A test module whose import (collection)
loads JAX fails to collect, naming it (e.g. a module-level ``pytest.importorskip("mujoco.mjx")``); a test
fails whose setup, call or teardown leaves JAX imported in the test process, or forks (os.fork,
multiprocessing's fork) with JAX loaded, whatever imported it.
"""

from __future__ import annotations

import os
import sys

import pytest

#: Forks made with JAX loaded since the last test ended (the before-fork hook cannot fail the test itself).
_FORKS_WITH_JAX: list[int] = []


def _before_fork() -> None:
    if "jax" in sys.modules:
        _FORKS_WITH_JAX.append(os.getpid())


os.register_at_fork(before=_before_fork)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> object:
    had_jax = "jax" in sys.modules
    outcome = yield
    if not had_jax and "jax" in sys.modules:
        # Fail the importer here: left alone, JAX would stay loaded and every later forking test would fail.
        report = outcome.get_result()
        report.outcome = "failed"
        report.longrepr = (f"collecting {collector.nodeid} imported JAX into the test process, which forks later "
                           "(case hosts): don't import mujoco.mjx or jax at module level (importorskip imports "
                           "it; use importlib.util.find_spec) and run MJX in a spawned process or a case host")
    return None


def _guarded(phase: str) -> object:
    had_jax = "jax" in sys.modules
    _FORKS_WITH_JAX.clear()
    yield
    if _FORKS_WITH_JAX:
        pytest.fail(f"the test's {phase} forked the test process {len(_FORKS_WITH_JAX)} time(s) with JAX imported, "
                    "which may deadlock the child: keep JAX out of any process that forks (run it in a spawned "
                    "one)", pytrace=False)
    if not had_jax and "jax" in sys.modules:
        pytest.fail(f"this test's {phase} imported JAX into the test process, which forks later (case hosts): "
                    "run MJX in a spawned process or in a case host", pytrace=False)
    return None


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> object:
    return (yield from _guarded("setup"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item) -> object:
    return (yield from _guarded("call"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item) -> object:
    return (yield from _guarded("teardown"))
