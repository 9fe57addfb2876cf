"""``xval report``: the page's structure for a fixed small results directory, its self-containment, and robustness.

The results come from a real run of tests/report_suite.toml (see
report_support); the expected structure below is the golden one: which
sections, tables, rows and plots (with how many traces each) the page has.
"""

from __future__ import annotations

import json
import re

import plotly.graph_objects as go
import pytest

from compare.results.sweep import sweeps
from engines.errors import UserError
from report_support import PageStructure, copy_results, run_suite_once
from reports.load import choose_dt, load_report_data
from reports.render import render, write_report
from reports.summary import Column, _best_flags, metric_columns
from cli_support import run_cli


@pytest.fixture(scope="session")
def small_results(tmp_path_factory):
    return run_suite_once(tmp_path_factory.getbasetemp())


@pytest.fixture(scope="session")
def small_page(small_results):
    return PageStructure(render(load_report_data(small_results)))


# -- golden structure -------------------------------------------------------------------

#: Per scene: summary rows (engine, status at the chosen dt), other tables, and plots with their trace counts.
GOLDEN = {
    "scene-0": {
        "heading": "Scene bead",
        "rows": [("reference/dop853", "ok"), ("mujoco/hinge-rk4", "ok"), ("pymunk/pin", "ok"),
                 ("broken/blow-up", "unstable"), ("broken/raise", "failed")],
        "tables": ["summary sortable filterable"],
        # work-precision and error-vs-dt: the 3 variants with ok cases; time series: 4 variants with samples
        # x 3 panels and the × where broken/blow-up stops; constraint forces: the reference's + the 3 variants whose engines report them (the
        # broken engine returns none) and, below (issue 44), those 3 variants' difference from the reference's;
        # phase plot: the reference + 4 variants, 1 particle; paths: the same, and below (issue 44) the 4
        # variants' distance from the reference.
        "plots": [("s0-wp", 3), ("s0-dt", 3), ("s0-ts", 13), ("s0-force", 7), ("s0-phase", 5), ("s0-path", 9)],
    },
    "scene-1": {
        "heading": "Scene spherical",
        "rows": [("reference/dop853", "ok"), ("mujoco/hinge-rk4", "ok"),
                 ("broken/blow-up", "unstable"), ("broken/raise", "failed")],
        "tables": ["summary sortable filterable", "skipped"],
        "plots": [("s1-wp", 2), ("s1-dt", 2), ("s1-ts", 10), ("s1-force", 5), ("s1-phase", 4), ("s1-path", 7)],
    },
}


def test_page_has_the_sections_in_order_the_verdict_first(small_page):
    assert [(s.id, s.heading) for s in small_page.sections] == [
        ("top", "xval report: report-small"),
        ("summary", "Summary"),  # issue 44: the summary across scenes before the verdict
        ("verdict", "Verdict"),
        ("run", "Run"),
        ("scene-0", "Scene bead"),
        ("scene-1", "Scene spherical"),
        ("problems", "Unstable and failed cases"),
        ("how-to-read", "How to read this"),
    ]
    # Before the verdict: the title and the filter bar only, no table and no plot.
    assert small_page.sections[0].tables == [] and small_page.sections[0].plots == []


def test_header_counts_every_status(small_page):
    counts = small_page.section("run").tables[0]
    assert counts.css_class == "counts"
    assert counts.rows == [
        ["cases", "ran", "ok", "unstable", "failed", "skipped"],
        ["30", "27", "15", "6", "6", "3"],
    ]


def test_header_names_machine_engines_and_commit(small_results):
    html = render(load_report_data(small_results))
    header = json.loads((small_results / "run.json").read_text())
    env = header["environment"]
    for text in (env["cpu"], env["python"], env["engines"]["mujoco"], env["engines"]["pymunk"], header["started"]):
        assert text in html
    if env["git_commit"]:
        assert env["git_commit"] in html


