"""xval gates itself: run suites/smoke.toml and gate it against the committed baselines/smoke.json.

A change that makes a solver in the smoke suite less accurate (or unstable)
fails this test, hence ``make test`` and CI. Timing cannot fail it: the gate
runs with ``--timing report`` (a CI runner is not the machine the baseline
was timed on, and the smoke suite times each case once), so slowdowns are
shown in the table but never gated.

After a deliberate change of accuracy, or of suites/smoke.toml, run
``make baseline`` and commit baselines/smoke.json with the reason.
"""

from __future__ import annotations

import subprocess

from compare.gate.baseline import build_baseline, load_baseline
from compare.gate.gate import gate_results
from compare.run.results import load_results
from compare.suite.gate_rules import GateSettings
from conftest import ROOT, XVAL

SUITE = ROOT / "suites" / "smoke.toml"
BASELINE = ROOT / "baselines" / "smoke.json"
REGENERATE = "run 'make baseline' and commit baselines/smoke.json, saying why in the commit message"


def test_the_smoke_suite_is_no_worse_than_its_committed_baseline(tmp_path):
    results = tmp_path / "smoke"
    ran = subprocess.run([*XVAL, "run", str(SUITE), "--output", str(results)], capture_output=True, text=True, cwd=ROOT)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    gated = subprocess.run(
        [*XVAL, "gate", str(results), "--baseline", str(BASELINE), "--timing", "report"],
        capture_output=True, text=True, cwd=ROOT,
    )
    # The table is the failure message: it names each worse case and both numbers.
    assert gated.returncode == 0, f"the smoke suite got worse than {BASELINE}:\n{gated.stdout}{gated.stderr}"

    # A baseline that no longer matches the suite would pass vacuously: its cases would be new or missing.
    report = gate_results(load_baseline(BASELINE), build_baseline(load_results(results)), GateSettings(), str(BASELINE))
    stale = [c for c in report.cases if c.outcome in ("new", "missing") or c.reason.startswith("scene changed")]
    assert not stale, f"suites/smoke.toml changed since {BASELINE} was made; {REGENERATE}:\n{gated.stdout}"
    # ours' version is this project's, so a dependency upgrade cannot make its cases
    # "not comparable": every one of them must really have been compared.
    uncompared = [c for c in report.cases if c.engine.startswith("ours/") and c.outcome == "not comparable"]
    assert not uncompared, f"ours cases were not compared; {REGENERATE}:\n{gated.stdout}"
    assert sum(c.engine.startswith("ours/") for c in report.cases) == 30  # 5 variants × 2 scenes × 3 dt


def test_the_baseline_carries_every_gated_field_and_an_order_for_every_ours_sweep():
    # A baseline made before a gated metric existed passes that metric vacuously; so does an ours sweep
    # whose errors left the order band (no observed order to compare).
    import json

    from compare.results import declared

    cases = json.loads(BASELINE.read_text())["cases"].values()
    ok = [c for c in cases if c["status"] == "ok" and not c["engine"].startswith("reference")]
    assert ok
    for metric in declared.gated():
        if metric.name == "momentum_drift":
            continue  # null by definition on planar scenes, which the smoke suite's two are
        if metric.name.startswith("gradient_"):
            continue  # taken only in a suite with [gradients], which the smoke suite has not
        present = [c for c in ok if metric.name in c["metrics"]]
        assert len(present) == len(ok), f"{len(ok) - len(present)} ok cases lack {metric.name}; {REGENERATE}"
    for case in ok:
        assert "consistent" in case, f"{case['engine']} at dt {case['dt']} lacks consistent; {REGENERATE}"
        assert case["timing"].get("cpu"), f"{case['engine']} at dt {case['dt']} lacks CPU timing; {REGENERATE}"
        if case["engine"].startswith("ours/"):
            assert case["metrics"]["observed_order"] is not None, (
                f"{case['engine']} on {case['scene_id']}: no observed order, so the gate checks none; {REGENERATE}")
