"""Trends across runs: the step rule (compare.history.trend.steps), series out of a history, and the trend page.

The planted history is twelve synthetic runs made from one real run of
tests/gate_suite.toml: every case's timing wanders by up to ±10 % from run
to run (a fixed, seeded pattern), and from run 8 on the position errors of
one variant are doubled. The step rule must find exactly that step, at that
run, in exactly those series, and nothing in the noisy timings.
"""

from __future__ import annotations

import json
import re

import numpy as np
import plotly.graph_objects as go
import pytest

from compare.history.store import History
from compare.history.trend import build_series, steps
from compare.results.declared import METRICS

from reports.history import write_history_report
from reports.pack import unpacked

from browser_support import CHROMIUM, Page
from history_support import ENGINE, ERRORS, add, real_run, synthetic, xval

#: The first run (0-based) whose errors are doubled.
STEP_AT = 7
RUNS = 12


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return real_run(tmp_path_factory.mktemp("history-trend") / "run")


@pytest.fixture(scope="module")
def planted(base, tmp_path_factory):
    root = tmp_path_factory.mktemp("history-planted")
    noise = np.random.default_rng(7).uniform(0.9, 1.1, size=(RUNS, len(base.records)))
    index_of = {r.case.id: i for i, r in enumerate(base.records)}
    path = root / "h.sqlite"
    with History.open(path, create=True) as history:
        for run in range(RUNS):
            timing = lambda record, run=run: float(noise[run, index_of[record.case.id]])  # noqa: E731
            add(history, synthetic(base, run, error=2.0 if run >= STEP_AT else 1.0, timing=timing), run)
    return path


def test_the_planted_step_is_found_where_it_was_planted_and_nowhere_else(planted):
    with History.open(planted) as history:
        series = build_series(history)
    stepped = [s for s in series if s.steps]
    assert {(s.engine, s.metric.name, s.dt) for s in stepped} == {
        (ENGINE, metric, dt) for metric in ERRORS for dt in (1e-2, 5e-3, 2.5e-3)}
    for s in stepped:
        (step,) = s.steps
        assert step.index == STEP_AT and s.points[step.index].run_id == STEP_AT + 1
        assert step.outcome == "worse" and step.ratio == pytest.approx(2.0, rel=1e-12)
    timings = [s for s in series if s.metric.name == "cost_per_simulated_second"]
    assert len(timings) == 6 and all(len(s.points) == RUNS for s in timings)


def test_a_regression_and_its_fix_are_two_steps():
    metric = METRICS["position_error_linf"]
    found = steps([1e-3] * 4 + [3e-3] * 4 + [1e-3] * 4, metric)
    assert [(s.index, s.outcome, s.ratio) for s in found] == [(4, "worse", pytest.approx(3.0)), (8, "better", pytest.approx(1 / 3))]


def test_gaps_keep_their_place_and_direction_follows_the_declaration():
    divergence = METRICS["divergence_time"]  # higher is better
    found = steps([0.8, None, 0.8, 0.8, 0.4, None, 0.4, 0.4], divergence)
    assert [(s.index, s.outcome) for s in found] == [(4, "worse")]


@pytest.mark.parametrize("values", [
    [1e-3] * 10,                                  # constant
    [1e-3] * 5 + [1.05e-3] * 5,                   # 5 %: inside the gate's 10 % tolerance, round-off class
    [1e-3],                                       # too short
])
def test_no_step_where_the_gate_would_see_none(values):
    assert steps(values, METRICS["position_error_linf"]) == []


def test_a_change_in_the_latest_run_is_a_step_at_that_run():
    found = steps([1e-3] * 5 + [5e-3], METRICS["position_error_linf"])
    assert [(s.index, s.outcome, s.before, s.after) for s in found] == [(5, "worse", 1e-3, 5e-3)]


def test_a_timing_needs_enough_runs_to_measure_its_noise_first():
    cost = METRICS["cost_per_simulated_second"]
    assert steps([1e-3, 1e-3, 2e-3, 2e-3, 2e-3], cost) == []  # 5 runs: the noise is not known yet
    assert [s.index for s in steps([1e-3, 1e-3, 1e-3, 2e-3, 2e-3, 2e-3], cost)] == [3]
    assert steps([1e-3] * 6 + [2e-3], cost) == []  # one slow run is not a step in a timing
    assert steps([1e-3, 1.05e-3, 0.97e-3, 1e-3, 1.02e-3, 0.99e-3, 2e-3, 1.01e-3], cost) == []


def test_noise_alone_is_not_a_step_and_a_step_above_it_is():
    rng = np.random.default_rng(3)
    cost = METRICS["cost_per_simulated_second"]
    noise = np.exp(0.05 * rng.standard_normal(12))
    assert steps(list(1e-3 * noise), cost) == []
    found = steps(list(1e-3 * noise * np.r_[np.ones(6), 1.5 * np.ones(6)]), cost)
    assert [(s.index, s.outcome) for s in found] == [(6, "worse")]


# -- the page -------------------------------------------------------------------------------------


