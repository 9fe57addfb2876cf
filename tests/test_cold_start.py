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
