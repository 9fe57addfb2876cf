"""Stability search, Baumgarte gain-map theory, and blow-ups recorded (not crashing) in a suite run."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from engines.errors import UserError

from compare.stability.gainmap import load_gainmap, run_gainmap
from ours.stability import critical_limit, largest_stable_dt, spectral_radius, theory_stable
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.stability.search import (
    BOUNDED,
    STABLE_AT_LARGEST,
    UNDECIDED,
    UNSTABLE_AT_SMALLEST,
    Trial,
    SearchSettings,
    load_stability,
    plan_stability,
    run_stability,
    search,
)
from compare.suite.reader import parse_suite

K_S = 1e6  # stiff enough that the feedback, not explicit Euler's slow energy growth, sets the limit
K_D = 2 * math.sqrt(K_S)

BEAD_SUITE = f"""
name = "bead-stability"
duration = 0.5
dt = [1e-2, 1e-4]
timeout = 60
scenes = [{{ id = "bead", scene = "bead" }}]
engines = [
    {{ id = "ours/baumgarte-euler", options = {{ k_s = {K_S}, k_d = {K_D} }} }},
    {{ id = "ours/baumgarte-symplectic-euler", options = {{ k_s = {K_S}, k_d = {K_D} }} }},
]
[bounds]
energy_drift = 1.0
constraint_error = 0.1
[stability]
dt_max = 1e-2
dt_min = 1e-4
"""


# -- the pure search ---------------------------------------------------------------------------


def threshold_trial(boundary: float):
    """A fake engine stable exactly for dt ≤ boundary (s)."""
    return lambda dt: Trial(dt, "ok" if dt <= boundary else "unstable")


@pytest.mark.parametrize("boundary", [3.7e-4, 1e-3, 2.2e-3, 9.9e-3])
def test_search_brackets_a_known_boundary_to_ten_percent(boundary):
    verdict, lo, hi, trials = search(threshold_trial(boundary), SearchSettings(1e-2, 1e-4))
    assert verdict == BOUNDED
    assert lo <= boundary < hi and hi / lo <= 1.1 * (1 + 1e-9)
    assert len(trials) <= 10  # two per decade down, then ~4 bisections


def test_search_edges_stable_at_largest_and_unstable_at_smallest():
    assert search(threshold_trial(1.0), SearchSettings(1e-2, 1e-4))[:3] == (STABLE_AT_LARGEST, 1e-2, None)
    verdict, lo, hi, trials = search(threshold_trial(1e-6), SearchSettings(1e-2, 1e-4))
    assert (verdict, lo, hi) == (UNSTABLE_AT_SMALLEST, None, 1e-4)
    assert trials[-1].dt == 1e-4  # the smallest dt was tried, not skipped over


def test_a_timed_out_trial_leaves_the_boundary_undecided_where_the_search_stood():
    """A machine too loaded to finish a trial in time says nothing about stability: the bracket known so far
    is kept, and the dt that timed out is neither stable nor unstable."""
    def trial(dt):
        if 2e-3 < dt < 6e-3:
            return Trial(dt, "timeout", "ran past the timeout")
        return Trial(dt, "ok" if dt <= 1e-3 else "unstable")

    verdict, lo, hi, trials = search(trial, SearchSettings(1e-2, 1e-4))
    assert (verdict, lo, hi) == (UNDECIDED, None, 1e-2)
    assert [t.status for t in trials] == ["unstable", "timeout"]


#: A bead run by the test engines of tests/compare_engines.py: ``pause`` answers after PAUSE s (6 s),
#: ``sleep`` never. Trials get 6 s, then 4 × 6 s (a new case host warms the variant up first: the paused
#: trial sleeps 2 × 6 s, past the first limit on any machine, and the retry leaves 12 s for starting the host,
#: which took more than 4 s at a load of 4× the cores).
SLOW_SUITE = """
name = "slow-stability"
duration = 0.2
dt = [1e-2]
timeout = 6
scenes = [{ id = "bead", scene = "bead" }]
engines = [{ id = "compare_engines:MISBEHAVING/pause" }, { id = "compare_engines:MISBEHAVING/sleep" }]
[stability]
dt_max = 1e-2
dt_min = 1e-2
"""


def test_a_trial_past_its_limit_is_run_again_longer_then_undecided_never_unstable(tmp_path):
    path = run_stability(parse_suite(SLOW_SUITE), tmp_path)
    results = {r["engine"]: r for r in load_stability(path.parent)["results"]}
    paused = results["compare_engines:MISBEHAVING/pause"]
    # 12 s is past the 6 s limit and within the retry's 24 s: decided, and stable.
    assert (paused["verdict"], paused["largest_stable_dt"]) == (STABLE_AT_LARGEST, 1e-2)
    asleep = results["compare_engines:MISBEHAVING/sleep"]
    assert (asleep["verdict"], asleep["undecided_dt"], asleep["smallest_unstable_dt"]) == (UNDECIDED, 1e-2, None)
    assert asleep["trials"][-1]["message"] == "ran past 6 s, then past 24 s: undecided, not unstable"


# -- theory ------------------------------------------------------------------------------------


def test_euler_and_symplectic_euler_regions_match_their_closed_forms():
    """Euler: h k_s ≤ k_d ≤ 2/h + h k_s/2. Symplectic Euler: h k_d ≤ 2 and h² k_s + 2 h k_d ≤ 4."""
    h = 1e-3
    for k_s in (1e1, 1e3, 1e5, 3e6, 5e6):
        for k_d in (0.3, 3.0, 30.0, 300.0, 1.5e3, 3e3, 3e4):
            assert theory_stable("euler", h, k_s, k_d) == (h * k_s <= k_d <= 2 / h + h * k_s / 2)
            assert theory_stable("symplectic-euler", h, k_s, k_d) == (h * k_d <= 2 and h * h * k_s + 2 * h * k_d <= 4)


def test_critical_damping_limits():
    """h√k_s at the limit: real-axis limits of R(z) (2, 2, 2.785) and 2(√2 − 1) for symplectic Euler."""
    assert critical_limit("euler") == pytest.approx(2.0, rel=1e-5)
    assert critical_limit("midpoint") == pytest.approx(2.0, rel=1e-5)
    assert critical_limit("rk4") == pytest.approx(2.785293, rel=1e-5)
    assert critical_limit("symplectic-euler") == pytest.approx(2 * (math.sqrt(2) - 1), rel=1e-5)
    assert largest_stable_dt("euler", 1.0, 0.0) is None  # undamped: |1 + iωh| > 1 for every h
    assert spectral_radius("rk4", 1e-3, 1e6, 2e3) < 1


# -- the search on a real engine, through the isolation ------------------------------------------


def test_search_finds_the_analytic_baumgarte_boundary_on_the_bead(tmp_path):
    suite = parse_suite(BEAD_SUITE, str(tmp_path / "bead.toml"))
    path = run_stability(suite, tmp_path / "out", jobs=2)
    document = load_stability(path.parent)
    assert document["schema_version"] == 2 and "energy drift" in document["criterion"]
    results = {r["engine"]: r for r in document["results"]}
    euler = results["ours/baumgarte-euler"]
    analytic = 2 / math.sqrt(K_S)  # |1 + λh| ≤ 1 with λ = −√k_s (double): h ≤ 2/√k_s = 2 ms
    assert euler["analytic_dt"] == pytest.approx(analytic, rel=1e-5)
    assert euler["verdict"] == BOUNDED
    assert abs(euler["largest_stable_dt"] / analytic - 1) < 0.2
    assert euler["smallest_unstable_dt"] / euler["largest_stable_dt"] <= 1.1 + 1e-9
    assert [t["dt"] for t in euler["trials"]][:2] == [1e-2, pytest.approx(1e-2 / math.sqrt(10))]  # every run kept
    symplectic = results["ours/baumgarte-symplectic-euler"]
    assert abs(symplectic["largest_stable_dt"] / (2 * (math.sqrt(2) - 1) / math.sqrt(K_S)) - 1) < 0.2
    with pytest.raises(UserError, match="exists; pass --force"):
        run_stability(suite, tmp_path / "out")


def test_stability_table_errors_name_the_key(tmp_path):
    bad = BEAD_SUITE.replace('dt_min = 1e-4', 'dt_min = 1e-4\nscenes = ["nope"]')
    with pytest.raises(UserError, match=r"stability\.scenes: unknown scene id 'nope'; this suite's are: bead"):
        plan_stability(parse_suite(bad, "s.toml"))
    bad = BEAD_SUITE.replace('dt_min = 1e-4', 'dt_min = 1e-4\nengines = ["mujoco/*"]')
    with pytest.raises(UserError, match=r"'mujoco/\*' matches no engine variant"):
        plan_stability(parse_suite(bad, "s.toml"))


def test_cli_bad_input_is_one_line_and_exit_2(tmp_path):
    suite = tmp_path / "bad.toml"
    suite.write_text(BEAD_SUITE.replace("dt_min = 1e-4", "dt_min = 1"))
    xval = str(Path(sys.executable).parent / "xval")
    done = subprocess.run([xval, "stability", str(suite), "--output", str(tmp_path / "o")], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0
    assert "stability.dt_min: 1 s is larger than dt_max 0.01 s" in done.stderr


def test_output_files_of_another_version_are_refused_with_the_command_that_rewrites_them(tmp_path):
    assert load_stability(tmp_path) is None and load_gainmap(tmp_path) is None  # none written: no section
    (tmp_path / "stability.json").write_text('{"schema": "xval-stability", "schema_version": 0}')
    with pytest.raises(UserError, match=r"stability\.json: xval-stability version 0, but this xval reads version 2; "
                                        r"rerun xval stability SUITE --output DIR --force$"):
        load_stability(tmp_path)
    (tmp_path / "gainmap.json").write_text("{")
    with pytest.raises(UserError, match=r"gainmap\.json: cannot read it \(.*\); rerun xval stability SUITE"):
        load_gainmap(tmp_path)


def test_a_version_1_stability_file_reads_with_its_probes_as_trials(tmp_path):
    """Version 1 called each pair's runs "probes" (the word of ``xval probe``, which measures something else)."""
    trial = {"dt": 0.01, "status": "unstable", "message": "", "energy_drift": 2.0, "constraint_error": None,
             "elapsed": 0.1}
    old = {"schema": "xval-stability", "schema_version": 1, "criterion": "c",
           "results": [{"scene_id": "bead", "engine": "ours/baumgarte-euler", "verdict": UNSTABLE_AT_SMALLEST,
                        "largest_stable_dt": None, "smallest_unstable_dt": 0.01, "reason": "", "analytic_dt": None,
                        "probes": [trial]}]}
    (tmp_path / "stability.json").write_text(json.dumps(old))
    document = load_stability(tmp_path)
    assert document["schema_version"] == 2 and document["results"][0]["trials"] == [trial]
    assert "probes" not in document["results"][0]