@pytest.mark.parametrize("section_id", sorted(GOLDEN))
def test_scene_sections_have_the_golden_tables_and_plots(small_page, section_id):
    golden = GOLDEN[section_id]
    section = small_page.section(section_id)
    assert section.heading == golden["heading"]
    assert [t.css_class for t in section.tables] == golden["tables"]
    summary = section.tables[0]
    assert summary.rows[0][:4] == ["engine variant", "status at this dt", "consistent", "over the dt sweep"]
    assert [(row[0], row[1]) for row in summary.rows[1:]] == golden["rows"]
    assert section.plots == golden["plots"]


def test_summary_marks_the_best_value_of_each_column(small_page):
    summary = small_page.section("scene-0").tables[0]
    header, rows = summary.rows[0], {row[0]: row for row in summary.rows[1:]}
    column = {name: header.index(name) for name in header}
    # MuJoCo's RK4 is far more accurate than pymunk's first-order solver: it holds the position-error star.
    assert rows["mujoco/hinge-rk4"][column["position error / m"]].startswith("★")
    assert not rows["pymunk/pin"][column["position error / m"]].startswith("★")
    # The reference is never ranked, and neither are the broken variants.
    for name in ("reference/dop853", "broken/blow-up", "broken/raise"):
        assert not any(cell.startswith("★") for cell in rows[name])
    # Neither ok variant diverges: a tie of everyone, so no star at all in that column.
    divergence = column["divergence time / s"]
    assert [rows[n][divergence] for n in ("mujoco/hinge-rk4", "pymunk/pin")] == ["never", "never"]
    # Every other column has exactly one star (the order only pymunk's first-order sweep could fit) but the CPU
    # cost's: a cost is starred only beyond its interval (at least 1.7× either side), which two engines this
    # close need not be.
    cost = column["CPU cost / s/s"]
    stars = [sum(row[k].startswith("★") for row in rows.values()) for k in range(4, len(header))
             if k not in (divergence, cost)]
    assert stars == [1] * len(stars)
    assert sum(row[cost].startswith("★") for row in rows.values()) <= 1
    assert all(float(rows[n][cost].lstrip("★ ")) > 0 for n in ("mujoco/hinge-rk4", "pymunk/pin"))


def test_a_run_without_samples_shows_no_numbers(small_page):
    row = next(r for r in small_page.section("scene-0").tables[0].rows if r[0] == "broken/raise")
    assert row[4:] == ["–"] * 7  # six declared report metrics and the order


def test_skipped_pairs_are_listed_with_their_reason(small_page):
    skipped = small_page.section("scene-1").tables[1]
    assert skipped.rows[1:] == [["pymunk/pin", "pymunk is 2-D and cannot express the 3-D scene 'spherical-pendulum'"]]


def test_problems_list_every_unstable_and_failed_case_with_its_message(small_page):
    problems = small_page.problems_table()
    rows = problems.rows[1:]
    assert len(rows) == 12
    assert {(r[1], r[3]) for r in rows} == {("broken/blow-up", "unstable"), ("broken/raise", "failed")}
    assert "non-finite state at t = 0.25 s" in {r[4] for r in rows}
    assert "RuntimeError: deliberate failure of <b>the test engine</b> & friends" in {r[4] for r in rows}


def test_how_to_read_states_every_metric_and_its_unit(small_results):
    html = render(load_report_data(small_results))
    section = html[html.index('id="how-to-read"'):]
    for term in ("position error (m)", "divergence time (s)", "energy drift (E*)", "constraint error (m)",
                 "constraint-force error (N)", "cost (s/s)", "observed order", "E* = total mass · g · L",
                 "δ = 0.01"):
        assert term in section


def test_how_to_read_states_the_settings_of_the_suite_stored_with_the_results(small_results, tmp_path):
    """δ, the status bounds and the verdict tolerance the page states are DIR/suite.toml's, not the defaults
    (the test above would pass on defaults: the small suite sets none of them)."""
    results = copy_results(small_results, tmp_path / "settings")
    suite = results / "suite.toml"
    suite.write_text("delta = 0.05\n" + suite.read_text()
                     + "\n[bounds]\nenergy_drift = 0.25\nconstraint_error = 0.125\n\n[verdict]\ntolerance = 3e-05\n")
    html = render(load_report_data(results))
    section = html[html.index('id="how-to-read"'):]
    for term in ("δ = 0.05;", "above 0.25 E*", "above 0.125 L", "(3e-05·L)"):
        assert term in section, term


