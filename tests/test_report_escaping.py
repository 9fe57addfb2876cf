"""Every string from a suite or results file reaches the page as text: a `<script>` id renders, it never runs."""

from __future__ import annotations

import re

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
    scene = page.section("scene-0")
    assert scene.heading == f"Scene {HOSTILE}"
    summary = scene.tables[0]
    assert [row[0] for row in summary.rows[1:]] == [HOSTILE, "broken/raise"]
    problems = page.problems_table()
    assert problems.rows[1][0] == HOSTILE and problems.rows[1][4].endswith(HOSTILE)
    assert str(markupsafe.escape(HOSTILE)) in hostile_html  # escaped by Jinja, quotes included


def test_no_script_or_element_is_injected(hostile_html):
    page = PageStructure(hostile_html)
    executable = [a for a in page.scripts if "type" not in a]
    assert len(executable) == 1  # the page's own; every other <script> is data (packed: base64 only)
    assert not [url for url in page.urls if not url.startswith("#")]
    # The verdict names the hostile engine as text too: in its cost table, heat map and legend.
    verdict = page.section("verdict")
    assert HOSTILE in [row[0] for table in verdict.tables for row in table.rows]


def test_packed_tables_are_escaped_like_the_page(hostile_html):
    """The tables at other dts are inserted with innerHTML when asked for: they must be escaped HTML already."""
    page = PageStructure(hostile_html)
    for name in ("tables-0-packed", "problems-packed"):
        packed = page.packs()[name]
        assert HOSTILE not in packed and "<img" not in packed and "<script" not in packed
    tables = page.other_dt_tables(0)
    assert tables and all(table.rows[1][0] == HOSTILE for table in tables)


def test_figure_json_cannot_close_its_script_and_plot_text_is_escaped(hostile_html):
    page = PageStructure(hostile_html)
    for attrs, body in zip(page.scripts, page.script_bodies):
        if "type" in attrs:
            # Packed (reports/pack.py): no "<" can close the element, no NUL or CR for the parser to change.
            assert attrs.get("data-encoding") == "gzip-7bit" and not re.search("[<\x00\r]", body)
    names = {trace["name"] for spec in page.figure_specs().values() for trace in spec["data"]}
    # plotly.js reads a subset of HTML in trace names: they carry the escaped text, which it shows literally.
    assert plot_text(HOSTILE) in names
    assert HOSTILE not in names