# -- gain map ------------------------------------------------------------------------------------


def test_gain_map_agrees_with_theory_away_from_the_boundary(tmp_path):
    text = BEAD_SUITE + """
[gainmap]
scene = "bead"
engines = ["ours/baumgarte-euler", "ours/baumgarte-rk4"]
x = "k_s"
y = "k_d"
dt = 1e-3
x_values = { from = 1, to = 1e8, per_decade = 1 }
y_values = { from = 1e-1, to = 1e5, per_decade = 1 }
theory_points = 11
"""
    path = run_gainmap(parse_suite(text, str(tmp_path / "g.toml")), tmp_path / "out", jobs=2)
    document = json.loads(path.read_text())
    assert document["dt"] == 1e-3 and len(document["x_values"]) == 9 and len(document["y_values"]) == 7
    for integrator, grid in document["maps"].items():
        cells = [(s, rho) for row_s, row_rho in zip(grid["status"], grid["rho"]) for s, rho in zip(row_s, row_rho)]
        clearly_stable = [s for s, rho in cells if rho < 0.999]  # the run must stay ok
        clearly_unstable = [s for s, rho in cells if rho > 1.1]  # grows ≥ 10 % a step: past any bound long before 500 steps
        # Both sides of the boundary are on the grid, or the agreement below would hold vacuously.
        assert len(clearly_stable) >= 5 and len(clearly_unstable) >= 5, (integrator, len(clearly_stable), len(clearly_unstable))
        assert set(clearly_stable) == {"ok"}, integrator
        assert set(clearly_unstable) == {"unstable"}, integrator
        assert len(grid["theory"]["log10_rho"]) == 11