def test_status_element_announces_plots_and_traces(small_page):
    plots = small_page.plots
    assert small_page.status["data-plots"] == str(len(plots)) == "12"
    assert small_page.status["data-traces"] == str(sum(n for _, n in plots))


# -- figures ----------------------------------------------------------------------------


def test_every_figure_spec_is_valid_plotly_with_the_announced_traces(small_page):
    specs = small_page.figure_specs()
    # Besides each plot, the time series at the scene's two other dts, for the dt selector.
    others = {f"s{n}-ts@{j}" for n in (0, 1) for j in (0, 1)}
    assert sorted(specs) == sorted([plot_id for plot_id, _ in small_page.plots] + list(others))
    for plot_id, n_traces in small_page.plots:
        figure = go.Figure(specs[plot_id])  # raises on any property plotly does not know
        assert len(figure.data) == n_traces
    for plot_id in others:
        go.Figure(specs[plot_id])


def test_work_precision_is_log_log_with_dt_in_the_hover(small_page):
    spec = small_page.figure_specs()["s0-wp"]
    assert spec["layout"]["xaxis"]["type"] == spec["layout"]["yaxis"]["type"] == "log"
    trace = next(t for t in spec["data"] if t["name"] == "mujoco/hinge-rk4")
    assert [c[1] for c in trace["customdata"]] == [1e-2, 3e-3, 1e-3]
    assert "dt = %{customdata[1]" in trace["hovertemplate"] and "%{customdata[0]}" in trace["hovertemplate"]


def test_error_vs_dt_legend_gives_the_observed_order(small_page):
    names = [t["name"] for t in small_page.figure_specs()["s0-dt"]["data"]]
    assert any(re.fullmatch(r"pymunk/pin \(order 1\.\d\d\)", n) for n in names), names
    # RK4's errors (≤ 9e-9 m at these dts) sit below the fit's 1e-8 L floor: no order, shown as a dash.
    assert "mujoco/hinge-rk4 (order –)" in names, names


def test_a_run_that_blows_up_is_marked_where_it_stops(small_page):
    spec = small_page.figure_specs()["s0-ts"]
    marks = [t for t in spec["data"] if t.get("mode") == "markers+text"]
    # The test engine's state turns NaN at t = 0.25 s; its last finite sample is at 0.24 s.
    assert [(t["name"], t["text"]) for t in marks] == [("broken/blow-up", ["non-finite after t = 0.24 s"])]


def test_paths_are_drawn_over_the_reference_at_equal_scale(small_page):
    spec = small_page.figure_specs()["s0-path"]
    assert spec["data"][0]["name"] == "reference"
    assert spec["layout"]["yaxis"]["scaleanchor"] == "x"


# -- self-contained -----------------------------------------------------------------------


def test_plotly_is_embedded_once_and_nothing_is_fetched(small_results, small_page):
    html = render(load_report_data(small_results))
    executable = [body for attrs, body in zip(small_page.scripts, small_page.script_bodies) if "type" not in attrs]
    assert len(executable) == 1  # the page's own script; plotly.js and the data are packed, not executable as such
    packs = small_page.packs()
    bundle = packs["xval-plotly"]
    assert len(bundle) > 3_000_000 and "plotly.js v" in bundle[:1000]
    assert sum("plotly.js v" in text for text in packs.values()) == 1  # once, not a copy per figure
    assert all("src" not in attrs for attrs in small_page.scripts)
    assert not [url for url in small_page.urls if not url.startswith("#")]
    for text in [html] + [t for name, t in packs.items() if name != "xval-plotly"]:
        assert "http:" not in text and "https:" not in text  # no CDN, no link: the page names no server at all
    assert "default-src 'none'" in html  # the page's CSP forbids any request


