"""Every code snippet in docs/plugins.md runs: the Python ones are executed (and the adapters they define are
simulated and checked against the reference: the order the docstring claims, forces reported in part), the TOML
ones parse, and the shell one (the CI gate) runs against a suite of the page's own adapters.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest

from engines.scene import catalog
from engines.errors import Unsupported
from engines.reference.reference import solve

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "plugins.md"
BLOCK = re.compile(r"^(?P<indent> *)```(?P<lang>\w+)\n(?P<body>.*?)^(?P=indent)```", re.M | re.S)


def snippets(lang: str) -> list[str]:
    return [textwrap.dedent(m.group("body")) for m in BLOCK.finditer(DOC.read_text()) if m.group("lang") == lang]


def test_the_page_has_the_snippets_this_test_runs():
    assert len(snippets("python")) == 3 and len(snippets("toml")) == 1 and len(snippets("sh")) == 1


@pytest.mark.parametrize("index", range(3))
def test_every_python_snippet_runs(index):
    exec(compile(snippets("python")[index], f"docs/plugins.md python block {index + 1}", "exec"), {})


def adapter(index: int):
    namespace: dict = {}
    exec(compile(snippets("python")[index], f"docs/plugins.md python block {index + 1}", "exec"), namespace)
    return namespace["ENGINE"]


def position_errors(engine, scene, dts):
    reference = solve(scene)
    out = []
    for dt in dts:
        trajectory = engine.simulate(scene, dt)
        assert trajectory.info.status == "ok", trajectory.info.message
        q, _, f = reference.at(trajectory.t)
        force = None if trajectory.constraint_forces is None else np.abs(trajectory.constraint_forces - f).max()
        out.append((np.linalg.norm(trajectory.positions - q, axis=2).max(), force))
    return out


def test_the_minimal_adapter_is_first_order_as_its_docstring_says():
    engine = adapter(0)
    (coarse, _), (fine, _) = position_errors(engine, catalog.build("bead", {"duration": 2}), (2e-3, 1e-3))
    assert 0.8 < np.log2(coarse / fine) < 1.2
    with pytest.raises(Unsupported, match="euler-projection models pins only"):
        engine.check(catalog.build("double-pendulum"))


def test_the_angle_adapter_is_first_order_and_reports_the_pin_force():
    engine = adapter(2)
    (coarse, coarse_force), (fine, fine_force) = position_errors(engine, catalog.build("bead", {"duration": 2}),
                                                                 (2e-3, 1e-3))
    assert 0.8 < np.log2(coarse / fine) < 1.2 and 0.8 < np.log2(coarse_force / fine_force) < 1.2
    assert fine_force < 0.05  # N, against a weight of 9.81 N
    with pytest.raises(Unsupported, match="angle-pendulum models a single pendulum"):
        engine.check(catalog.build("double-pendulum"))
    with pytest.raises(Unsupported, match="is 3-D; angles in the x-z plane describe planar chains only"):
        engine._check(catalog.build("spherical-pendulum"), {})


def test_the_toml_snippet_is_an_entry_point_table():
    (text,) = snippets("toml")
    table = tomllib.loads(text)["project"]["entry-points"]["xval.engines"]
    assert all(re.fullmatch(r"[\w.]+:\w+", target) for target in table.values())


def test_the_ci_gate_commands_run_on_the_page_s_adapters(tmp_path):
    """Step 2 (run + baseline) and step 3's shell block, on a suite naming the page's two adapters by path."""
    for index, module in ((0, "euler_projection"), (2, "angle_pendulum")):
        (tmp_path / f"{module}.py").write_text(snippets("python")[index])
    (tmp_path / "suite.toml").write_text("""
name = "plugins-doc"
duration = 0.5
dt = [1e-2, 5e-3]
scenes = [{ scene = "bead" }]
engines = ["euler_projection:ENGINE/default", "angle_pendulum:ENGINE/default"]
""")
    step2 = "xval run suite.toml --output results && xval baseline results --output baseline.json"
    assert f"`{step2}`" in DOC.read_text()
    (step3,) = snippets("sh")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    ran = subprocess.run(["bash", "-c", f"set -euo pipefail\n{step2}\nrm -r results\n{step3}"], cwd=tmp_path,
                         env=env, capture_output=True, text=True)
    assert ran.returncode == 0, ran.stdout[-3000:] + ran.stderr[-3000:]
    assert "<testsuite" in (tmp_path / "gate.xml").read_text() and (tmp_path / "gate.md").read_text().strip()
