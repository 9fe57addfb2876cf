"""The verdict (compare/results/verdict.py) and the end of ``xval run``: exact numbers on hand-made sweeps, the
problems of a real run, and what the terminal shows in each mode.

Hand-made records are plain case documents read through ``CaseRecord.from_json``, exactly as a results
directory holds them; the numbers (errors, costs) are chosen so that every expected value is exact.
"""

from __future__ import annotations

import json
import math
import re

import pytest

from compare.results.record import CaseRecord
from compare.run.results import load_results
from compare.results.sweep import sweeps
from compare.results.verdict import (
    best_at_equal_cost, cost_to_reach, default_focus, family, focus_comparison, lower_envelope, pareto_front, problems, scene_verdicts,
)
from compare.results.verdict_format import clip, format_verdicts
from report_support import run_suite_once
from cli_support import run_cli


def record(engine: str, dt: float, error: float | None, cost: float | None, *, status: str = "ok",
           scene: str = "s", index: int = 0, message: str = "") -> CaseRecord:
    """One case document of scene ``scene`` (L = 1 m) with the given max position error (m) and cost (s/s)."""
    return CaseRecord.from_json({
        "schema_version": 1,
        "case": {"id": f"{scene}|{engine}|dt={dt}", "scene_id": scene, "scene_name": "bead", "engine": engine,
                 "engine_id": engine, "variant": engine.split("/")[1], "options": {}, "dt": dt,
                 "position": [0, index, int(round(-math.log10(dt) * 10))]},
        "status": status, "message": message,
        "metrics": {"position_error_linf": error, "cost_per_simulated_second": cost, "n_samples": 10},
        "run_info": None, "wall_times": [], "elapsed": 0.0, "scene": {}, "scene_hash": "h",
        "characteristic": {"length": 1.0, "energy": 9.81}, "series": None, "reference": None, "finished": "",
    })


def test_family_is_the_label_before_the_first_slash():
    assert family("mujoco/hinge-rk4") == "mujoco"
    assert family("command/my/solver") == "command"
    assert family("plain") == "plain"


def test_pareto_front_drops_only_the_certainly_beaten_runs_most_accurate_first():
    # Changed by issue 45 (it pinned the classic front, cheapest first): a run leaves the front only when
    # another is certainly cheaper (cost intervals apart; here each run's own, RESOLUTION either side) and
    # errs no more, so runs within each other's timing noise all stay, listed by error.
    runs = sweeps([
        record("a/x", 0.1, 1e-1, 0.5, index=0), record("a/x", 0.01, 1e-2, 1.0, index=0),
        record("b/y", 0.1, 1e-3, 3.0, index=1), record("b/y", 0.01, 1e-4, 2.0, index=1),
        record("c/z", 0.1, 1e-2, 10.0, index=2),  # b/y at 2 s/s ([1.2, 3.4]) is certainly cheaper and errs less
    ])
    front = pareto_front(runs)
    assert [(p.engine, p.cost, p.error) for p in front] == [
        ("b/y", 2.0, 1e-4), ("b/y", 3.0, 1e-3), ("a/x", 1.0, 1e-2), ("a/x", 0.5, 1e-1)]
    # The staircase drawn through it: the classic front at the measured costs, cheapest first.
    assert [(p.engine, p.cost) for p in lower_envelope(front)] == [("a/x", 0.5), ("a/x", 1.0), ("b/y", 2.0)]
    # Each point's margin: the least high end, over the other variants' points that err no more, over its own
    # low end (b/y at 2 s/s beats a/x's at 1 and 0.5 once costs move 2·R² and 4·R²); none where nothing errs less.
    from compare.results.cost import RESOLUTION

    assert [p.margin for p in front[:2]] == [None, None]
    assert [p.margin for p in front[2:]] == pytest.approx([2 * RESOLUTION ** 2, 4 * RESOLUTION ** 2], rel=1e-12)


def test_pareto_front_names_equal_errors_in_suite_order():
    runs = sweeps([record("a/x", 0.1, 1e-3, 1.0, index=0), record("b/y", 0.1, 1e-3, 1.2, index=1)])
    assert [p.engine for p in pareto_front(runs)] == ["a/x", "b/y"]
    swapped = sweeps([record("a/x", 0.1, 1e-3, 1.2, index=0), record("b/y", 0.1, 1e-3, 1.0, index=1)])
    assert [p.engine for p in pareto_front(swapped)] == ["a/x", "b/y"]


