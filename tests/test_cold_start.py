"""Cold start (issue 20): listing engines and importing the packages compile nothing.

`xval engines` loads every engine adapter (ours, the reference, MuJoCo, …) to
describe it; neither that nor ``import ours`` / ``import compare`` may import
numba (whose import alone costs about 0.3 s) or compile a function, scipy's
integrators are not loaded until a reference is solved, and pydrake not until
a Drake plant is built. Checked in a fresh
interpreter with an empty cache directory: nothing may be written to it.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

PROBE = r"""
import contextlib, io, json, sys
import compare, ours
from compare.cli import main
out = io.StringIO()
with contextlib.redirect_stdout(out):
    try:
        main(["engines"])
    except SystemExit as exc:
        code = exc.code
    else:
        code = 0
print(json.dumps({"code": code, "listed": "ours/baumgarte-rk4" in out.getvalue(),
                  "numba": "numba" in sys.modules, "integrate": "scipy.integrate" in sys.modules,
                  "drake_variants": "drake/" in out.getvalue(), "drake_pip_line": "xval[drake]" in out.getvalue(),
                  "pydrake": "pydrake" in sys.modules}))
"""


def test_xval_engines_imports_no_numba_and_compiles_nothing(tmp_path):
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "XVAL_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    # Drake is listed (with its variants when installed, else with the pip line) without importing pydrake.
    installed = importlib.util.find_spec("pydrake") is not None
    assert result == {"code": 0, "listed": True, "numba": False, "integrate": False, "drake_variants": installed,
                      "drake_pip_line": not installed, "pydrake": False}
    cache = tmp_path / "cache"
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*")), list(cache.rglob("*"))


#: Runs the suite given as TOML in argv[1] into argv[2] with one job, and prints what the run imported,
#: the engine versions run.json records and each case's position error.
RUN_PROBE = r"""
import json, sys
from pathlib import Path
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from compare.results.store import iter_records
out = Path(sys.argv[2])
run_suite(parse_suite(sys.argv[1], path="inline.toml"), out, jobs=1)
print(json.dumps({
    "pydrake": "pydrake" in sys.modules, "integrate": "scipy.integrate" in sys.modules,
    "engines": json.loads((out / "run.json").read_text())["environment"]["engines"],
    "errors": {r.case.id: r.metrics["position_error_linf"] for r in iter_records(out / "cases")},
}))
"""


def run_probe(suite: str, out: Path, env: dict | None = None) -> dict:
    done = subprocess.run([sys.executable, "-c", RUN_PROBE, suite, str(out)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_run_without_drake_records_its_version_without_importing_it(tmp_path):
    """pydrake's import is dear: a run that does not use Drake reads its installed version from the
    distribution's metadata for run.json instead."""
    suite = ('duration = 0.05\nsample_interval = 0.01\ndt = [1e-2]\n[[scenes]]\nscene = "bead"\n'
             '[[engines]]\nid = "pymunk/pin"\n')
    result = run_probe(suite, tmp_path / "out")
    assert result["pydrake"] is False
    if importlib.util.find_spec("pydrake") is not None:
        assert result["engines"]["drake"] == f"not used by this run (drake {importlib.metadata.version('drake')} installed)"
    else:
        assert result["engines"]["drake"].startswith("unavailable: drake is not installed")
    assert result["engines"]["pymunk"][0].isdigit()  # a used engine's own version string


#: The process's threads (Linux /proc) and the environment variable after importing the run command's
#: module and then numpy and scipy.linalg.
THREADS = r"""
import json, os
threads = lambda: len(os.listdir("/proc/self/task"))
import compare.commands.run
import numpy, scipy.linalg
print(json.dumps({"threads": threads(), "variable": os.environ.get("OPENBLAS_NUM_THREADS")}))
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir() or (os.cpu_count() or 1) < 2, reason="Linux, 2+ cores")
@pytest.mark.parametrize("preset", [None, "2"])
def test_a_run_loads_blas_with_one_thread_and_leaves_the_environment_as_it_was(tmp_path, preset):
    # OpenBLAS (numpy's and scipy's copies) would start a thread per core each as it loads: the run
    # command loads both with one, and programs it starts still see the environment the user gave.
    # A number the user chose is kept: 2 threads for each copy (the main thread plus one each).
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    done = subprocess.run([sys.executable, "-c", THREADS], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert seen == {"threads": 1 if preset is None else 3, "variable": preset}


def test_a_second_run_takes_its_reference_samples_from_the_cache_without_scipy(tmp_path):
    # The first run solves the reference in a case host (its parent loads scipy's integrators to fork
    # them) and keeps it with its samples at both dts' times; the second finds them there: the kept
    # file is not written again, neither the parent nor anything it computes needs scipy's
    # integrators, and every case's error against the reference is the same.
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "XVAL_CACHE_DIR": str(tmp_path / "cache")}
    suite = ('duration = 0.5\nsample_interval = 0.01\ndt = [1e-2, 1e-3]\n[[scenes]]\nscene = "double-pendulum"\n'
             '[[engines]]\nid = "mujoco/hinge"\n')
    first = run_probe(suite, tmp_path / "first", env)
    [kept] = (tmp_path / "cache" / "reference").glob("*.pickle")
    written = kept.stat().st_mtime_ns
    second = run_probe(suite, tmp_path / "second", env)
    assert first["integrate"] is True and second["integrate"] is False
    assert kept.stat().st_mtime_ns == written
    assert second["errors"] == first["errors"] and len(first["errors"]) == 2
