"""Third-party engines: discovery through the xval.engines entry point, module:attribute ids, the example
package's gate (passing as committed, failing when the solver is made worse), and broken plugins contained.

The example package (examples/my-solver) must be installed in the test environment; the Makefile's install
step does it (``pip install -e examples/my-solver``).
"""

from __future__ import annotations

import importlib.metadata
import os
import subprocess

import numpy as np
import pytest


from compare.gate.baseline import build_baseline, load_baseline
from compare.gate.gate import gate_results
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import load_suite, parse_suite
from compare.suite.gate_rules import GateSettings
from engines.scene import catalog
from engines import registry
from engines.adapter import API_VERSION, api_version_problem
from engines.errors import UserError
from conftest import ROOT, XVAL

EXAMPLE = ROOT / "examples" / "my-solver"
INSTALL = "install it with 'make test' or '.venv/bin/python -m pip install -e examples/my-solver'"


def require_example() -> None:
    if "my-solver" not in registry.entry_points():
        pytest.fail(f"the example plugin my-solver is not installed in this environment; {INSTALL}")


def xval(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([*XVAL, *args], capture_output=True, text=True, cwd=ROOT, env={**os.environ, **(env or {})})


# -- discovery --------------------------------------------------------------------


def test_the_example_is_discovered_through_its_entry_point():
    require_example()
    found = registry.status("my-solver")
    assert found.kind == "plugin" and found.engine is not None, found.reason
    assert found.origin == f"plugin from my-solver {importlib.metadata.version('my-solver')}: my_solver.xval_adapter:ENGINE"
    assert registry.engine_names()[:len(registry.BUILTIN)] == list(registry.BUILTIN) and "my-solver" in registry.engine_names()
    engine, variant = registry.resolve("my-solver/shake")
    assert (engine.name, variant) == ("my-solver", "shake")

    listed = xval("engines")
    assert listed.returncode == 0, listed.stderr
    assert "my-solver 0.1.0  [plugin from my-solver 0.1.0: my_solver.xval_adapter:ENGINE]" in listed.stdout
    assert "reference scipy" in listed.stdout and "[built-in: engines.reference.reference]" in listed.stdout


def test_the_example_solver_is_second_order_and_agrees_with_ours_rattle():
    require_example()
    scene = catalog.build("double-pendulum", {"duration": 1.0})
    mine = registry.get_engine("my-solver")
    ours = registry.get_engine("ours")
    errors = []
    for dt in (4e-3, 2e-3):
        a = mine.simulate(scene, dt)
        b = ours.simulate(scene, dt, variant="rattle")
        assert a.info.status == "ok" and a.info.engine_version == "0.1.0"
        # Same scheme, different code: positions agree to round-off amplified by a chaotic scene.
        assert np.abs(a.positions - b.positions).max() < 1e-9
        errors.append(np.abs(a.positions[-1] - b.positions[-1]).max())
    from engines.reference.reference import solve

    reference = solve(scene)
    e = [np.abs(mine.simulate(scene, dt).positions[-1] - reference.at(np.array([1.0]))[0][0]).max() for dt in (4e-3, 2e-3)]
    assert 3.6 < e[0] / e[1] < 4.4  # halving dt divides the error by 4: second order


# -- the example's suite and gate -------------------------------------------------------


def test_the_example_suite_passes_its_gate_and_fails_it_when_velocity_projection_is_off(tmp_path):
    require_example()
    suite = EXAMPLE / "suite.toml"
    baseline = EXAMPLE / "baseline.json"
    good = tmp_path / "good"
    ran = xval("run", str(suite), "--output", str(good))
    assert ran.returncode == 0, ran.stdout + ran.stderr
    gated = xval("gate", str(good), "--baseline", str(baseline), "--timing", "report")
    assert gated.returncode == 0, f"the example no longer matches {baseline}:\n{gated.stdout}{gated.stderr}"
    # Every case was compared (same engine versions and scenes), so the pass is not vacuous.
    report = gate_results(load_baseline(baseline), build_baseline(load_results(good)), GateSettings(), str(baseline))
    verdicts = {c.outcome for c in report.cases if "my-solver" in c.name}
    assert verdicts == {"unchanged"}, gated.stdout

    worse = tmp_path / "worse"
    ran = xval("run", str(suite), "--output", str(worse), env={"MY_SOLVER_NO_VELOCITY_PROJECTION": "1"})
    assert ran.returncode == 0, ran.stdout + ran.stderr
    gated = xval("gate", str(worse), "--baseline", str(baseline), "--timing", "report")
    assert gated.returncode == 1, gated.stdout + gated.stderr
    worse_rows = [line for line in gated.stdout.splitlines() if line.startswith("worse") and "not gated" not in line]
    assert worse_rows and all("my-solver/rattle" in line for line in worse_rows)
    assert any("energy_drift" in line for line in worse_rows)
    assert "gate FAILED (suite my-solver): 6 worse" in gated.stdout


# -- module:attribute ids -----------------------------------------------------------------


def test_module_attribute_ids_load_from_a_suite_file(tmp_path):
    require_example()
    path = tmp_path / "s.toml"
    path.write_text(
        'duration = 0.3\ndt = [1e-2]\n[[scenes]]\nscene = "bead"\n'
        '[[engines]]\nid = "plugin_engines:EXACT_CLASS"\n'          # a class: instantiated by xval
        '[[engines]]\nid = "my_solver.xval_adapter:ENGINE/shake"\n'  # an installed adapter by path
    )
    suite = load_suite(path)
    assert [e.label for e in suite.engines] == ["plugin_engines:EXACT_CLASS/default",
                                                "my_solver.xval_adapter:ENGINE/shake"]
    run_suite(suite, tmp_path / "r", jobs=1)
    records = {r.case.engine: r for r in load_results(tmp_path / "r").records}
    assert records["plugin_engines:EXACT_CLASS/default"].status == "ok"
    assert records["plugin_engines:EXACT_CLASS/default"].metrics["position_error_linf"] == 0.0
    assert records["my_solver.xval_adapter:ENGINE/shake"].status == "ok"


@pytest.mark.parametrize(
    "engine_id, message",
    [
        ("plugin_engines:NOT_AN_ENGINE", "engine 'plugin_engines:NOT_AN_ENGINE': plugin_engines.NOT_AN_ENGINE is "
         "not an Engine object; point module:attribute at an engines.adapter.Engine instance"),
        ("plugin_engines:NOPE", "engine 'plugin_engines:NOPE': plugin_engines.NOPE is not an Engine object"),
        ("no_such_plugin_module:ENGINE", "engine 'no_such_plugin_module:ENGINE': no module named "
         "'no_such_plugin_module'; install the package that provides it, or put its directory on PYTHONPATH"),
        (":ENGINE", "engine ':ENGINE': write a path as package.module:ATTRIBUTE, e.g. my_solver.adapter:ENGINE"),
    ],
)
def test_a_wrong_path_is_a_user_error_naming_the_fix(engine_id, message):
    with pytest.raises(UserError, match="^" + __import__("re").escape(message)):
        registry.load_engine(engine_id)


# -- broken plugins ---------------------------------------------------------------------------

BROKEN = {
    "plugin_broken_import:ENGINE": (
        "skipped", "engine 'plugin_broken_import:ENGINE' is unavailable: importing plugin_broken_import failed: "
        "ModuleNotFoundError: No module named 'xval_test_no_such_solver_library'"),
    "plugin_engines:OLD_PROTOCOL": (
        "skipped", "engine 'plugin_engines:OLD_PROTOCOL' declares api_version = 0, but this xval speaks api_version 1; "
        "update the adapter to the protocol in docs/plugins.md (see its 'Protocol versions' list), then set "
        "api_version = 1"),
    "plugin_engines:FUTURE_PROTOCOL": (
        "skipped", "engine 'plugin_engines:FUTURE_PROTOCOL' declares api_version = 99, newer than this xval speaks (1); "
        "upgrade xval, or install a version of the plugin written for api_version 1"),
    "plugin_engines:FLAT_POSITIONS/default": (
        "failed", "RawRunError: flat-positions: RawRun.positions has shape (31, 3), expected (n <= 31, 1, 3): "
        "samples x particles x (x, y, z); record one row per scheduled sample (schedule.sample_steps), in the "
        "scene frame (engines.external.plugin.Recorder builds it)"),
    "plugin_engines:TOO_MANY_SAMPLES/default": (
        "failed", "RawRunError: too-many-samples: RawRun.positions has shape (93, 1, 3), expected (n <= 31, 1, 3)"),
    "plugin_engines:WRONG_FORCES/default": (
        "failed", "RawRunError: wrong-forces: RawRun.forces has shape (31, 2, 3), expected (n <= 31, 1, 3): "
        "samples x constraints x (x, y, z)"),
    "plugin_engines:MILLIMETRES/default": (
        "failed", "RawRunError: millimetres: the first sample's positions are 865 m off the scene's initial "
        "positions; sample 0 must be the initial state in the scene frame (metres, z up, particles in scene order)"),
    "plugin_engines:NANOSECONDS/default": (
        "failed", "RawRunError: nanoseconds: RawRun.wall_time = 5e+08 s but _run took only"),
    "plugin_engines:RAISES/default": ("failed", "ValueError: cannot build a model with 1 particle"),
    "plugin_engines:NAN_HALFWAY/default": ("unstable", "non-finite state at t = 0.15 s"),
}


def test_broken_plugins_are_reported_and_every_other_engine_still_runs(tmp_path):
    require_example()
    ids = "".join(f'[[engines]]\nid = "{engine_id.split("/")[0]}"\n' for engine_id in BROKEN)
    suite = parse_suite(f'duration = 0.3\ndt = [1e-2]\ntimeout = 30\n[[scenes]]\nscene = "bead"\n{ids}'
                        '[[engines]]\nid = "my-solver/rattle"\n[[engines]]\nid = "reference/dop853"\n')
    run_suite(suite, tmp_path / "r", jobs=2)
    records = {r.case.engine: r for r in load_results(tmp_path / "r").records}
    for engine_id, (status, message) in BROKEN.items():
        record = records[engine_id]
        assert (record.status, record.message[: len(message)]) == (status, message), engine_id
    assert records["my-solver/rattle"].status == "ok"
    assert records["reference/dop853"].status == "ok"
    # The NaN plugin keeps its samples before the first non-finite one (t = 0 .. 0.14 s).
    assert records["plugin_engines:NAN_HALFWAY/default"].metrics["n_samples"] == 15


@pytest.mark.parametrize("line, fix", [
    ("from engines.plugin import Engine", "ModuleNotFoundError: No module named 'engines.plugin'; engines.plugin is "
     "engines.external.plugin now: import it from there"),
    ("from engines.scene import Scene", "engines.scene is a package of modules now (engines.scene.scene): import from "
     "the module, or take what a plugin needs from engines.external.plugin (docs/plugins.md)"),
    ("from engines.adapters.mujoco import ENGINE", "ModuleNotFoundError: No module named 'engines.adapters'; "
     "engines.adapters is engines.<engine>.adapter (each engine's home) now: import it from there"),
    ("from engines.mujoco import ENGINE", "engines.mujoco is a package of modules now (engines.mujoco.adapter): import "
     "from the module, or take what a plugin needs from engines.external.plugin (docs/plugins.md)"),
])
def test_a_plugin_written_before_engines_was_split_into_folders_is_told_where_to_import_from(
        line, fix, tmp_path, monkeypatch):
    (tmp_path / "pre_split_plugin.py").write_text(f"{line}\nENGINE = None\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(registry.EngineUnavailable) as raised:
        registry.load_engine("pre_split_plugin:ENGINE")
    assert str(raised.value).startswith("engine 'pre_split_plugin:ENGINE' is unavailable: importing pre_split_plugin "
                                        "failed: ") and str(raised.value).endswith(fix)


def test_a_broken_entry_point_is_unavailable_with_its_name_and_the_reason():
    # A real entry point object (not installed): the same path `xval engines` and suites take for one.
    point = importlib.metadata.EntryPoint("broken-solver", "plugin_broken_import:ENGINE", registry.ENTRY_POINT_GROUP)
    found = registry._load_plugin("broken-solver", point)
    assert found.engine is None and found.kind == "plugin"
    assert found.reason == ("plugin 'broken-solver' (plugin_broken_import:ENGINE): cannot load: ModuleNotFoundError: "
                            "No module named 'xval_test_no_such_solver_library'")
    renamed = registry._load_plugin("other-name", importlib.metadata.EntryPoint(
        "other-name", "plugin_engines:EXACT_CLASS", registry.ENTRY_POINT_GROUP))
    assert renamed.engine is None and renamed.reason.endswith(
        "its Engine.name is 'exact', but the entry point is named 'other-name'; make them the same")


def test_api_version_messages():
    engine = registry.get_engine("reference")
    assert engine.api_version == API_VERSION and api_version_problem(engine, "x") is None
    old = registry.load_path("plugin_engines:EXACT_CLASS")
    type(old).api_version = "1"  # a string is not a version: refused, with the fix
    try:
        assert api_version_problem(old, "plugin 'exact'") == (
            "plugin 'exact' declares api_version = '1', but this xval speaks api_version 1; update the adapter to "
            "the protocol in docs/plugins.md (see its 'Protocol versions' list), then set api_version = 1")
    finally:
        type(old).api_version = 1
