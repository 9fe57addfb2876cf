"""bench/bench_models.py runs: a row per engine variant, each ratio its cost over its class's MuJoCo peer's, and an
engine it cannot load is an error naming it. Behaviour only: the speeds it prints are not asserted."""

from __future__ import annotations

import importlib.util
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "bench" / "bench_models.py"


def bench_module():
    spec = importlib.util.spec_from_file_location("bench_models", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_short_run_prints_a_row_for_every_engine_against_its_peer():
    bench = bench_module()
    out = subprocess.run([sys.executable, str(SCRIPT), "--steps", "10", "--repeats", "1"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600, check=True).stdout
    rows = {cells[1]: cells for cells in (re.split(r"\s*\|\s*", line)[1:-1] for line in out.splitlines()
                                          if line.startswith("| ") and not line.startswith("| class"))}
    assert list(rows) == [engine_id for _, engine_id, *_ in bench.ROWS]
    assert {engine_id.split("/")[0] for engine_id in rows} == {"mujoco", "pybullet", "drake", "dart", "ours"}
    for kind, engine_id, *_ in bench.ROWS:
        cost, ratio, peer = float(rows[engine_id][4]), float(rows[engine_id][5]), rows[engine_id][6]
        assert math.isfinite(cost) and cost > 0
        assert peer == bench.PEERS[kind] and peer.startswith("mujoco/")
        # The ratio is this row's cost over its peer's, as both are printed (to 0.001 µs and 0.01).
        assert ratio == pytest.approx(cost / float(rows[peer][4]), rel=5e-3, abs=6e-3), (engine_id, rows[engine_id])
        if engine_id == peer:
            assert ratio == 1.0
    assert re.search(r"10 steps of dt 0\.001 s .* load average \d+\.\d on \d+ CPUs", out)


def test_an_engine_it_cannot_load_ends_the_bench_naming_it(tmp_path, monkeypatch):
    bench = bench_module()
    with pytest.raises(SystemExit, match=r"bench_models: .*nosuch.*needs every engine"):
        bench.engine_of("nosuch/variant")
    # An engine whose library is not installed (its module's import fails): EngineUnavailable, the same end.
    (tmp_path / "uninstalled_engine.py").write_text("import no_such_engine_library  # noqa: F401\nENGINE = None\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(SystemExit, match=r"bench_models: engine 'uninstalled_engine:ENGINE' is unavailable: importing "
                                         r"uninstalled_engine failed: .*no_such_engine_library.*needs every engine"):
        bench.engine_of("uninstalled_engine:ENGINE/variant")
