"""Bad input, class by class (docs/reliability.md lists them): each ends in exactly one line on
stderr naming what was wrong and its allowed range or fix, exit 2, before any case runs, never a
traceback. In-process through ``compare.cli.main``; nothing here starts an engine run."""

from __future__ import annotations

import re

import pytest

from compare.cli import main

GOOD_SUITE = 'dt = [1e-2]\nduration = 0.5\nengines = ["mujoco/hinge"]\n[[scenes]]\nscene = "bead"\n'


def suite(**changes: str) -> str:
    """GOOD_SUITE with top-level lines replaced or added (``key = value``), or scene parameters (``parameters``)."""
    lines = {"dt": "[1e-2]", "duration": "0.5", "engines": '["mujoco/hinge"]'}
    scene, parameters = changes.pop("scene", "bead"), changes.pop("parameters", "")
    engines = changes.pop("engine_table", "")
    lines.update(changes)
    text = "".join(f"{k} = {v}\n" for k, v in lines.items() if v is not None)
    text += f'[[scenes]]\nscene = "{scene}"\n' + (f"parameters = {{ {parameters} }}\n" if parameters else "")
    return text + engines


SIM = ["simulate", "bead", "--dt", "1e-2", "--output", "{tmp}/o.csv"]
RUN = ["run", "{tmp}/s.toml", "--output", "{tmp}/r"]

