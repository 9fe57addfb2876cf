"""Cold start (issue 20): listing engines and importing the packages compile nothing.

`xval engines` loads every engine adapter (ours, the reference, MuJoCo, …) to
describe it; neither that nor ``import ours`` / ``import compare`` may import
numba (whose import alone costs about 0.3 s) or compile a function, and scipy's
integrators are not loaded until a reference is solved. Checked in a fresh
interpreter with an empty cache directory: nothing may be written to it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

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
                  "numba": "numba" in sys.modules, "integrate": "scipy.integrate" in sys.modules}))
"""


def test_xval_engines_imports_no_numba_and_compiles_nothing(tmp_path):
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "XVAL_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result == {"code": 0, "listed": True, "numba": False, "integrate": False}
    cache = tmp_path / "cache"
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*")), list(cache.rglob("*"))


RUN_PROBE = r"""
import json, sys
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
suite = parse_suite('''
name = "no-drake"
duration = 0.05
sample_interval = 0.01
dt = [1e-2]
[[scenes]]
id = "bead"
scene = "bead"
[[engines]]
id = "pymunk/pin"
''', path="inline.toml")
run_suite(suite, sys.argv[1], jobs=1)
engines = json.load(open(sys.argv[1] + "/run.json"))["environment"]["engines"]
print(json.dumps({"pydrake": "pydrake" in sys.modules, "drake": engines["drake"], "pymunk": engines["pymunk"]}))
"""


def test_a_run_without_drake_records_its_version_without_importing_it(tmp_path):
    """pydrake's import costs 0.15 s of CPU: a run that does not use Drake reads its installed version
    from the distribution's metadata for run.json instead."""
    done = subprocess.run([sys.executable, "-c", RUN_PROBE, str(tmp_path / "out")], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["pydrake"] is False
    assert result["drake"].startswith(("not used by this run (drake ", "unavailable: drake is not installed"))
    assert result["pymunk"][0].isdigit()  # a used engine's own version string
