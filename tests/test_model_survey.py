"""`xval model survey` over pybullet_data's robot models (every URDF with two or more moving joints, every MJCF
file: scripts/model_survey.py's set): no crash of xval itself, JSON that parses, every URDF that is well-formed
(XML, no xacro, numbers where numbers go) checked rather than refused, a reason on every row that is not
"agrees". Bounded in time by the per-engine timeout; its duration is a benchmark (bench/bench_model_survey.py)."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

from cli_support import run_cli

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "model_survey.py"
FIXTURES = Path(__file__).resolve().parent / "fixtures" / "models"
#: The reasons a URDF may be refused for: what only the user can fix in the file.
USER_FIXES = re.compile(r"not well-formed XML|unexpanded xacro|is not \d finite numbers")


def survey_script():
    spec = importlib.util.spec_from_file_location("scripts_model_survey", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def pybullet_data_set() -> list[str]:
    return survey_script().pybullet_data_set()


def test_the_survey_of_pybullet_data(capsys):
    models = pybullet_data_set()
    assert len(models) >= 60  # 41 URDFs and 26 MJCF files in pybullet 3.2.7
    code, out, err = run_cli(capsys, "model", "survey", *models, "--jobs", "2", "--states", "10", "--timeout", "120",
                             "--format", "json")
    report = json.loads(out)
    rows = report["files"]
    assert [row["model"] for row in rows] == models
    assert [row for row in rows if row["outcome"] == "failed"] == []  # xval itself never fails
    assert sum(report["counts"].values()) == len(models)
    assert code == (1 if report["counts"]["crashed"] else 0)
    refused_urdf = [row for row in rows if row["model"].endswith(".urdf") and row["outcome"] == "refused"]
    assert all(USER_FIXES.search(row["reason"]) for row in refused_urdf), refused_urdf
    checked = [row for row in rows if row["model"].endswith(".urdf") and row["outcome"] != "refused"]
    assert len(checked) >= 35
    assert all(row["reason"] for row in rows if row["outcome"] != "agrees")
    assert all(row["engines"] for row in rows if row["outcome"] in ("disagrees", "crashed"))
    assert "checking: " in err  # progress on stderr, a line at each tenth when not a terminal


def test_the_survey_of_gymnasiums_mujoco_assets(capsys):
    """Every MJCF in gymnasium's envs/mujoco/assets (the folder, found as `model survey` finds files): xval never
    fails, the JSON parses, every file MuJoCo compiles is checked (not refused), and every row that is not
    "agrees" names its engines and a cause. ant.xml (a free joint) is compared in all four engines."""
    import mujoco

    script = survey_script()
    models = script.gymnasium_set()
    assert len(models) >= 14  # gymnasium 1.4.0
    code, out, err = run_cli(capsys, "model", "survey", script.gymnasium_assets(), "--jobs", "2", "--states", "10",
                             "--timeout", "120", "--format", "json")
    report = json.loads(out)
    rows = {row["model"]: row for row in report["files"]}
    assert sorted(rows) == models
    assert report["counts"]["failed"] == 0 and report["counts"]["crashed"] == 0 and code == 0, err
    for model, row in rows.items():
        try:
            mujoco.MjModel.from_xml_path(model)
        except ValueError:
            continue
        assert row["outcome"] != "refused", row
        if row["outcome"] != "agrees":
            assert row["engines"] and row["reason"], row
    ant = rows[str(script.gymnasium_assets() / "ant.xml")]
    assert (ant["outcome"], ant["moving_joints"]) == ("disagrees", 8)
    assert ant["engines"] == ["pybullet", "dart"] and "dart holds 1 kg·m²" in ant["reason"], ant


def test_a_folder_is_searched_and_an_engine_crash_is_a_crashed_row(capsys, tmp_path):
    """The acrobot (DART segfaults on it) and a same-name arm in a folder; a text file beside them is skipped."""
    (tmp_path / "arms").mkdir()
    for name in ("acrobot.xml", "same_name.urdf"):
        (tmp_path / "arms" / name).write_text((FIXTURES / name).read_text())
    (tmp_path / "arms" / "notes.xml").write_text("<notes>not a model</notes>")
    code, out, err = run_cli(capsys, "model", "survey", tmp_path, "--jobs", "1", "--states", "5", "--quiet")
    lines = out.splitlines()
    assert code == 1 and err == ""
    assert lines[0].split() == ["model", "result", "engines", "reason"]
    assert lines[1].split()[:3] == [str(tmp_path / "arms" / "acrobot.xml"), "crashed", "dart"]
    assert "dart crashed (SIGSEGV) while loading" in lines[1]
    assert lines[2].split()[:3] == [str(tmp_path / "arms" / "same_name.urdf"), "agrees", "-"]
    assert lines[3] == "2 files: 1 agrees, 0 disagrees, 0 refused, 0 nothing to compare, 1 crashed, 0 failed"


def test_a_path_that_is_not_there_is_one_line_and_exit_2(capsys, tmp_path):
    code, out, err = run_cli(capsys, "model", "survey", tmp_path / "nowhere")
    assert (code, out) == (2, "")
    assert err == (f"xval: error: model survey: {tmp_path / 'nowhere'}: no such file or folder; give model files or "
                   f"folders holding them\n")


def test_the_survey_on_a_dask_cluster_gives_the_same_rows(capsys):
    """--scheduler local:1: a Dask worker checks each file (each engine still in a child of its own), and DART's
    segfault on the acrobot is its row there too."""
    models = [str(FIXTURES / "acrobot.xml"), str(FIXTURES / "same_name.urdf")]
    code, out, err = run_cli(capsys, "model", "survey", *models, "--scheduler", "local:1", "--states", "5",
                             "--format", "json", "--quiet")
    rows = json.loads(out)["files"]
    assert code == 1
    assert [(r["model"], r["outcome"], r["engines"]) for r in rows] == [
        (models[0], "crashed", ["dart"]), (models[1], "agrees", [])]


def test_pybullet_data_s_folders_are_reached_by_their_prefix():
    from compare.model.survey import find_models

    found = find_models(["pybullet_data:kuka_iiwa"])
    assert found and all(f.endswith(".urdf") and "/kuka_iiwa/" in f for f in found)
    assert any(f.endswith("/kuka_iiwa/model.urdf") for f in found)


def test_a_file_with_no_moving_joint_is_nothing_to_compare_not_refused():
    from compare.model.survey import survey_one

    path = str(Path(__file__).resolve().parent / "fixtures" / "urdf" / "no_joint.urdf")
    row = survey_one(path, states=3, seed=0, timeout=60)
    assert (row.outcome, row.moving_joints) == ("nothing to compare", 0)
    assert row.reason.endswith("no moving joint (revolute, continuous or prismatic); nothing to compare")