def test_the_trend_page_is_self_contained_and_marks_the_step(planted, tmp_path, capsys):
    output = tmp_path / "trend.html"
    code, out, err = xval(capsys, "history", "report", "--history", planted, "--output", output)
    assert code == 0, err
    assert re.fullmatch(rf"history report: {re.escape(str(output))} \(12 runs, 9 step changes, \d+\.\d MB, \d+\.\d\d s\)\n", out)
    page = output.read_text()
    assert "Content-Security-Policy" in page and "default-src 'none'" in page
    # The page without its packed elements (plotly.js, the figure specs) nor its script.
    markup = re.sub(r"<script\b[^>]*>.*?</script>", "", page, flags=re.S)
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", markup)  # nothing fetched
    assert not re.search(r"<(link|img|iframe)\b", markup)
    packs = {m.group(1): json.loads(unpacked(m.group(2))) for m in re.finditer(
        r'<script type="application/octet-stream" class="xval-pack" id="(pack-\d+)" data-encoding="gzip-7bit">'
        r'([^<]*)</script>', page)}
    assert list(packs) == ["pack-0"]
    runs = packs["pack-0"].pop("runs")
    assert len(runs) == RUNS and runs[0].startswith("run ") and " · commit " in runs[0]
    specs = packs["pack-0"]
    titles = re.findall(r"<h3>(.*?)</h3>", page)
    assert titles == ["bead · reference/loose", "bead · reference/coarse"]
    for name, spec in specs.items():
        go.Figure(spec)  # a valid plotly figure (raises on an unknown property)
        assert f'id="{name}" data-expected-traces="{len(spec["data"])}" data-pack="pack-0"' in page
        for trace in spec["data"]:  # values kept to 3 significant digits, what the hover shows
            assert all(y is None or float(f"{y:.2e}") == y for y in trace["y"])
            assert set(trace["x"]) <= set(range(RUNS))
    loose = specs["trend-0"]
    dashed = [s for s in loose["layout"]["shapes"] if s["line"]["dash"] == "dash"]
    assert len(dashed) == 9 and {s["x0"] for s in dashed} == {STEP_AT - 0.5}
    assert not specs["trend-1"]["layout"]["shapes"]
    steps_table = page[page.index('<table class="steps">'):page.index("</table>", page.index('<table class="steps">'))]
    assert steps_table.count("<tr>") == 2  # the heading and one grouped row
    assert "reference/loose" in steps_table and "worse" in steps_table and "×2" in steps_table


def test_machines_are_kept_apart(base, tmp_path):
    from reports.history import page_context

    with History.open(tmp_path / "h.sqlite", create=True) as history:
        for index in range(3):
            add(history, synthetic(base, index), index)
            add(history, synthetic(base, index + 10, machine={"cpu": "another CPU", "cpu_count": 64}), index + 10)
        context = page_context(history)
    assert [(s["machine"].split(" ×")[0], len(s["runs"])) for s in context["sections"]] == [
        (base.header["environment"]["cpu"], 3), ("another CPU", 3)]
    assert all(len(s["plots"]) == 2 for s in context["sections"])


@pytest.mark.parametrize("last", [None, 3])
def test_every_point_is_labelled_with_its_own_run(base, tmp_path, last):
    """Each point's hover label (the pack's run labels, by x) names the run the point's value came from,
    with the whole history or the last N runs, and with two machines whose names read alike (run.json
    fields that differ only where the name shows nothing: no machine type, or an empty one)."""
    from reports.history import page_context

    factor = {}  # run id -> the factor its reference/loose errors were scaled by: identifies the run by value
    with History.open(tmp_path / "h.sqlite", create=True) as history:
        for index in range(4):
            for offset, kind in ((0, None), (10, "")):
                run = add(history, synthetic(base, index + offset, error=index + offset + 1.0,
                                             machine={"machine": kind}), index + offset)
                factor[run.id] = index + offset + 1.0
        context = page_context(history, last=last)
    assert [len(s["runs"]) for s in context["sections"]] == [last or 4] * 2
    checked = 0
    for section in context["sections"]:
        pack = json.loads(unpacked(context["packs"][section["pack"]]))
        labelled = [factor[int(re.match(r"run (\d+) ", label).group(1))] for label in pack["runs"]]
        for plot in section["plots"]:
            for trace in pack[plot.id]["data"]:
                if plot.title.endswith(ENGINE) and f"{ERRORS[0]} =" in trace["hovertemplate"]:
                    first = trace["x"][0]
                    for x, y in zip(trace["x"], trace["y"]):
                        assert y / trace["y"][0] == pytest.approx(labelled[x] / labelled[first], rel=1e-2)
                        checked += 1
    assert checked == 2 * 3 * (last or 4)  # two machines, three dts


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium here; install it with 'apt-get install -y chromium' (.ci/run does)")
def test_the_trend_page_draws_every_plot_in_a_browser_with_the_network_off(planted, tmp_path):
    page_path = tmp_path / "trend.html"
    write_history_report(str(planted), page_path)
    with Page(page_path, tmp_path / "profile") as page:
        # Interactive before plotly.js is unpacked: the tables are plain HTML.
        assert page.evaluate('document.getElementById("xval-render-status").getAttribute("data-state")') in ("ready", "done")
        assert page.await_promise("window.xvalDrawAll()") == 2
        assert page.evaluate('document.getElementById("xval-render-status").textContent') == "2 plots drawn."
        drawn = page.evaluate('Array.from(document.querySelectorAll("div.xval-plot")).map(function (d) {'
                              ' return [d.getAttribute("data-expected-traces"), d.getAttribute("data-drawn-traces")]; })')
        assert len(drawn) == 2 and all(expected == got for expected, got in drawn), drawn
        # Each point's hover label is the run's, filled in from the pack's run labels.
        label = page.evaluate('document.getElementById("trend-0").data[0].customdata[0]')
        assert label.startswith("run ") and " · commit " in label
        assert page.errors() == []
        assert all(url.startswith(("file:", "data:", "blob:", "about:")) for url in page.requests()), page.requests()
