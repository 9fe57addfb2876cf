"""Every command in README.md runs as written, in order, in a fresh clone of the repository.

README's commands are the lines of its ```sh blocks (a trailing backslash continues a line; a comment
``# exit N`` on a command's line is the exit code it documents, else 0). README may hold no other code
block a reader could run: no indented code blocks and no fence language but sh, toml (a suite: parsed
and its engines resolved) and yaml (a CI workflow: each of its xval commands must be one of the sh
commands, so it runs here too). So a command cannot be added to README without this test running it.

The clone is ``git clone`` of this checkout plus its uncommitted changes to tracked files (what a commit
of the tree would hold; untracked files are left out, as a fresh clone leaves them out). It does not
install anything: its ``.venv`` is a symlink to the environment running the tests (make's .venv, which
has every engine), and PYTHONPATH puts the clone's own code before that environment's editable install.

Not run here: the set-up commands README opens with, which .ci/run runs on every CI build
(test_the_set_up_commands_left_out_here_are_run_by_ci checks that): ``make test`` (this test suite)
and ``make demo`` (suites/default.toml, 1155 cases since the mechanisms joined it: minutes on 2 cores).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from compare.suite.reader import parse_suite

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: Set-up commands left out, and where CI runs them.
SET_UP = {"make demo": ".ci/run", "make test": ".ci/run"}
#: Fence languages README may use; a new one must be handled here first.
LANGUAGES = {"sh", "toml", "yaml"}
#: Seconds for all the commands together (about 3 minutes on a quiet 2-core machine).
BUDGET = 1500

_FENCE = re.compile(r"^(\s*)```(\S*)\s*$")
_EXIT = re.compile(r"#\s*exit (\d+)\b")


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order; the body dedented by its fence's indent."""
    found, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        opening = _FENCE.match(lines[i])
        if not opening:
            i += 1
            continue
        indent, language, body = len(opening.group(1)), opening.group(2), []
        i += 1
        while not _FENCE.match(lines[i]):
            body.append(lines[i][indent:])
            i += 1
        found.append((language, "\n".join(body)))
        i += 1
    return found


def commands(text: str) -> list[str]:
    """The commands of README's sh blocks, in order (continued lines joined, comment lines dropped)."""
    found = []
    for language, body in blocks(text):
        if language != "sh":
            continue
        pending = ""
        for line in body.splitlines():
            if not pending and (not line.strip() or line.lstrip().startswith("#")):
                continue
            pending += line + "\n"
            if not line.rstrip().endswith("\\"):
                found.append(pending.rstrip("\n"))
                pending = ""
    return found


def expected_exit(command: str) -> int:
    documented = _EXIT.search(command)
    return int(documented.group(1)) if documented else 0


def words(command: str) -> str:
    """A command compared as a reader sees it: no comment, no continuation, no `.venv/bin/`, one space."""
    command = re.sub(r"\s+#[^\n]*", "", command).replace("\\\n", " ").replace(".venv/bin/", "")
    return " ".join(command.split())


def test_readme_runs_no_command_outside_its_sh_blocks():
    text = README.read_text(encoding="utf-8")
    outside, fenced = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if _FENCE.match(line):
            fenced = not fenced
        elif not fenced and (line.startswith("    ") or line.startswith("\t")):
            outside.append(f"README.md:{number}: {line.strip()}")
    assert not outside, "indented code blocks are not run by tests/test_readme.py; fence them as ```sh:\n" + "\n".join(outside)
    languages = {language for language, _ in blocks(text)}
    assert languages <= LANGUAGES, f"README code blocks in {sorted(languages - LANGUAGES)}: make them sh, or check them here"


def test_readme_suites_parse_and_its_workflow_runs_readme_commands():
    text = README.read_text(encoding="utf-8")
    sh = {words(c) for c in commands(text)}
    suites = [body for language, body in blocks(text) if language == "toml"]
    workflows = [yaml.safe_load(body) for language, body in blocks(text) if language == "yaml"]
    assert suites and workflows
    for body in suites:
        parse_suite(body, "README.md")  # a UserError names the key; engines are resolved too
    runs = [step["run"] for w in workflows for job in w["jobs"].values() for step in job["steps"] if "run" in step]
    xval_runs = [words(run) for run in runs if run.lstrip().startswith("xval ")]
    assert xval_runs and all(run in sh for run in xval_runs), (xval_runs, sorted(sh))


