"""Suite files: the shipped ones load; every rule a bad file breaks has its own pinned message."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from compare.suite.reader import geometric_sweep, load_suite, parse_suite
from engines.errors import UserError

ROOT = Path(__file__).resolve().parent.parent

GOOD = """\
name = "t"
duration = 1.0
dt = [1e-2, 1e-3]

[[scenes]]
id = "bead"
scene = "bead"

[[engines]]
id = "mujoco/hinge"
"""


def bad(text: str, message: str) -> None:
    with pytest.raises(UserError, match="^" + re.escape(message) + "$"):
        parse_suite(text, "s.toml")


def test_shipped_suites_load():
    default = load_suite(ROOT / "suites/default.toml")
    assert default.dts[0] == 0.1 and default.dts[-1] == 1e-4 and len(default.dts) == 7
    assert {s.id for s in default.scenes} == {"bead", "double-pendulum", "slider-pendulum", "four-bar", "bead-ellipse"}
    labels = {e.label for e in default.engines}
    assert {"mujoco/hinge", "pymunk/pin", "pybullet/multibody"} <= labels
    smoke = load_suite(ROOT / "suites/smoke.toml")
    assert smoke.name == "smoke" and all(s.scene.duration <= 1.0 for s in smoke.scenes)


def test_a_good_suite_parses_with_defaults():
    suite = parse_suite(GOOD, "s.toml")
    assert suite.dts == (1e-2, 1e-3)
    assert suite.scenes[0].scene.duration == 1.0
    assert (suite.sample_interval, suite.delta, suite.repeats, suite.timeout) == (0.01, 1e-2, 1, 120.0)
    assert suite.engines[0].id == "mujoco/hinge" and suite.engines[0].variant == "hinge"


def test_wildcard_expands_to_every_variant():
    from engines import registry

    suite = parse_suite(GOOD.replace('"mujoco/hinge"', '"mujoco/*"'), "s.toml")
    assert [e.label for e in suite.engines] == registry.get_engine("mujoco").variant_ids()


def test_geometric_sweep():
    assert geometric_sweep(1e-1, 1e-4, 1) == [0.1, 0.01, 0.001, 0.0001]
    assert geometric_sweep(1e-1, 1e-2, 2) == [0.1, 0.0316227766017, 0.01]


def test_missing_file():
    with pytest.raises(UserError, match=r"^nope\.toml: no such file; pass the path of a suite: a UTF-8 \.toml file"):
        load_suite("nope.toml")


def test_invalid_toml_gives_the_line():
    bad(GOOD.replace("duration = 1.0", "duration = = 1.0"),
        "s.toml:2: invalid TOML at column 12: Invalid value; fix the syntax there")


def test_unknown_top_level_key():
    bad(GOOD.replace("duration = 1.0", "durations = 1.0"),
        "s.toml:2: durations: unknown key; valid keys are: name, description, duration, sample_interval, "
        "delta, repeats, timeout, dt, reference, bounds, tolerances, gate, scenes, engines, stability, gainmap, verdict, "
        "tolerance, gradients")


def test_missing_required_key():
    bad(GOOD.replace("dt = [1e-2, 1e-3]\n", ""),
        "s.toml: dt: missing; add dt = ... (a list of time steps or a table {from, to, per_decade})")


def test_wrong_type():
    bad(GOOD.replace("duration = 1.0", 'duration = "long"'),
        "s.toml:2: duration: must be a positive number, got a string 'long'; write e.g. duration = 0.01")


def test_not_positive():
    bad("delta = -1\n" + GOOD, "s.toml:1: delta: must be a positive number, got -1")


def test_repeats_must_be_an_integer():
    bad(GOOD.replace('name = "t"', 'name = "t"\nrepeats = 1.5'),
        "s.toml:2: repeats: must be a positive integer, got a number 1.5; write e.g. repeats = 1")


def test_unknown_key_in_a_table():
    bad(GOOD + "\n[bounds]\nenergy = 1.0\n",
        "s.toml:13: bounds.energy: unknown key; valid keys are: energy_drift, constraint_error")


def test_unknown_tolerance_metric():
    bad(GOOD + "\n[tolerances]\nspeed = 1.0\n",
        "s.toml:13: tolerances.speed: unknown key; valid keys are: position_error_linf, position_error_rms, "
        "position_error_final, divergence_time, energy_drift, constraint_error, constraint_force_error, "
        "observed_order, momentum_drift, gradient_error, gradient_wrong, cost_per_simulated_second")


def test_a_results_suite_toml_refuses_an_unknown_tolerance_as_the_suite_reader_does(tmp_path):
    """xval gate reads [tolerances] from a results directory's suite.toml (load_run_settings): one check, so
    the same line-numbered message as reading the suite itself."""
    from compare.suite.reader import load_run_settings

    text = GOOD + "\n[tolerances]\nspeed = 1.0\n"
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(UserError) as stored:
        load_run_settings(tmp_path / "s.toml")
    with pytest.raises(UserError) as read:
        parse_suite(text, str(tmp_path / "s.toml"))
    assert str(stored.value) == str(read.value)
    assert str(stored.value).startswith(f"{tmp_path / 's.toml'}:13: tolerances.speed: unknown key; valid keys are: ")


def test_tolerances_and_gate_validate_a_tolerance_alike():
    # [tolerances] and [gate] both set relative tolerances: the same rule (a number >= 0) for both,
    # each message naming the key (and, for the suite file, the line).
    for table in ("tolerances", "gate"):
        suite = parse_suite(GOOD + f"\n[{table}]\nenergy_drift = 0\n")
        assert suite.gate.tolerance("energy_drift").rtol == 0.0
        bad(GOOD + f"\n[{table}]\nenergy_drift = -0.1\n",
            f"s.toml:13: {table}.energy_drift: must be a number ≥ 0, got -0.1; write e.g. energy_drift = 0.1")


def test_incomplete_sweep():
    bad(GOOD.replace("dt = [1e-2, 1e-3]", "dt = { from = 1e-1, to = 1e-3 }"),
        "s.toml:3: dt: the sweep needs per_decade; write dt = { from = 1e-1, to = 1e-4, per_decade = 2 }")


def test_empty_dt_list():
    bad(GOOD.replace("dt = [1e-2, 1e-3]", "dt = []"),
        "s.toml:3: dt: is empty; list at least one time step, e.g. dt = [1e-2, 1e-3]")


def test_duplicate_dt():
    bad(GOOD.replace("dt = [1e-2, 1e-3]", "dt = [1e-2, 1e-2]"),
        "s.toml:3: dt: lists the same time step twice; remove the duplicate")


def test_dt_longer_than_the_duration():
    bad(GOOD.replace("dt = [1e-2, 1e-3]", "dt = [2.0]"),
        "s.toml:3: dt: the time step 2 s is longer than scene 'bead''s duration 1 s; "
        "use smaller time steps or a longer duration")


def test_unknown_scene():
    bad(GOOD.replace('scene = "bead"', 'scene = "beed"'),
        "s.toml:7: scenes[0].scene: unknown scene 'beed'; choose one of: bead, double-pendulum, chain, spherical-pendulum, slider-pendulum, four-bar, bead-ellipse")


def test_bad_scene_parameter():
    bad(GOOD.replace('scene = "bead"', 'scene = "bead"\nparameters = { radius = -1 }'),
        "s.toml:8: scenes[0].parameters: bead: parameter radius must be positive, got -1")


def test_unknown_scene_parameter():
    bad(GOOD.replace('scene = "bead"', 'scene = "bead"\nparameters = { mass = 2 }'),
        "s.toml:8: scenes[0].parameters: bead: unknown parameter 'mass'; "
        "its parameters are: m, radius, theta0, omega0, g, duration")


def test_duplicate_scene_id():
    bad(GOOD + '\n[[scenes]]\nid = "bead"\nscene = "double-pendulum"\n',
        "s.toml:13: scenes[1].id: 'bead' is used twice; give each scene a distinct id")


def test_unknown_engine():
    bad(GOOD.replace('id = "mujoco/hinge"', 'id = "mujoko/hinge"'),
        "s.toml:10: engines[0].id: unknown engine 'mujoko'; choose one of: "
        # built-ins, then installed plugins (e.g. examples/my-solver)
        + ", ".join(__import__("engines.registry").registry.engine_names()))


def test_unknown_variant():
    bad(GOOD.replace('id = "mujoco/hinge"', 'id = "mujoco/hinj"'),
        "s.toml:10: engines[0].id: unknown variant mujoco/hinj; choose one of: "
        + ", ".join(__import__("engines.registry").registry.get_engine("mujoco").variant_ids()))


def test_unknown_engine_option():
    from engines import registry

    options = ", ".join(registry.get_engine("mujoco").options)
    bad(GOOD + "options = { stiffness = 3 }\n",
        f"s.toml:11: engines[0].options: mujoco: unknown option 'stiffness'; its options are: {options}")


def test_duplicate_engine():
    bad(GOOD + '\n[[engines]]\nid = "mujoco/hinge"\n',
        "s.toml:13: engines[1].id: 'mujoco/hinge' is listed twice; remove one, "
        "or give variants with different options a label")


def test_module_attribute_that_is_not_an_engine():
    bad(GOOD.replace('id = "mujoco/hinge"', 'id = "math:pi"'),
        "s.toml:10: engines[0].id: engine 'math:pi': math.pi is not an Engine object; "
        "point module:attribute at an engines.adapter.Engine instance")


def test_engines_as_plain_strings():
    suite = parse_suite(GOOD.split("[[engines]]")[0].replace('name = "t"', 'name = "t"\nengines = ["pymunk/pin"]'), "s.toml")
    assert [e.label for e in suite.engines] == ["pymunk/pin"]


def test_a_command_engines_program_and_version_are_part_of_the_fingerprint(tmp_path):
    """--resume must not mix results of two different programs under one label."""
    def suite(argv: str, version: str) -> str:
        return GOOD.replace('[[engines]]\nid = "mujoco/hinge"',
                            f'[[engines]]\ncommand = {argv}\nlabel = "mine"\nversion = "{version}"')

    path = str(tmp_path / "s.toml")
    (tmp_path / "s.toml").write_text("")
    base = parse_suite(suite('["python3", "a.py"]', "1"), path).fingerprint()
    assert parse_suite(suite('["python3", "a.py"]', "1"), path).fingerprint() == base
    assert parse_suite(suite('["python3", "b.py"]', "1"), path).fingerprint() != base
    assert parse_suite(suite('["python3", "a.py"]', "2"), path).fingerprint() != base


def test_reference_tolerances_outside_the_reference_engines_range_are_refused():
    bad(GOOD.replace('dt = [1e-2, 1e-3]', 'dt = [1e-2, 1e-3]\n[reference]\nrtol = 1e-300'),
        "s.toml:5: reference.rtol: reference: option rtol = 1e-300 is outside the allowed range [1e-14, 0.1]")