# -- robustness ----------------------------------------------------------------------------


def test_a_single_case_renders(small_results, tmp_path):
    single = copy_results(small_results, tmp_path / "one",
                          keep=lambda r: r["case"]["id"] == "bead|pymunk/pin|dt=0.003")
    page = PageStructure(render(load_report_data(single)))
    assert [s.id for s in page.sections] == ["top", "summary", "verdict", "run", "scene-0", "problems", "how-to-read"]
    assert page.section("scene-0").tables[0].rows[1][:2] == ["pymunk/pin", "ok"]
    # One point: nothing to fit an order to, but every plot still draws its one variant;
    # the force, phase and paths plots add the reference's, stored in the record beside the engine's, and the
    # force and paths plots (issue 44) the variant's difference from it.
    assert [n for _, n in page.plots] == [1, 1, 3, 3, 2, 3]


def test_only_failures_and_skips_render(small_results, tmp_path):
    broken = copy_results(small_results, tmp_path / "broken",
                          keep=lambda r: r["status"] in ("failed", "skipped"))
    page = PageStructure(render(load_report_data(broken)))
    assert page.plots == []
    assert len(page.problems_table().rows) == 1 + 6
    assert page.section("scene-1").tables[1].css_class == "skipped"


def test_a_scene_whose_every_pair_was_skipped_renders(small_results, tmp_path):
    skipped = copy_results(small_results, tmp_path / "skipped", keep=lambda r: r["status"] == "skipped")
    html = render(load_report_data(skipped))
    page = PageStructure(html)
    assert [s.heading for s in page.sections if s.id.startswith("scene-")] == ["Scene spherical"]
    assert "No engine variant ran on this scene." in html
    assert [t.css_class for t in page.section("scene-0").tables] == ["skipped"]
    assert page.plots == [] and "None: no case ran." in html


def test_an_empty_or_unfinished_run_renders(small_results, tmp_path):
    def unfinished(header):
        header["finished"] = None
        header.pop("counts", None)

    empty = copy_results(small_results, tmp_path / "empty", keep=lambda r: False, change_header=unfinished)
    html = render(load_report_data(empty))
    assert "not finished" in html
    assert [s.id for s in PageStructure(html).sections] == ["top", "summary", "verdict", "run", "problems", "how-to-read"]


def test_missing_metrics_and_series_render(small_results, tmp_path):
    """Records from a writer that stored no series (or an older one): tables still render, plots drop out."""
    def strip(record):
        record["series"] = None

    stripped = copy_results(small_results, tmp_path / "stripped", change=strip)
    page = PageStructure(render(load_report_data(stripped)))
    assert [plot_id for plot_id, _ in page.plots] == ["s0-wp", "s0-dt", "s1-wp", "s1-dt"]


# -- choices --------------------------------------------------------------------------------


def test_chosen_dt_is_the_smallest_with_the_most_ok_variants(small_results):
    from compare.run.results import load_results

    scene_sweeps = [s for s in sweeps(load_results(small_results).records) if s.scene_id == "bead"]
    assert choose_dt(scene_sweeps, [1e-2, 3e-3, 1e-3]) == 1e-3
    assert choose_dt(scene_sweeps, [1e-2, 3e-3, 1e-3], requested=4e-3) == 3e-3
    assert choose_dt([], []) is None


def test_best_flags_rank_only_eligible_values_and_keep_ties():
    low = Column("x", "x", "m", "low")
    assert _best_flags(low, [3.0, 1.0, 1.0, 0.5], [True, True, True, False]) == [False, True, True, False]
    assert _best_flags(low, [2.0, 2.0], [True, True]) == [False, False]  # all tie: nothing to point at
    assert _best_flags(low, [2.0, 5.0], [True, False]) == [True, False]  # a single ranked value is still best
    assert _best_flags(low, [None, None], [True, True]) == [False, False]
    divergence = next(c for c in metric_columns() if c.key == "divergence_time")
    # None is "never diverged": the best divergence time there is.
    assert _best_flags(divergence, [0.3, None, 0.9], [True, True, True]) == [False, True, False]