def test_the_set_up_commands_left_out_here_are_run_by_ci():
    text = README.read_text(encoding="utf-8")
    assert [words(c) for c in commands(text)][: len(SET_UP)] == list(SET_UP)  # README opens with them
    for command, where in SET_UP.items():
        assert command in (ROOT / where).read_text(encoding="utf-8").splitlines(), f"{where} must run {command}"


def clone(tmp_path: Path) -> Path:
    """A fresh clone of this checkout with its uncommitted changes to tracked files."""
    if not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout of xval (README's commands run in a fresh clone of it)")
    target = tmp_path / "xval"
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(target)], check=True, timeout=120)
    diff = subprocess.run(["git", "-C", str(ROOT), "diff", "--binary", "HEAD"], check=True, capture_output=True,
                          timeout=60).stdout
    if diff:
        subprocess.run(["git", "-C", str(target), "apply", "--whitespace=nowarn", "-"], input=diff, check=True, timeout=60)
    return target


def environment(target: Path) -> dict[str, str]:
    """The test's own venv as the clone's .venv, its code first on the path, README's defaults in force."""
    venv = Path(sys.prefix)
    if venv == Path(sys.base_prefix) or not (venv / "bin" / "xval").exists():
        pytest.skip("runs from make's .venv (README's commands name .venv/bin/xval)")
    (target / ".venv").symlink_to(venv, target_is_directory=True)
    stamp = venv / ".installed-stamp"
    if stamp.exists():  # so a `make` target finds the environment installed and does not reinstall it
        old = stamp.stat().st_mtime - 1
        for name in ("requirements.lock", "pyproject.toml", "examples/my-solver/pyproject.toml"):
            os.utime(target / name, (old, old))
    env = {k: v for k, v in os.environ.items() if k not in ("XVAL_HISTORY", "PYTHONPATH")}
    env["PYTHONPATH"] = os.pathsep.join([str(target), str(target / "examples" / "my-solver")])
    env["PATH"] = os.pathsep.join([str(target / ".venv" / "bin"), env.get("PATH", "")])
    return env


def script(steps: list[str], log: Path) -> str:
    """One bash script: each command, then its exit code checked (so README's & and %1 jobs work)."""
    lines = []
    for number, command in enumerate(steps):
        lines += [command, f"s=$?; echo \"{number} $s $EPOCHREALTIME\" >> {log}",
                  f"[ \"$s\" = {expected_exit(command)} ] || exit 100"]
    return "\n".join(lines) + "\n"


@pytest.mark.timeout(BUDGET + 120)
def test_every_readme_command_runs_as_written_in_a_fresh_clone(tmp_path):
    steps = [c for c in commands(README.read_text(encoding="utf-8")) if words(c) not in SET_UP]
    target = clone(tmp_path)
    env = environment(target)
    where = subprocess.run([str(target / ".venv/bin/python"), "-c", "import compare; print(compare.__file__)"],
                           cwd=target, env=env, capture_output=True, text=True, check=True, timeout=60).stdout
    assert Path(where.strip()).is_relative_to(target), where  # the clone's code, not the checkout's
    log, out, err = tmp_path / "log", tmp_path / "stdout", tmp_path / "stderr"
    with out.open("w") as stdout, err.open("w") as stderr:
        # Its own process group: README starts a Dask scheduler and workers in the background, and
        # whatever outlives the script (a command that failed before README's `kill`) goes with the group.
        shell = subprocess.Popen(["bash", "-c", script(steps, log)], cwd=target, env=env, stdout=stdout,
                                 stderr=stderr, stdin=subprocess.DEVNULL, start_new_session=True)
        try:
            code = shell.wait(timeout=BUDGET)
        except subprocess.TimeoutExpired:
            code = None
        finally:
            try:
                os.killpg(shell.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            shell.wait()
    done = [line.split() for line in log.read_text().splitlines()] if log.exists() else []
    if code != 0:
        failed = steps[len(done) - 1] if code == 100 else steps[len(done)] if len(done) < len(steps) else "(after all)"
        status = f"exited {done[-1][1]}" if code == 100 else f"did not finish in {BUDGET} s" if code is None else f"bash {code}"
        pytest.fail(f"README command {status}:\n{failed}\n--- stderr (end):\n{err.read_text()[-3000:]}")
    assert len(done) == len(steps)
    shutil.rmtree(target, ignore_errors=True)
