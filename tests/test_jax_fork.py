"""JAX is never imported in a process that forks afterwards: MJX runs in case hosts, which import it themselves.

JAX starts threads on import, and a fork of a process with them may deadlock (JAX warns "os.fork() was
called ... JAX is multithreaded"). So the xval process, which forks every case host, must never import
it: the MJX adapter imports JAX on first use (engines.mjx.library.jax_mjx), inside the host running the case, and
the host has forked its one child (the reaper) before any case runs.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# find_spec, not importorskip: importing mujoco.mjx would load JAX into this (forking) test process.
if importlib.util.find_spec("jax") is None or importlib.util.find_spec("mujoco.mjx") is None:
    pytest.skip("MJX is not installed: pip install 'xval[mjx]'", allow_module_level=True)

PROBE = """
import json, sys, warnings
warnings.simplefilter("always")
from compare.run.runner import run_suite
from compare.run.results import load_results
from compare.suite.reader import parse_suite
suite = parse_suite('name = "jax"\\nduration = 0.05\\ndt = [1e-2]\\n[[scenes]]\\nscene = "bead"\\n'
                    '[[engines]]\\nid = "mjx/hinge"\\n[[engines]]\\nid = "mujoco/hinge"\\n')
run_suite(suite, sys.argv[1], jobs=2)
print(json.dumps({"jax_here": "jax" in sys.modules,
                  "statuses": sorted(r.status.value for r in load_results(sys.argv[1]).records)}))
"""


def test_an_mjx_run_never_imports_jax_where_hosts_are_forked(tmp_path):
    done = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path / "r")], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, env={**os.environ, "PYTHONWARNINGS": "always"})
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.splitlines()[-1])
    assert seen == {"jax_here": False, "statuses": ["ok", "ok"]}  # MJX ran, in its host
    assert "os.fork()" not in done.stderr  # JAX's warning from any process that forked with it loaded


GUARDED = """
import os

import pytest


@pytest.fixture
def jax_module():
    import jax
    return jax


def test_given_jax_by_a_fixture(jax_module):
    pass


def test_imports_jax():
    import jax  # noqa: F401


def test_forks_with_jax_loaded():
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)


def test_forks_without_jax():
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)
"""


def guarded_pytest(directory: Path, *targets: str) -> subprocess.CompletedProcess:
    """pytest with tests/fork_guard.py on ``targets`` in ``directory``, in a fresh process (300 s: JAX imports)."""
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "fork_guard", "-p", "no:cacheprovider",
                           *targets], cwd=directory, env={**os.environ, "PYTHONPATH": str(ROOT / "tests")},
                          capture_output=True, text=True, timeout=300)


def test_the_test_processes_guard_fails_a_test_that_imports_jax_or_forks_with_it(tmp_path):
    # tests/fork_guard.py, loaded in every pytest run: the first test leaves JAX in the process, the second
    # forks with it loaded; both fail, naming why. A fixture importing JAX fails its test's setup. (The last
    # runs alone, in a process without JAX.)
    (tmp_path / "test_guarded.py").write_text(GUARDED)
    done = guarded_pytest(tmp_path, "test_guarded.py::test_imports_jax", "test_guarded.py::test_forks_with_jax_loaded")
    assert "2 failed" in done.stdout, done.stdout[-3000:]
    assert "this test's call imported JAX into the test process" in done.stdout
    assert "forked the test process 1 time(s) with JAX imported" in done.stdout
    fixture = guarded_pytest(tmp_path, "test_guarded.py::test_given_jax_by_a_fixture")
    assert "this test's setup imported JAX into the test process" in fixture.stdout, fixture.stdout[-3000:]
    alone = guarded_pytest(tmp_path, "test_guarded.py::test_forks_without_jax")
    assert "1 passed" in alone.stdout, alone.stdout[-3000:]


def test_the_guard_fails_the_module_that_imports_jax_at_collection_not_the_tests_after_it(tmp_path):
    # A module-level importorskip of mujoco.mjx loads JAX while collecting; the guard names that module, and
    # pytest stops before any test (which would otherwise fork with JAX loaded and be blamed).
    (tmp_path / "test_guarded.py").write_text(GUARDED)
    (tmp_path / "test_importer.py").write_text("import pytest\n\npytest.importorskip('jax')\n\n\n"
                                               "def test_nothing():\n    pass\n")
    done = guarded_pytest(tmp_path, "test_importer.py", "test_guarded.py::test_forks_without_jax")
    assert done.returncode == 2, done.stdout[-3000:]  # interrupted: errors during collection
    assert "collecting test_importer.py imported JAX into the test process" in done.stdout, done.stdout[-3000:]
    assert "1 error" in done.stdout and "passed" not in done.stdout and "failed" not in done.stdout