# -- the command -----------------------------------------------------------------------------




def test_report_command_writes_dir_report_html_by_default(small_results, tmp_path, capsys):
    results = copy_results(small_results, tmp_path / "r")
    code, out, err = run_cli(capsys, "report", str(results))
    assert code == 0, err
    assert (results / "report.html").is_file()
    assert out.startswith(f"report: {results / 'report.html'} (")


def test_report_command_output_and_dt(small_results, tmp_path, capsys):
    target = tmp_path / "elsewhere.html"
    code, _, err = run_cli(capsys, "report", str(small_results), "--output", str(target), "--dt", "0.01")
    assert code == 0, err
    page = PageStructure(target.read_text())
    assert '<option value="0" selected>0.01 s</option>' in target.read_text()
    assert page.section("scene-0").tables[0].rows[1][:2] == ["reference/dop853", "ok"]


@pytest.mark.parametrize("argv, message", [
    (["report", "{tmp}/nowhere"], r"^xval: error: .*nowhere: not a results directory.*; give the --output directory of 'xval run'\n$"),
    (["report", "{results}", "--output", "{tmp}/no/such/dir/r.html"], r"^xval: error: --output: directory .* does not exist; create it or choose another path\n$"),
    (["report", "{results}", "--dt", "-1"], r"^xval: error: .*--dt.*\n$"),
])
def test_bad_input_is_one_line_and_exit_2(small_results, tmp_path, capsys, argv, message):
    argv = [a.format(tmp=tmp_path, results=small_results) for a in argv]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert re.match(message, err), err


def test_a_record_of_another_schema_version_is_refused(small_results, tmp_path):
    def old(record):
        record["schema_version"] = 0

    results = copy_results(small_results, tmp_path / "old", change=old)
    with pytest.raises(UserError, match=r"results schema version 0, but this xval reads version \d+; re-run the suite"):
        write_report(results)


def test_write_report_reports_size_and_time(small_results, tmp_path):
    written = write_report(small_results, tmp_path / "r.html")
    assert written.size == (tmp_path / "r.html").stat().st_size
    assert 1_650_000 < written.size < 3_000_000  # the packed plotly.js bundle (1.68 MB) and a little data
    assert written.seconds < 10


# -- the verdict section --------------------------------------------------------------------------


def _unbroken(html: str) -> str:
    """``html`` without the spans that keep each number on one line (reports.render.unbroken_numbers)."""
    return re.sub(r'<span class="num">([^<]*)</span>', r"\1", html)


def _answers(html: str) -> list[str]:
    return [re.sub(r"\s+", " ", m) for m in re.findall(r'<p class="answer">(.*?)</p>', _unbroken(html), re.S)]


def test_the_verdict_compares_the_suites_first_family_unless_told_otherwise(small_results):
    data = load_report_data(small_results)
    # The reference is the yardstick, so the first competing family is mujoco; pymunk's first-order pin
    # never reaches 1e-6 L = 1e-6 m in this short sweep, so the sentence gives both sides.
    first = _answers(render(data))
    assert first[0].startswith("to reach 1e-06 m: mujoco/hinge-rk4 ≤ ") and "pymunk/pin not reached" in first[0]
    assert _answers(render(data, "pymunk"))[0].startswith("to reach 1e-06 m: pymunk/pin not reached (best 0.002 m); mujoco/hinge-rk4 ≤ ")
    # The spherical scene has no pymunk variant (2-D engine): the verdict says so instead of comparing.
    assert _answers(render(data, "pymunk"))[1] == "no pymunk variant ran on this scene."