def test_cost_to_reach_interpolates_on_the_log_log_curve():
    runs = sweeps([record("a/x", 0.1, 1e-4, 1e-3), record("a/x", 0.01, 1e-8, 1e-2)])
    reach = cost_to_reach(runs[0], 1e-6)
    # Half way from 1e-4 to 1e-8 in log error is half way from 1e-3 to 1e-2 in log cost: 10^-2.5 s/s.
    assert reach.how == "interpolated" and reach.dts == (0.1, 0.01)
    assert reach.cost == pytest.approx(10 ** -2.5, rel=1e-12)
    assert cost_to_reach(runs[0], 1e-3).how == "at most" and cost_to_reach(runs[0], 1e-3).cost == 1e-3
    assert cost_to_reach(runs[0], 1e-9).cost is None and cost_to_reach(runs[0], 1e-9).how == "not reached"
    failed = sweeps([record("b/y", 0.1, None, None, status="failed")])
    assert cost_to_reach(failed[0], 1e-6).how == "no ok run"


def test_equal_cost_budget_is_the_most_every_family_spent():
    runs = sweeps([
        record("a/x", 0.1, 1e-2, 1e-4, index=0), record("a/x", 0.01, 1e-5, 1e-3, index=0),
        record("a/x", 0.001, 1e-8, 1e-2, index=0),
        record("b/y", 0.1, 1e-3, 5e-4, index=1), record("b/y", 0.01, 1e-4, 5e-3, index=1),
    ])
    budget, best = best_at_equal_cost(runs)
    assert budget == 5e-3  # family b's dearest run; family a's 1e-2 s/s run is over it
    # Each family's error is read from its curve at the budget, not taken from a run near it: a/x between
    # (1e-3 s/s, 1e-5 m) and (1e-2 s/s, 1e-8 m), at log share log10(5) of the decade; b/y its dearest run's.
    assert [(b.family, b.engine) for b in best] == [("a", "a/x"), ("b", "b/y")]
    assert best[0].reading.error == pytest.approx(1e-5 * 1e-3 ** math.log10(5), rel=1e-9)
    assert best[1].reading.error == pytest.approx(1e-4, rel=1e-9) and best[1].reading.how == "at its finest"
    # The interval: these records carry no CPU times, so each cost is good to RESOLUTION = 1.7 either side.
    assert best[0].reading.low < best[0].reading.error < best[0].reading.high


def test_focus_comparison_is_the_ratio_of_the_costs_to_reach_the_target():
    runs = sweeps([
        record("a/x", 0.1, 1e-4, 1e-3, index=0), record("a/x", 0.01, 1e-8, 1e-2, index=0),
        record("b/y", 0.1, 1e-5, 1e-2, index=1), record("b/y", 0.01, 1e-7, 1e-1, index=1),
    ])
    assert default_focus(runs) == "a"
    comparison = focus_comparison(runs, "a", 1e-6)
    # b reaches 1e-6 half way between its two runs in log terms: 10^-1.5 s/s; a needs 10^-2.5.
    assert comparison.ratio == pytest.approx(10.0, rel=1e-12)
    # These records carry no CPU times (one wall-clock cost each): each cost is good to RESOLUTION = 1.7
    # either side, so the ratio to 1.7² either side: [10 / 2.89, 10 · 2.89].
    assert comparison.describe() == "best a (a/x) reaches 1e-06 m 10× [3.46, 28.9] cheaper than the best other engine (b/y)"
    assert focus_comparison(runs, "b", 1e-6).describe().startswith("best b (b/y) reaches 1e-06 m 10× [3.46, 28.9] dearer")


def test_a_solver_that_converges_to_the_wrong_answer_is_an_inconsistent_problem():
    # Errors stop falling at 5 cm, far above the 1 cm tolerance: clean convergence, to something else.
    runs = sweeps([record("a/wrong", 0.1, 1e-1, 1e-3), record("a/wrong", 0.01, 5e-2, 1e-2),
                   record("a/wrong", 0.001, 5e-2, 1e-1)], tolerance=1e-2)
    found = problems(runs)
    assert [(p.kind, p.engine) for p in found] == [("inconsistent", "a/wrong")]
    assert found[0].text.startswith("converges to something 0.05 m from the reference: error stops falling at 0.05 m")


@pytest.fixture(scope="module")
def small_verdicts(tmp_path_factory):
    return scene_verdicts(load_results(run_suite_once(tmp_path_factory.getbasetemp())).sweeps())


def test_problems_of_a_real_run_name_the_statuses_and_their_dts(small_verdicts):
    bead = small_verdicts[0]
    assert bead.scene_id == "bead"
    assert [(p.kind, p.engine, p.dts) for p in bead.problems] == [
        ("failed", "broken/raise", (1e-2, 3e-3, 1e-3)),
        ("unstable", "broken/blow-up", (1e-2, 3e-3, 1e-3)),
    ]
    assert bead.problems[1].text.startswith("unstable at dt 0.01, 0.003, 0.001 s (the largest dt of the suite; never ok)")
    # The two real engines converge towards the reference: neither is called inconsistent.
    assert all(p.kind != "inconsistent" for v in small_verdicts for p in v.problems)


