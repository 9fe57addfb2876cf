"""``xval simulate`` and ``xval engines`` across every built-in engine variant and catalog scene.

Exit codes as documented: 0 when the run ends ok, 1 when it ends unstable or
failed (the CSV still holds the samples up to the end), 2 for a pair the
engine cannot express (with the reason).
"""

import csv

import numpy as np
import pytest

from cli_support import run_cli
from engines.scene import catalog
from engines import registry

BUILT_IN = ["ours", "mujoco", "pybullet", "pymunk"]
VARIANTS = [v for name in BUILT_IN for v in registry.get_engine(name).variant_ids()]
#: Pairs left out on purpose, with the words their refusal must contain.
LEFT_OUT = {
    ("pymunk", "spherical-pendulum"): "pymunk is 2-D and cannot express the 3-D scene 'spherical-pendulum'",
    ("ours/lagrangian", "spherical-pendulum"): "planar chain",
    # Mechanisms (tests/test_mechanisms_engines.py pins these refusals in full).
    ("ours/lagrangian", "slider-pendulum"): "ours/lagrangian needs a chain hung from a fixed point",
    ("ours/lagrangian", "four-bar"): "ours/lagrangian needs a chain hung from a fixed point",
    ("ours/lagrangian", "bead-ellipse"): "ours/lagrangian needs a chain hung from a fixed point",
    ("mujoco/connect", "slider-pendulum"): "MuJoCo has no equality constraint that holds a point on a line",
    ("mujoco/connect", "four-bar"): "use mujoco/hinge, which closes a loop with an equality",
    ("mujoco", "bead-ellipse"): "MuJoCo cannot hold a body on an ellipse",
    ("pybullet/multibody", "four-bar"): "closes a loop through particle 1",
    ("pybullet", "bead-ellipse"): "no joint or constraint of PyBullet holds a body on an ellipse",
    ("pymunk", "bead-ellipse"): "pymunk has no joint that holds a body on an ellipse",
}


def refusal(variant: str, scene_name: str) -> str | None:
    for (prefix, scene), words in LEFT_OUT.items():
        if variant.startswith(prefix) and scene == scene_name:
            return words
    return None


@pytest.mark.parametrize("scene_name", catalog.scene_names())
@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_simulates_every_scene_it_can_express(variant, scene_name, tmp_path, capsys):
    output = tmp_path / "run.csv"
    code, out, err = run_cli(capsys, *["simulate", scene_name, "--engine", variant, "--dt", "1e-3",
                                  "--duration", "0.1", "--output", str(output)])
    words = refusal(variant, scene_name)
    if words is not None:
        assert code == 2 and words in err and err.count("\n") == 1
        assert not output.exists()
        return
    assert code == 0, out + err
    rows = np.array(list(csv.reader(output.open()))[1:], dtype=float)
    assert len(rows) == 11  # 0.1 s sampled every 0.01 s, both ends included
    scene = catalog.build(scene_name)
    # 0.1 s at dt = 1e-3 from the catalog's initial state: every engine starts where the scene says
    # and stays within a stretch of 1 % of L (the softest setting, MuJoCo's default connect, stays under 0.3 %).
    np.testing.assert_allclose(rows[0, 1:4], scene.initial_positions[0], atol=1e-9)
    assert rows[:, -1].max() < 1e-2 * scene.characteristic_length


def test_a_blow_up_exits_1_and_keeps_the_samples_up_to_it(tmp_path, capsys):
    output = tmp_path / "blowup.csv"
    code, out, err = run_cli(capsys, *["simulate", "chain", "--engine", "mujoco/hinge", "--dt", "0.05",
                                  "--param", "n=8", "--duration", "5", "--output", str(output)])
    assert code == 1, out + err
    assert ": unstable," in out
    rows = list(csv.reader(output.open()))[1:]
    assert 1 < len(rows) < 101  # some samples, fewer than the 101 scheduled
    assert np.isfinite(np.array(rows, dtype=float)).all()


def test_engines_lists_every_engine_with_version_variants_and_capabilities(capsys):
    code, out, _ = run_cli(capsys, *["engines"])
    assert code == 0
    for name in BUILT_IN + ["reference"]:
        engine = registry.get_engine(name)
        assert f"{name} {engine.version()}" in out
        for variant in engine.variant_ids():
            assert variant in out
    assert "pymunk" in out and "can express: constraint-forces" in out