def test_the_verdict_lists_problems_with_links_to_their_evidence(small_page, small_results):
    html = render(load_report_data(small_results))
    items = re.findall(r'<li data-engine="([^"]+)" data-status="([^"]+)">.*?<a href="(#[^"]+)">evidence</a></li>', html)
    assert items[:2] == [("broken/raise", "failed", "#s0-d0-v4"), ("broken/blow-up", "unstable", "#s0-d0-v3")]
    # The links point at rows of the scene's tables (the largest dt's is packed; its rows carry those ids).
    rows = [row[0] for row in small_page.other_dt_tables(0)[0].rows]
    assert rows[4] == "broken/blow-up" and rows[5] == "broken/raise"
    assert 'id="s0-d0-v3"' in small_page.packs()["tables-0-packed"]


def test_an_unknown_focus_family_is_one_line_and_exit_2(small_results, tmp_path, capsys):
    code, out, err = run_cli(capsys, "report", str(small_results), "--output", str(tmp_path / "r.html"), "--focus", "nope")
    assert code == 2 and out == ""
    assert err == "xval: error: --focus: no engine family 'nope' in these results; choose one of: mujoco, pymunk, broken\n"


def test_a_stored_probe_result_lists_hidden_dissipation(small_results, tmp_path):
    """``xval probe ENGINE --format json > DIR/probe-NAME.json``: a variant found damping shows as a problem."""
    results = copy_results(small_results, tmp_path / "probed")
    (results / "probe-pymunk.json").write_text(json.dumps(
        {"engine": "pymunk/pin", "scene": "bead", "rate": 0.0123, "uncertainty": 0.001, "hidden_dissipation": True}))
    (results / "probe-mujoco.json").write_text(json.dumps(
        {"engine": "mujoco/hinge-rk4", "scene": "bead", "rate": 1e-9, "uncertainty": 1e-9, "hidden_dissipation": False}))
    html = _unbroken(render(load_report_data(results)))
    items = re.findall(r'<li data-engine="([^"]+)" data-status="hidden dissipation">(.*?)</li>', html, re.S)
    assert [engine for engine, _ in items] == ["pymunk/pin"]  # bead only: pymunk does not run the 3-D scene
    assert "(0.012 E*/s)" in items[0][1]


def test_best_flags_mark_no_star_inside_the_error_bars():
    low = Column("x", "x", "m", "low")
    # 4.22e-12 against 6.23e-12 with the reference's bar 4.2e-12 on each: a difference inside the bars, no star.
    assert _best_flags(low, [4.22e-12, 6.23e-12, 1e-3], [True, True, True], [4.2e-12, 4.2e-12, 4.2e-12]) == \
        [False, False, False]
    # Beyond both bars the best keeps its star.
    assert _best_flags(low, [4.22e-12, 6.23e-8, 1e-3], [True, True, True], [4.2e-12, 4.2e-12, 4.2e-12]) == \
        [True, False, False]


def test_each_scenes_verdict_is_computed_once_per_report(small_results, monkeypatch):
    # The verdict section, the plots' colours and the time series at every dt all come from one verdict per scene.
    import compare.results.verdict as verdict
    import reports.emphasis
    import reports.verdict

    calls: list[str] = []

    def counted(sweeps, *args, **kwargs):
        calls.append(sweeps[0].scene_id)
        return verdict.scene_verdicts(sweeps, *args, **kwargs)

    monkeypatch.setattr(reports.verdict, "scene_verdicts", counted)
    monkeypatch.setattr(reports.emphasis, "scene_verdicts", counted)
    data = load_report_data(small_results)
    render(data)
    assert sorted(calls) == sorted(scene.scene_id for scene in data.scenes if scene.sweeps)


#: Characters drawn as emoji by default (Unicode Emoji_Presentation): the page must need no emoji font.
_EMOJI = re.compile("[\u231a\u231b\u23e9-\u23f3\u23f8-\u23fa\u25fd\u25fe\u2614\u2615\u2648-\u2653\u267f\u2693\u26a1"
                    "\u26aa\u26ab\u26bd\u26be\u26c4\u26c5\u26ce\u26d4\u26ea\u26f2\u26f3\u26f5\u26fa\u26fd\u2705"
                    "\u270a\u270b\u2728\u274c\u274e\u2753-\u2755\u2757\u2795-\u2797\u27b0\u27bf\u2b1b\u2b1c\u2b50"
                    "\u2b55\U0001f000-\U0001faff]")