def test_the_verdict_ranks_the_real_engines(small_verdicts):
    bead = small_verdicts[0]
    # The reference is the yardstick, never a competitor; the families are the suite's others, in order.
    assert [b.family for b in bead.best] == ["mujoco", "pymunk", "broken"]
    assert bead.comparison is not None and bead.comparison.focus_family == "mujoco"
    # MuJoCo's RK4 is at ~1e-9 m already at dt = 0.01 s; pymunk's first-order pin never reaches 1e-6 L here.
    reaches = {r.engine: r for r in bead.reaches}
    assert reaches["mujoco/hinge-rk4"].how == "at most"
    assert reaches["pymunk/pin"].how == "not reached"
    assert reaches["broken/raise"].how == "no ok run"
    text = format_verdicts(small_verdicts)
    assert "bead:\n  cheapest to reach 1e-06 m, per family" in text and "\n  most accurate at equal cost" in text
    assert re.search(r"\n    failed       broken/raise: failed at dt 0\.01, 0\.003, 0\.001 s: RuntimeError", text)


# -- the terminal ----------------------------------------------------------------------------------

TINY = """
name = "tiny"
duration = 0.1
sample_interval = 0.01
dt = [1e-2, 5e-3]
scenes = [{ scene = "bead" }]
engines = ["mujoco/hinge", "pymunk/pin", { id = "report_support:BROKEN/raise", label = "broken/raise" }]
"""