# -- blow-ups inside a suite run -----------------------------------------------------------------


def test_a_run_that_blows_up_is_recorded_unstable_with_its_samples(tmp_path):
    text = f"""
duration = 1.0
dt = [5e-3, 1e-3]
scenes = [{{ id = "bead", scene = "bead" }}]
engines = [{{ id = "ours/baumgarte-euler", options = {{ k_s = {K_S}, k_d = {K_D} }} }}, "ours/rattle"]
"""
    summary = run_suite(parse_suite(text, "blowup.toml"), tmp_path / "run", jobs=2)
    records = {(r.case.engine, r.case.dt): r for r in load_results(summary.path).records}
    blown = records[("ours/baumgarte-euler", 5e-3)]  # h√k_s = 5 > 2
    assert blown.status == "unstable"
    t = blown.series["t"]
    assert 0 < len(t) and t[-1] < 1.0  # the samples up to the blow-up are kept
    assert blown.metrics["complete"] is False
    assert records[("ours/baumgarte-euler", 1e-3)].status == "ok"  # h√k_s = 1: inside the region
    assert all(records[("ours/rattle", dt)].status == "ok" for dt in (5e-3, 1e-3))


# -- report sections -----------------------------------------------------------------------------


def test_report_shows_the_stability_table_bars_and_gain_maps(tmp_path):
    from reports.render import write_report

    text = BEAD_SUITE.replace("duration = 0.5", "duration = 0.2").replace("dt_min = 1e-4", "dt_min = 1e-3") + """
[gainmap]
scene = "bead"
engines = ["ours/baumgarte-symplectic-euler"]
x = "k_s"
y = "k_d"
dt = 1e-3
x_values = [1e2, 1e7]
y_values = [1.0, 1e4]
theory_points = 5
"""
    suite = parse_suite(text, str(tmp_path / "r.toml"))
    output = tmp_path / "out"
    run_suite(suite, output, jobs=1)
    plain = write_report(output, tmp_path / "plain.html").path.read_text()
    assert 'id="stability"' not in plain and 'id="gainmap"' not in plain  # only with stability data
    run_stability(suite, output, jobs=2)
    run_gainmap(suite, output, jobs=2)
    html = write_report(output).path.read_text()
    assert 'id="stability"' in html and 'id="stability-bars"' in html
    assert "ours/baumgarte-symplectic-euler" in html and "theory / s" in html
    for kind in ("stability", "constraint-error", "energy-drift"):
        assert f'id="gainmap-0-{kind}"' in html
    from report_support import PageStructure  # the page packs its figure specs; read them as the page does

    specs = PageStructure(html).figure_specs()
    contours = [t for spec in specs.values() for t in spec["data"] if t["type"] == "contour"]
    assert len(contours) == 3  # the theory boundary over each heat map