def test_the_page_needs_no_emoji_font_and_its_inline_plots_are_named(small_results):
    html = render(load_report_data(small_results))
    assert _EMOJI.findall(html) == []
    svgs = re.findall(r"<svg\b[^>]*>", html)
    assert svgs and all(re.search(r'aria-label="[^"]{20,}"', svg) for svg in svgs)


def test_the_verdict_draws_error_against_dt_beside_the_work_precision_with_each_order(small_results):
    from reports.palette import Palette
    from reports.verdict import verdict_views

    data = load_report_data(small_results)
    view = verdict_views(data, Palette(s.engine for scene in data.scenes for s in scene.sweeps))[0]
    orders = {e.engine: e.order for _, entries in view.pareto.legend for e in entries}
    # The orders the plotly plot's legend gives (test_error_vs_dt_legend_gives_the_observed_order): pymunk's
    # first-order stepping, and no fit for RK4, whose errors sit below the fit's floor.
    assert re.fullmatch(r"1\.\d\d", orders["pymunk/pin"]) and orders["mujoco/hinge-rk4"] == "–", orders
    dt_svg, wp_svg = str(view.pareto.dt_svg), str(view.pareto.svg)
    assert 'id="dtplot-0"' in dt_svg and "max position error against the time step dt" in dt_svg
    # One y axis for both plots: the same decades, so a variant's errors sit at the same heights side by side.
    ticks = re.compile(r'text-anchor="end">10<tspan[^>]*>(-?\d+)</tspan>')
    assert ticks.findall(dt_svg) == ticks.findall(wp_svg) != []
    # Each variant's dt sweep: one marker per ok run (mujoco's three dts).
    mujoco = re.search(r'<g class="series[^"]*" data-series="\d+" data-variant="mujoco/hinge-rk4".*?</g>', dt_svg).group(0)
    assert mujoco.count("<title>") == 3 and "dt 0.001 s" in mujoco


def test_forces_and_paths_draw_the_difference_from_the_reference(small_page, small_results):
    data = load_report_data(small_results)
    bead = data.scenes[0]
    record = bead.case_at(next(s for s in bead.sweeps if s.engine == "mujoco/hinge-rk4"), bead.chosen_dt)
    specs = small_page.figure_specs()
    # Paths: below the x–z plane, each variant's position error against t; its largest value is the case's max
    # position error (the same samples; 4 significant digits in the spec).
    [distance] = [t for t in specs["s0-path"]["data"] if t.get("yaxis") == "y2" and t["name"] == "mujoco/hinge-rk4"]
    assert max(distance["y"]) == pytest.approx(record.metrics["position_error_linf"], rel=1e-3)
    assert specs["s0-path"]["layout"]["legend"]["tracegroupgap"] == 0  # one group per variant: no gaps to scroll
    # Forces: below ‖F‖, the largest difference from the reference's force, from the stored forces (6 significant
    # digits a component, so within 1e-5·max‖F‖ of exact, and drawn at that floor when below it); its maximum is
    # the case's constraint-force error.
    [difference] = [t for t in specs["s0-force"]["data"] if t.get("yaxis") == "y2" and t["name"] == "mujoco/hinge-rk4"]
    forces = [t for t in specs["s0-force"]["data"] if t.get("yaxis") == "y" and t["name"] == "reference"][0]["y"]
    resolution = 1e-5 * max(forces)
    assert min(v for v in difference["y"] if v is not None) >= resolution * (1 - 1e-3)
    assert abs(max(difference["y"]) - record.metrics["constraint_force_error"]) <= resolution + 1e-3 * max(difference["y"])
    assert specs["s0-force"]["layout"]["legend"]["tracegroupgap"] == 0
