"""The report's gradient section (reports/gradients.py): a suite with [gradients] gets it, with its variants, the
reference's horizon where the scene is chaotic and an accessible name on every plot; a suite without has none."""

from __future__ import annotations

import re

import pytest

from reports.gradients import Line, time_svg
from reports.load import load_report_data
from reports.render import render
from report_support import PageStructure, run_suite_once

#: A regular scene (the bead: no horizon) and a chaotic one (the double pendulum released at 150°, 150°: the
#: reference's Jacobian parts from its tighter solve at 4.6 s of 6), three variants: MuJoCo's RK4 and pymunk by
#: differences of rollouts (error over time), MuJoCo's Euler by its chained mjd_transitionFD (error at T only).
SUITE = """
name = "gradients-report"
dt = [2e-3]
duration = 0.5
sample_interval = 0.01
repeats = 1
timeout = 600
scenes = [
    { id = "bead", scene = "bead" },
    { id = "chaos", scene = "double-pendulum", parameters = { theta1 = 150, theta2 = 150, duration = 6.0 } },
]
engines = [{ id = "mujoco/hinge-rk4" }, { id = "mujoco/hinge" }, { id = "pymunk/pin" }]
gradients = { wrt = ["theta0", "theta1"] }
"""
VARIANTS = ["mujoco/hinge-rk4", "mujoco/hinge", "pymunk/pin"]


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> str:
    suite = tmp_path_factory.mktemp("suite") / "suite.toml"
    suite.write_text(SUITE)
    return render(load_report_data(run_suite_once(tmp_path_factory.mktemp("gradients"), suite)))


def _section(text: str, section_id: str) -> str:
    start = text.index(f'<section class="gradient-scene" id="{section_id}"')
    return text[start:text.index("</section>", start)]


def test_a_suite_with_gradients_gets_the_section_with_its_variants(page):
    structure = PageStructure(page)
    section = structure.section("gradients")
    assert section.heading.startswith("Gradients")
    tables = [t for s in structure.sections if s.id.startswith("gradients-") for t in s.tables]
    assert len(tables) == 2  # one per scene
    for table in tables:
        assert [row[0] for row in table.rows[1:]] == VARIANTS
    bead, chaos = tables
    # RK4 to the reference within 1e-6 on the bead, the first-order variants at their O(dt) (~1e-2 at 2e-3 s)
    assert float(bead.rows[1][2]) < 1e-6 and all(1e-4 < float(row[2]) < 0.1 for row in bead.rows[2:])
    assert [row[4] for row in bead.rows[1:]] == ["correct"] * 3
    # past the horizon neither side resolves the sensitivity: chaotic, whatever the error
    assert [row[4] for row in chaos.rows[1:]] == ["chaotic"] * 3


def test_the_chaotic_scene_marks_the_reference_horizon_and_the_regular_one_none(page):
    bead, chaos = _section(page, "gradients-0"), _section(page, "gradients-1")
    assert 'class="horizon"' not in bead and "reference horizon none" in bead
    horizon = float(re.search(r"reference horizon ([0-9.]+) s", chaos).group(1))
    assert 2.0 < horizon < 6.0
    assert chaos.count('class="horizon"') == 2  # on the error plot and on the norm growth


def test_every_gradient_plot_has_an_accessible_name_and_each_variant_its_family_s_marker(page):
    for number in (0, 1):
        section = _section(page, f"gradients-{number}")
        svgs = re.findall(r"<svg [^>]*>", section)
        assert len(svgs) == 2 and all('aria-label="' in svg for svg in svgs)
        groups = dict(re.findall(r'<g class="series" data-variant="([^"]+)"[^>]*>(.*?)</g>', section))
        # the two MuJoCo variants share their family's shape, pymunk has another; each draws its marker
        shapes = {name: re.findall(r"<(circle|polygon)", body) for name, body in groups.items() if name in VARIANTS}
        assert set(shapes) == set(VARIANTS) and all(shapes.values())


def test_a_suite_without_gradients_has_no_section(tmp_path):
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE.replace('gradients = { wrt = ["theta0", "theta1"] }', "").replace(
        'engines = [{ id = "mujoco/hinge-rk4" }, { id = "mujoco/hinge" }, { id = "pymunk/pin" }]',
        'engines = [{ id = "pymunk/pin" }]').replace("duration = 6.0", "duration = 0.5"))
    text = render(load_report_data(run_suite_once(tmp_path, suite)))
    assert 'id="gradients"' not in text


def test_the_time_plot_leaves_out_what_a_log_axis_cannot_show_and_escapes_names():
    svg = str(time_svg([Line("<b>x</b>", "#000", "dash", "square", [(0.0, 0.0), (0.5, 1e-3), (1.0, float("nan")),
                                                                        (1.5, 1e-2), (2.0, 2e-2)])],
                       duration=2.0, y_title="e", label="a <plot>", horizon=1.0))
    assert 'aria-label="a &lt;plot&gt;"' in svg and "<b>" not in svg
    assert svg.count("<polyline") == 1  # 0 and NaN break the line: one run of two points is drawn
    assert 'class="horizon"' in svg
    assert str(time_svg([], duration=1.0, y_title="e", label="empty")) == ""
