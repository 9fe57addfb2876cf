"""The report's building blocks: colours per engine family, LTTB thinning, clipped blow-ups, the verdict's SVG."""

from __future__ import annotations

import math
from pathlib import Path

from reports.decimate import decimate, lttb_indices
from reports.figures import clip, phase_curve
from reports.palette import FAMILY_COLOURS, Palette, family_colours
from reports.svgplot import Series, loglog_svg


def _hue(colour: str) -> float:
    import colorsys

    r, g, b = (int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return colorsys.rgb_to_hls(r, g, b)[0]


def test_a_variant_has_the_same_colour_in_every_report():
    alone = Palette(["mujoco/hinge"])
    crowded = Palette(["ours/rk4", "pybullet/p2p", "mujoco/hinge", "pymunk/pin", "reference/dop853"])
    assert alone.style("mujoco/hinge") == crowded.style("mujoco/hinge")
    # Trace order does not matter either.
    assert Palette(reversed(["ours/rk4", "mujoco/hinge"])).colour("ours/rk4") == crowded.colour("ours/rk4")


def test_families_get_distinct_hues_and_variants_shades_of_theirs():
    families = family_colours(["ours", "mujoco", "pybullet", "pymunk"])
    assert len(set(families.values())) == 4
    palette = Palette(["mujoco/hinge", "mujoco/connect", "ours/rk4"])
    hinge, connect, ours = (palette.colour(e) for e in ("mujoco/hinge", "mujoco/connect", "ours/rk4"))
    assert abs(_hue(hinge) - _hue(connect)) < 0.02 < abs(_hue(hinge) - _hue(ours))
    assert palette.style("mujoco/hinge") != palette.style("mujoco/connect")
    assert Palette(["reference/dop853"]).style("reference/dop853")["color"].startswith("rgba(0,0,0")


def test_colliding_families_are_moved_apart():
    names = [f"family{k}" for k in range(len(FAMILY_COLOURS))]
    assert len(set(family_colours(names).values())) == len(FAMILY_COLOURS)


def test_lttb_keeps_at_most_the_limit_the_ends_and_a_spike():
    x = list(range(100_000))
    y = [math.sin(i / 500) for i in x]
    y[61_234] = 40.0  # a blow-up spike one sample wide
    kept = lttb_indices(x, y, 2000)
    assert len(kept) <= 2000 and kept[0] == 0 and kept[-1] == len(x) - 1
    assert 61_234 in kept
    assert kept == sorted(kept)
    short_x, short_y = decimate([0.0, 1.0], [1.0, 2.0])
    assert (short_x, short_y) == ([0.0, 1.0], [1.0, 2.0])


def test_lttb_keeps_a_gap_as_a_gap():
    x = list(range(10_000))
    y = [1.0] * 5_000 + [None] * 5_000  # a run cut at its first non-finite state
    kept = lttb_indices(x, y, 100)
    assert any(y[i] is None for i in kept) and any(y[i] == 1.0 for i in kept)


def test_clip_caps_a_blow_up_and_says_when():
    values, blew = clip([0.0, 0.1, 0.2, 0.3, 0.4], [1.0, 5.0, 1e300, None, 2.0], ceiling=10.0)
    assert values == [1.0, 5.0, 10.0, 10.0, 2.0] and blew == 0.2
    assert clip([0.0, 1.0], [1.0, 2.0], 10.0) == ([1.0, 2.0], None)


def test_phase_curve_of_a_planar_pendulum_from_velocities_and_from_differences():
    # θ(t) = 0.3 sin t for a 1 m rod: positions and velocities exact.
    t = [k * 0.01 for k in range(101)]
    theta = [0.3 * math.sin(s) for s in t]
    omega = [0.3 * math.cos(s) for s in t]
    positions = [[[math.sin(a), 0.0, -math.cos(a)]] for a in theta]
    velocities = [[[w * math.cos(a), 0.0, w * math.sin(a)]] for a, w in zip(theta, omega)]
    th, om = phase_curve(t, positions, velocities, 0, [0.0, 0.0, 0.0], planar=True)
    assert max(abs(a - b) for a, b in zip(th, theta)) < 1e-12
    assert max(abs(a - b) for a, b in zip(om, omega)) < 1e-12
    _, differenced = phase_curve(t, positions, None, 0, [0.0, 0.0, 0.0], planar=True)
    # Central differences over 0.02 s: error ≈ ω h² / 6 ≈ 2e-5 rad/s inside; one-sided at the ends.
    assert max(abs(a - b) for a, b in zip(differenced[1:-1], omega[1:-1])) < 1e-4


def test_the_verdict_svg_escapes_its_text_and_draws_the_front():
    hostile = '<script>x()</script>"'
    svg = str(loglog_svg([Series(hostile, "#123456", "g", [(1e-3, 1e-4, hostile), (1e-2, 1e-8, "b")])],
                         [(1e-3, 1e-4), (1e-2, 1e-8)], x_title=hostile, y_title="e", target=1e-6, target_label="t"))
    assert "<script" not in svg and "&lt;script&gt;" in svg
    assert svg.count("<circle") == 2 and 'class="front"' in svg
    assert loglog_svg([], [], x_title="x", y_title="y") == ""


def test_a_run_cut_short_is_marked_where_it_stops():
    from reports.figures import last_finite

    assert last_finite([0.0, 0.1, 0.2], [1.0, 2.0, None], 0.2) == (0.1, 2.0)  # turned non-finite
    assert last_finite([0.0, 0.1], [1.0, 2.0], 0.2) == (0.1, 2.0)  # stored series stops early
    assert last_finite([0.0, 0.1, 0.2], [1.0, 2.0, 3.0], 0.2) is None  # ran to the end


def test_the_time_series_shade_the_run_past_the_reference_horizon(tmp_path):
    """A chaotic scene's errors past the reference horizon are not the engine's: the plot shades them."""
    import json
    import shutil

    from reports.figures import scene_plots
    from reports.load import load_report_data

    run = tmp_path / "run"
    shutil.copytree(Path(__file__).parent / "fixtures" / "run-v1-smoke", run)
    for file in (run / "cases").glob("double-pendulum_*.json"):
        record = json.loads(file.read_text())
        record["reference_horizon"] = 0.6
        file.write_text(json.dumps(record))
    scenes = {s.scene_id: s for s in load_report_data(run).scenes}
    shaded = next(p for p in scene_plots(scenes["double-pendulum"], 1) if p.id.endswith("-ts"))
    [shape] = shaded.figure["layout"]["shapes"]
    assert (shape["x0"], shape["x1"]) == (0.6, 1.0)
    assert "Shaded from t = 0.6 s: past the reference horizon" in shaded.caption
    plain = next(p for p in scene_plots(scenes["bead"], 0) if p.id.endswith("-ts"))
    assert "shapes" not in plain.figure["layout"] and "horizon" not in plain.caption


def test_si_prefixes_round_first_and_never_break():
    from reports.numbers import si

    assert si(1.28e-3, "s/s") == "1.3\u00a0ms/s"
    assert si(2.8e-10, "m") == "280\u00a0pm"  # never "2.8e+02 pm"
    assert si(999.96, "m") == "1\u00a0km"  # rounding carries to the next prefix
    assert si(0.0, "m") == "0\u00a0m" and si(None, "m") == "–" and si(math.inf, "m") == "–"


def test_the_summary_names_an_import_that_disagrees_with_the_links_at_fault():
    from reports.overview import import_findings

    # As reports.parity.parity_view lays out `xval model check`'s JSON for the Panda (compare/model/diagnosis.py).
    parity = {"reference": "pinocchio 4.1.0", "rows": [
        {"engine": "mujoco", "agrees": False, "message": "", "cells": [{"value": 0.3}],
         "diagnosis": ["links panda_link8, panda_grasptarget: mass 0 with inertia 0.1 kg·m² — mujoco drops the inertia"]},
        {"engine": "pybullet", "agrees": True, "message": "", "cells": [{"value": 1e-12}], "diagnosis": []},
        {"engine": "drake", "agrees": False, "message": "", "cells": [{"value": 0.2}],
         "diagnosis": ["link panda_link8: mass 0 with inertia 0.1 kg·m² — drake gives it 1 kg"]},
    ]}
    found = import_findings(3, "panda", parity, ran={"mujoco", "pybullet"})
    assert [(f.engine, f.href) for f in found] == [("mujoco", "#parity-3"), ("drake", "#parity-3")]
    assert found[0].text == ("disagrees with pinocchio 4.1.0 on this file: panda_link8, panda_grasptarget; "
                             "its error below reflects the import, not the stepping")
    assert found[1].text.endswith("panda_link8 (not in this run)")


def test_the_animation_view_leaves_out_a_runaway_link_of_a_model():
    from reports.animation import runaway

    # An arm's links within 0.6 m of the base; a free finger falls 6 m (the Panda's in issue 44).
    frames = [[[0.1, 0.3], [0.3, 0.5], [0.5, 0.4], [0.6, 0.2], [0.55, 0.2 - 6.0 * t]] for t in (0.0, 0.5, 1.0)]
    assert runaway([{"positions": frames}], model=True) == {4}
    assert runaway([{"positions": frames}], model=False) == set()  # a catalog scene's particles all count


def test_the_verdict_plot_names_its_picks_without_overlap_and_has_an_accessible_name():
    import re

    series = [Series("a/x", "#0072b2", "a", [(1e-3, 1e-4, "a/x: dt 0.01 s")], symbol="circle"),
              Series("b/y", "#e69f00", "b", [(1.05e-3, 1.02e-4, "b/y: dt 0.01 s")], symbol="square")]
    svg = str(loglog_svg(series, [], x_title="cost", y_title="error", picks=[(1e-3, 1e-4, "a/x"),
                                                                             (1.05e-3, 1.02e-4, "b/y")],
                         label="Scene s: error against cost"))
    assert 'aria-label="Scene s: error against cost"' in svg
    assert svg.count("<polygon") == 1 and svg.count("<circle") == 1  # one marker shape per family
    baselines = [float(y) for y in re.findall(r'<text class="pick" x="[^"]+" y="([^"]+)"', svg)]
    assert len(baselines) == 2 and abs(baselines[0] - baselines[1]) >= 13  # the second label moved below the first


def test_blow_ups_near_one_another_share_one_label():
    from reports.figures import _blowup_marker, place_blowup_labels

    # Three runs blow up in the last 2 % of a 2 s run, one early; the early one and a non-finite cut keep their own.
    markers = [_blowup_marker(t, 10.0, "#000", ("x", "y"), f"v/{k}") for k, t in enumerate((1.99, 1.96, 0.5, 1.97))]
    markers.append(_blowup_marker(1.98, 3.0, "#000", ("x", "y"), "v/cut", "non-finite after t = {t:.3g} s"))
    place_blowup_labels(markers, 2.0)
    labels = sorted(m["text"][0] for m in markers if "text" in m)
    assert labels == ["3 runs blew up at t = 1.96–1.99 s", "blew up at t = 0.5 s", "non-finite after t = 1.98 s"]
    # Every run keeps its ×, and its own hover text names it.
    assert len(markers) == 5 and all(m["marker"]["symbol"] == "x" for m in markers)
    assert sorted(m["hovertemplate"].split("<br>")[0] for m in markers) == ["v/0", "v/1", "v/2", "v/3", "v/cut"]
    # Labels along t take successive corners, so the cluster's and the cut's do not print over each other.
    assert len({m["textposition"] for m in markers if "text" in m}) == 3


def test_a_legend_key_draws_the_line_style_and_marker_shape():
    from reports.svgplot import key_svg

    key = str(key_svg("square", "dash", "#0072b2"))
    assert 'stroke-dasharray="6 4"' in key and "<polygon" in key and "color: #0072b2" in key
    assert 'class="key muted"' in str(key_svg("circle", "solid", "#0072b2", muted=True))
    assert "stroke-dasharray" not in str(key_svg("circle", "solid", "#0072b2")) and "<circle" in str(key_svg("circle", "solid", "#0072b2"))