#: (class, files to create in tmp, argv, regex the one stderr line must match after "xval: error: ").
CASES = [
    # -- command-line numbers ------------------------------------------------------------------------
    ("timeout-nan", {"s.toml": GOOD_SUITE}, RUN + ["--timeout", "nan"], r"--timeout.*'nan' is outside the allowed range: more than 0 and at most 1e\+06 s"),
    ("timeout-inf", {"s.toml": GOOD_SUITE}, RUN + ["--timeout", "inf"], r"--timeout.*'inf' is outside the allowed range"),
    ("timeout-negative", {"s.toml": GOOD_SUITE}, RUN + ["--timeout", "-1"], r"--timeout.*'-1' is outside the allowed range"),
    ("timeout-zero", {"s.toml": GOOD_SUITE}, RUN + ["--timeout", "0"], r"--timeout.*'0' is outside the allowed range"),
    ("timeout-text", {"s.toml": GOOD_SUITE}, RUN + ["--timeout", "soon"], r"--timeout.*'soon' is not a number of seconds"),
    ("jobs-zero", {"s.toml": GOOD_SUITE}, RUN + ["--jobs", "0"], r"--jobs.*0 is not in the range 1<=x<=64"),
    ("jobs-huge", {"s.toml": GOOD_SUITE}, RUN + ["--jobs", "1000000"], r"--jobs.*1000000 is not in the range 1<=x<=64"),
    ("memory-limit-tiny", {"s.toml": GOOD_SUITE}, RUN + ["--memory-limit", "10M"], r"--memory-limit.*'10M' is below the allowed minimum of 256M"),
    ("memory-limit-text", {"s.toml": GOOD_SUITE}, RUN + ["--memory-limit", "lots"], r"--memory-limit.*'lots' is not a size; write e.g. 4G"),
    ("run-output-empty", {"s.toml": GOOD_SUITE}, ["run", "{tmp}/s.toml", "--output", ""], r"--output.*is empty"),
    ("run-output-is-a-file", {"s.toml": GOOD_SUITE, "f": "x"}, ["run", "{tmp}/s.toml", "--output", "{tmp}/f"], r"--output: .*/f is a file; give a directory"),
    ("stability-timeout-nan", {"s.toml": GOOD_SUITE}, ["stability", "{tmp}/s.toml", "--output", "{tmp}/st", "--timeout", "nan"], r"--timeout.*'nan' is outside the allowed range"),
    ("dt-nan", {}, ["simulate", "bead", "--dt", "nan", "--output", "{tmp}/o.csv"], r"dt must be positive, got 'nan'"),
    ("dt-negative", {}, ["simulate", "bead", "--dt", "-1e-3", "--output", "{tmp}/o.csv"], r"dt must be positive, got '-1e-3'"),
    ("dt-zero", {}, ["simulate", "bead", "--dt", "0", "--output", "{tmp}/o.csv"], r"dt must be positive, got '0'"),
    ("dt-text", {}, ["simulate", "bead", "--dt", "fast", "--output", "{tmp}/o.csv"], r"dt must be a number of seconds, got 'fast'"),
    ("dt-past-duration", {}, ["simulate", "bead", "--dt", "20", "--output", "{tmp}/o.csv"], r"dt \(20 s\) is larger than the duration \(10 s\)"),
    ("steps-absurd", {}, ["simulate", "bead", "--dt", "1e-9", "--duration", "1000", "--output", "{tmp}/o.csv"], r"duration 1000 s at dt 1e-09 s is 1e\+12 steps, more than the allowed 1e\+08 per case"),
    ("samples-absurd", {}, ["simulate", "chain", "--param", "n=200", "--param", "duration=20000", "--dt", "1e-2", "--output", "{tmp}/o.csv"], r"is 2e\+06 samples of 200 particles; the allowed range is at most 1e\+06 samples"),
    ("sample-interval-nan", {}, SIM + ["--sample-interval", "nan"], r"--sample-interval.*'nan' is outside the allowed range"),
    ("simulate-output-empty", {}, ["simulate", "bead", "--dt", "1e-2", "--output", ""], r"--output.*is empty"),
    ("simulate-output-directory", {"d/x": "x"}, ["simulate", "bead", "--dt", "1e-2", "--output", "{tmp}/d"], r"--output: .*/d is a directory; give a file name"),
    ("simulate-output-missing-directory", {}, ["simulate", "bead", "--dt", "1e-2", "--output", "{tmp}/no/o.csv"], r"--output: directory .*/no does not exist"),
    ("simulate-output-name-too-long", {}, ["simulate", "bead", "--dt", "1e-2", "--output", "{tmp}/" + "n" * 300 + ".csv"], r"--output: the file name n{40}\.\.\. is 304 bytes, longer than the 255 a file system allows"),
    ("bounds-unknown", {}, SIM + ["--bounds", "speed=3"], r"--bounds: unknown bound 'speed'; the bounds are: energy_drift, constraint_error"),
    ("bounds-negative", {}, SIM + ["--bounds", "energy_drift=-1"], r"--bounds: energy_drift must be a positive finite number, got '-1'"),
    ("bounds-malformed", {}, SIM + ["--bounds", "energy_drift"], r"--bounds: expected NAME=VALUE, got 'energy_drift'"),
    # -- scene parameters ----------------------------------------------------------------------------
    ("mass-zero", {}, SIM + ["--param", "m=0"], r"bead: parameter m must be positive, got '0'"),
    ("mass-negative", {}, SIM + ["--param", "m=-2"], r"bead: parameter m must be positive, got '-2'"),
    ("mass-nan", {}, SIM + ["--param", "m=nan"], r"bead: parameter m must be finite, got 'nan'"),
    ("mass-inf", {}, SIM + ["--param", "m=inf"], r"bead: parameter m must be finite, got 'inf'"),
    ("mass-tiny", {}, SIM + ["--param", "m=1e-300"], r"bead: parameter m = 1e-300 kg is outside the allowed range \(1e-09 to 1e\+09 kg\)"),
    ("mass-huge", {}, SIM + ["--param", "m=1e300"], r"bead: parameter m = 1e\+300 kg is outside the allowed range"),
    ("radius-tiny", {}, SIM + ["--param", "radius=1e-300"], r"bead: parameter radius = 1e-300 m is outside the allowed range \(1e-06 to 1e\+06 m\)"),
    ("radius-huge", {}, SIM + ["--param", "radius=1e300"], r"bead: parameter radius = 1e\+300 m is outside the allowed range"),
    ("length-zero", {}, ["simulate", "double-pendulum", "--dt", "1e-2", "--param", "l2=0", "--output", "{tmp}/o.csv"], r"double-pendulum: parameter l2 must be positive, got '0'"),
    ("length-nan", {}, ["simulate", "double-pendulum", "--dt", "1e-2", "--param", "l1=nan", "--output", "{tmp}/o.csv"], r"double-pendulum: parameter l1 must be finite"),
    ("omega-absurd", {}, SIM + ["--param", "omega0=1e300"], r"bead: velocity: components must lie in \[-1e\+06, 1e\+06\] m/s, got .* \(from omega0 = 1e\+300\)"),
    ("gravity-absurd", {}, SIM + ["--param", "g=1e9"], r"bead: gravity: components must lie in \[-1e\+06, 1e\+06\] m/s\^2"),
    ("gravity-negative", {}, SIM + ["--param", "g=-9.81"], r"bead: parameter g must be at least 0, got '-9.81'"),
    ("duration-absurd", {}, ["simulate", "bead", "--dt", "1", "--duration", "1e12", "--output", "{tmp}/o.csv"], r"bead: parameter duration = 1e\+12 s is more than the allowed 1e\+06 s"),
    ("duration-nan", {}, SIM + ["--duration", "nan"], r"bead: parameter duration must be finite"),
    ("links-absurd", {}, ["simulate", "chain", "--dt", "1e-2", "--param", "n=400", "--output", "{tmp}/o.csv"], r"chain: parameter n = 400 is more than the allowed 256"),
    ("links-zero", {}, ["simulate", "chain", "--dt", "1e-2", "--param", "n=0", "--output", "{tmp}/o.csv"], r"chain: parameter n must be positive, got '0'"),
    ("links-fraction", {}, ["simulate", "chain", "--dt", "1e-2", "--param", "n=2.5", "--output", "{tmp}/o.csv"], r"chain: parameter n must be an integer, got '2.5'"),
    ("parameter-unknown", {}, SIM + ["--param", "mass=2"], r"bead: unknown parameter 'mass'; its parameters are: m, radius"),
    ("parameter-malformed", {}, SIM + ["--param", "m"], r"--param: expected NAME=VALUE, got 'm'"),
    ("scene-unknown", {}, ["simulate", "pendulum", "--dt", "1e-2", "--output", "{tmp}/o.csv"], r"unknown scene 'pendulum'; choose one of: bead"),
    # -- engines and options -------------------------------------------------------------------------
    ("engine-unknown", {}, SIM + ["--engine", "bullet"], r"bullet"),
    ("variant-unknown", {}, SIM + ["--engine", "mujoco/nope"], r"unknown variant 'mujoco/nope'; mujoco has: mujoco/hinge"),
    ("option-unknown", {}, SIM + ["--engine", "pymunk", "--option", "speed=2"], r"pymunk: unknown option 'speed'; its options are: error_bias"),
    ("option-not-a-number", {}, SIM + ["--engine", "ours", "--option", "k_s=stiff"], r"ours: option k_s must be a finite number, got 'stiff'"),
    ("option-nan", {}, SIM + ["--engine", "ours", "--option", "k_d=nan"], r"ours: option k_d must be a finite number, got 'nan'"),
    ("option-negative-gain", {}, SIM + ["--engine", "ours", "--option", "k_s=-1"], r"ours: option k_s = -1.0 is outside the allowed range \[0, 1e\+12\]"),
    ("option-iterations-absurd", {}, SIM + ["--engine", "pybullet", "--option", "iterations=100000000"], r"pybullet: option iterations = 100000000 is outside the allowed range <= 10000"),
    ("option-rtol-below-eps", {}, SIM + ["--engine", "reference", "--option", "rtol=1e-300"], r"reference: option rtol = 1e-300 is outside the allowed range \[1e-14, 0.1\]"),
    ("option-choice", {}, SIM + ["--engine", "mujoco", "--option", "integrator=leapfrog"], r"mujoco: option integrator must be one of"),
    ("option-3d-in-2d-engine", {}, ["simulate", "spherical-pendulum", "--engine", "pymunk", "--dt", "1e-2", "--output", "{tmp}/o.csv"], r"pymunk is 2-D and cannot express the 3-D scene 'spherical-pendulum'"),
    # -- suite files ---------------------------------------------------------------------------------
    ("suite-missing", {}, ["run", "{tmp}/none.toml", "--output", "{tmp}/r"], r"none.toml: no such file; pass the path of a suite"),
    ("suite-not-utf8", {"s.toml": b"name = \"\xff\xfe\"\n"}, RUN, r"s.toml: .*(UTF-8|utf-8)"),
    ("suite-invalid-toml", {"s.toml": "dt = [1e-2\n"}, RUN, r"s.toml(:\d+)?: invalid TOML"),
    ("suite-unknown-key", {"s.toml": suite(colour='"red"')}, RUN, r"s.toml:\d+: colour: unknown key"),
    ("suite-timeout-nan", {"s.toml": suite(timeout="nan")}, RUN, r"s.toml:\d+: timeout: must be a positive number, got nan"),
    ("suite-timeout-inf", {"s.toml": suite(timeout="inf")}, RUN, r"s.toml:\d+: timeout: must be a positive number, got inf"),
    ("suite-dt-zero", {"s.toml": suite(dt="[0.0]")}, RUN, r"dt\[0\]: must be a positive number, got 0.0"),
    ("suite-dt-negative", {"s.toml": suite(dt="[-1e-3]")}, RUN, r"dt\[0\]: must be a positive number, got -0.001"),
    ("suite-repeats-zero", {"s.toml": suite(repeats="0")}, RUN, r"repeats: must be a positive integer, got 0"),
    ("suite-mass-zero", {"s.toml": suite(parameters="m = 0")}, RUN, r"scenes\[0\].parameters: bead: parameter m must be positive"),
    ("suite-radius-tiny", {"s.toml": suite(parameters="radius = 1e-300")}, RUN, r"scenes\[0\].parameters: bead: parameter radius = 1e-300 m is outside the allowed range"),
    ("suite-links-absurd", {"s.toml": suite(scene="chain", parameters="n = 400")}, RUN, r"scenes\[0\].parameters: chain: parameter n = 400 is more than the allowed 256"),
    ("suite-steps-absurd", {"s.toml": suite(dt="[1e-7]", duration="100")}, RUN, r"s.toml: scene 'bead': duration 100 s at dt 1e-07 s is 1e\+09 steps, more than the allowed 1e\+08 per case"),
    ("suite-engine-unknown", {"s.toml": suite(engines='["bullet"]')}, RUN, r"engines\[0\].id: .*bullet"),
    ("suite-engine-option-range", {"s.toml": suite(engines=None, engine_table='[[engines]]\nid = "ours/baumgarte-rk4"\noptions = { k_s = -5 }\n')}, RUN, r"engines\[0\].options: ours: option k_s = -5.0 is outside the allowed range"),
    ("run-output-name-too-long", {"s.toml": GOOD_SUITE}, ["run", "{tmp}/s.toml", "--output", "{tmp}/" + "d" * 300], r"/d{300}: File name too long; choose a shorter path or name"),
    ("suite-name-too-long", {}, ["run", "{tmp}/" + "s" * 300 + ".toml", "--output", "{tmp}/r"], r"/s{300}\.toml: cannot read it \(File name too long\); pass the path of a suite"),
]


@pytest.mark.parametrize("files, argv, pattern", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2(files, argv, pattern, tmp_path, capsys):
    for name, content in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(SystemExit) as stop:
        main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    out, err = capsys.readouterr()
    assert stop.value.code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("xval: error: "), err
    assert re.search(pattern, lines[0]), lines[0]
    assert not (tmp_path / "r" / "cases").exists() or not any((tmp_path / "r" / "cases").iterdir())


def test_at_least_sixty_classes_are_covered():
    assert len({c[0] for c in CASES}) == len(CASES) >= 60