@pytest.fixture
def tiny_suite(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


@pytest.mark.parametrize("mode", ["default", "--quiet", "--verbose"])
def test_run_ends_with_the_verdict_and_shows_progress_as_asked(tiny_suite, tmp_path, capsys, mode):
    argv = ["run", str(tiny_suite), "--output", str(tmp_path / "out"), "--jobs", "1"]
    code, out, err = run_cli(capsys, *argv, *([] if mode == "default" else [mode]))
    assert code == 0, err
    assert "bead:\n  cheapest to reach 1e-06 m" in out and "\n  most accurate at equal cost" in out
    assert re.search(r"\n    failed       broken/raise: failed at dt 0\.01, 0\.005 s", out), out
    assert "6 cases run in" in out
    per_case = [line for line in err.splitlines() if re.match(r"\[\s*\d+/6\] bead · ", line)]
    if mode == "--quiet":
        assert err == ""
    elif mode == "--verbose":
        assert len(per_case) == 6
        assert out.startswith("scene bead (reference error ")  # the per-scene tables come back with --verbose, first
    else:
        assert "scene bead" not in out  # the verdict alone
        # Off a terminal the bar becomes a line at every tenth of the run (here, every case of six).
        assert per_case == []
        assert err.splitlines()[-1] == "running: 6/6 cases (100 %), 2 not ok"
        assert len(err.splitlines()) <= 10


def test_quiet_and_verbose_together_is_bad_input(tiny_suite, tmp_path, capsys):
    code, out, err = run_cli(capsys, "run", str(tiny_suite), "--output", str(tmp_path / "o"), "-q", "-v")
    assert code == 2 and out == ""
    assert err == "xval: error: --quiet and --verbose: choose one (--quiet prints only the verdict, --verbose a line per case)\n"
    assert not (tmp_path / "o").exists()



def test_equal_cost_falls_back_to_where_every_family_has_a_run():
    # Family a only ran cheap, family b only dear: the ranges do not overlap, so the budget is b's cheapest
    # run, and a competes with its best run.
    runs = sweeps([
        record("a/x", 0.1, 1e-2, 1e-5, index=0), record("a/x", 0.01, 1e-4, 1e-4, index=0),
        record("b/y", 0.1, 1e-3, 1e-2, index=1), record("b/y", 0.01, 1e-6, 1e-1, index=1),
    ])
    budget, best = best_at_equal_cost(runs)
    assert budget == 1e-2
    # a at its best run's error (the budget is past its dearest run); b at its cheapest run's.
    assert [(b.family, b.reading.how) for b in best] == [("a", "at its finest"), ("b", "interpolated")]
    assert [b.reading.error for b in best] == pytest.approx([1e-4, 1e-3], rel=1e-12)


def test_a_side_that_never_reaches_the_target_is_represented_by_its_closest_variant():
    runs = sweeps([
        record("a/failing", 0.1, None, None, status="failed", index=0),
        record("a/close", 0.1, 1e-3, 1e-3, index=1), record("a/close", 0.01, 1e-5, 1e-2, index=1),
        record("b/y", 0.1, 1e-2, 1e-3, index=2), record("b/y", 0.01, 1e-3, 1e-2, index=2),
    ])
    comparison = focus_comparison(runs, "a", 1e-6)
    assert comparison.ratio is None and comparison.focus.engine == "a/close"
    assert comparison.describe().startswith("to reach 1e-06 m: a/close not reached (best 1e-05 m); b/y not reached (best 0.001 m)")


def test_a_plateaued_variant_is_never_called_more_accurate_than_one_that_keeps_converging():
    # a/stuck: semi-implicit Euler stuck at 1.6e-3 m; b/rk4 converges past it to 1e-7 m. In the shared cost
    # range (up to 1e-1 s/s) a's runs are the more accurate, but saying "N× more accurate" would mislead.
    runs = sweeps([
        record("a/stuck", 0.1, 2e-3, 1e-3, index=0), record("a/stuck", 0.01, 1.6e-3, 1e-2, index=0),
        record("a/stuck", 0.001, 1.6e-3, 1e-1, index=0),
        record("b/rk4", 0.1, 1e-1, 5e-3, index=1), record("b/rk4", 0.05, 5e-3, 1e-2, index=1),
        record("b/rk4", 0.01, 1e-7, 2e-1, index=1),
    ])
    text = focus_comparison(runs, "a", 1e-8).describe()
    assert "more accurate" not in text
    assert text.endswith("; a/stuck stops at 0.0016 m, b/rk4 keeps converging (to 1e-07 m)")


def test_families_whose_cost_ranges_do_not_overlap_get_no_equal_cost_statement():
    runs = sweeps([
        record("a/x", 0.1, 1e-2, 1e-5, index=0), record("a/x", 0.01, 1e-4, 1e-4, index=0),
        record("b/y", 0.1, 1e-3, 1e-2, index=1), record("b/y", 0.01, 1e-5, 1e-1, index=1),
    ])
    assert focus_comparison(runs, "a", 1e-8).describe().endswith("; no cost range both sides ran in")


def test_messages_are_cut_between_words_never_inside_a_number():
    text = "unstable at dt 0.1 s: energy drift 3.57e+05 E* exceeds the bound 1 E*; constraint error 109.25 m"
    for width in range(20, len(text)):
        cut = clip(text, width)
        assert len(cut) <= width and cut.endswith(" …")
        assert text.startswith(cut[:-2]) and text[len(cut) - 2] == " "  # the cut falls on a space
    assert clip(text, len(text)) == text


def test_xval_verdict_gives_the_verdict_as_text_and_as_one_json_document(tiny_suite, tmp_path, capsys):
    code, _, err = run_cli(capsys, "run", str(tiny_suite), "--output", str(tmp_path / "out"), "--jobs", "1", "-q")
    assert code == 0, err
    code, text, err = run_cli(capsys, "verdict", str(tmp_path / "out"))
    assert code == 0, err
    assert text.startswith("bead:\n  cheapest to reach 1e-06 m, per family")
    code, out, err = run_cli(capsys, "verdict", str(tmp_path / "out"), "--format", "json")
    assert code == 0, err
    document = json.loads(out)
    # Changed by issue 45 (schema 1 always held the front): the front, which measured time decides point by
    # point, comes only with --front, each point with its margin; nothing else in the document moves with timing.
    assert document["schema"] == "xval-verdict/2" and document["focus"] == "mujoco"
    (bead,) = document["scenes"]
    assert "front" not in bead
    code, out, err = run_cli(capsys, "verdict", str(tmp_path / "out"), "--format", "json", "--front")
    assert code == 0, err
    (with_front,) = json.loads(out)["scenes"]
    assert with_front["front"] and all("margin" in p and p["case"].startswith("bead|") for p in with_front["front"])
    assert {k: v for k, v in with_front.items() if k != "front"} == bead
    assert [w["family"] for w in bead["winners"]] == ["mujoco", "pymunk", "broken"]
    models = {m["engine"]: m for m in bead["cost_models"]}
    hinge = models["mujoco/hinge"]  # two timed cases: per-step ratios, not a fit
    assert hinge["how"] == "ratio" and hinge["per_step_interval"][0] <= hinge["per_step"] <= hinge["per_step_interval"][1]
    assert {c["engine"] for c in bead["consistency"]} == {"mujoco/hinge", "pymunk/pin", "broken/raise"}
    assert [p["kind"] for p in bead["problems"]] == ["failed"]
    assert bead["comparison"]["text"] == text.splitlines()[-3].strip()
    code, out, err = run_cli(capsys, "verdict", str(tmp_path / "out"), "--focus", "nosuch")
    assert code == 2 and out == ""
    assert err == f"xval: error: --focus nosuch: no such engine family in {tmp_path / 'out'}; " \
                  "choose one of mujoco, pymunk, broken\n"
