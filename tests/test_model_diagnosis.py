"""The diagnosis on imports built by hand: what it says for a moved COM, a fused group that lost a fixed
joint's rotation, and nothing at all for an import that holds the file (pure functions, no engine)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from compare.model.diagnosis import diagnose, sentences
from compare.model.parity import relative_difference
from engines.model import source, urdf
from engines.model.inertia import LinkInertia, combine, description_inertias

FIXED_RPY = Path(__file__).resolve().parents[1] / "models/pitfalls/fixed_rpy.urdf"


def model():
    return urdf.read(source.resolve(str(FIXED_RPY)))


def test_an_import_that_holds_the_file_has_no_findings():
    description = model()
    held = description_inertias(description)
    assert diagnose(description, held) == []
    # Fused the right way (the tool's rotation kept) is still the file.
    fused = {"base": held["base"], "arm": combine([held["arm"], held["tool"]])}
    assert diagnose(description, fused) == []


def test_a_moved_centre_of_mass_is_named_with_its_distance():
    description = model()
    held = description_inertias(description)
    tool = held["tool"]
    held["tool"] = LinkInertia(tool.mass, tool.com + np.array([0.0, 0.0, 0.1]), tool.inertia)
    assert sentences({"someengine": diagnose(description, held)}) == [
        "link tool: mass 5 kg, inertia principal moments (0.2, 0.3, 0.4) kg·m² — someengine moves the COM by 0.1 m"]


def test_a_fused_group_that_lost_the_fixed_joints_rotation_is_named():
    """The bug of a fused fixed joint whose rpy was dropped: the tool's COM offset and inertia unrotated."""
    description = model()
    held = description_inertias(description)
    wrong_tool = LinkInertia(5.0, np.array([0.4, 0, 0.1]) + np.array([0.1, 0.05, 0]), np.diag([0.2, 0.3, 0.4]))
    fused = {"base": held["base"], "arm": combine([held["arm"], wrong_tool])}
    (line,) = sentences({"someengine": diagnose(description, fused)})
    assert line.startswith("links arm, tool: welded together (2 links) — someengine moves the COM by ")
    # Independent check of the figure it quotes: the tool's COM as the file places it (scipy's rotation).
    right = np.array([0.4, 0, 0.1]) + Rotation.from_euler("xyz", [0.3, 0.5, -0.2]).as_matrix() @ [0.1, 0.05, 0]
    shift = 5.0 * np.linalg.norm(right - wrong_tool.com) / 5.5
    assert f"moves the COM by {shift:.3g} m" in line


def test_the_relative_difference_divides_by_the_largest_reference_entry_over_all_states():
    reference = [np.array([1.0, -4.0]), np.array([0.0, 0.5])]
    engine = [np.array([1.0, -4.0]), np.array([0.2, 0.5])]
    assert relative_difference(engine, reference) == 0.2 / 4.0
    # A NaN at any state, first or not, is an infinite difference.
    assert relative_difference([np.array([0.1, 0.0]), np.array([np.nan, 0.0])], reference) == np.inf
