"""Every string from a suite or results file reaches the page as text: a `<script>` id renders, it never runs."""

from __future__ import annotations

import markupsafe

import pytest

from report_support import HOSTILE, PageStructure, hostile_results
from reports.figures import plot_text
from reports.load import load_report_data
from reports.render import render


@pytest.fixture(scope="session")
def hostile_html(tmp_path_factory):
    return render(load_report_data(hostile_results(tmp_path_factory.getbasetemp())))


def test_hostile_strings_never_appear_raw(hostile_html):
    assert HOSTILE not in hostile_html
    assert "<img" not in hostile_html
    assert "window.__xval_injected" in hostile_html  # it is there, but only as text


def test_hostile_strings_render_as_text(hostile_html):
    page = PageStructure(hostile_html)
    # The parser decodes entities: what a reader sees is the literal string.
    assert page.sections[0].heading == f"xval report: {HOSTILE}"
    assert page.sections[1].heading == f"Scene {HOSTILE}"
    summary = page.sections[1].tables[0]
    assert [row[0] for row in summary.rows[1:]] == [HOSTILE, "broken/raise"]
    problems = page.section("problems").tables[0]
    assert problems.rows[1][0] == HOSTILE and problems.rows[1][4].endswith(HOSTILE)
    assert str(markupsafe.escape(HOSTILE)) in hostile_html  # escaped by Jinja, quotes included


def test_no_script_or_element_is_injected(hostile_html):
    page = PageStructure(hostile_html)
    executable = [a for a in page.scripts if a.get("type") != "application/json"]
    assert len(executable) == 2
    assert not [url for url in page.urls if not url.startswith("#")]


def test_figure_json_cannot_close_its_script_and_plot_text_is_escaped(hostile_html):
    page = PageStructure(hostile_html)
    for attrs, body in zip(page.scripts, page.script_bodies):
        if attrs.get("type") == "application/json":
            assert "<" not in body and ">" not in body  # tojson writes \u003c, \u003e
    names = {trace["name"] for spec in page.figure_specs().values() for trace in spec["data"]}
    # plotly.js reads a subset of HTML in trace names: they carry the escaped text, which it shows literally.
    assert plot_text(HOSTILE) in names
    assert HOSTILE not in names
