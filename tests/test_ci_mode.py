"""CI mode (tests/ci_mode.py): a missing requirement fails the run in one line; a skip fails the test."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

SKIPPING = "import pytest\n\ndef test_needs_something():\n    pytest.skip('no such thing here')\n"


def pytest_in(tmp_path: Path, **env: str) -> subprocess.CompletedProcess:
    """pytest with the CI-mode plug-in on one test file that skips, in a fresh process (60 s: it runs one test)."""
    (tmp_path / "test_skips.py").write_text(SKIPPING)
    environment = {k: v for k, v in os.environ.items() if k not in ("XVAL_CI", "XVAL_CHROMIUM")}
    environment.update(PYTHONPATH=str(HERE), **env)
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "ci_mode", "-q", "-rs", "-p", "no:cacheprovider",
                           "test_skips.py"], cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=60)


def test_without_chromium_ci_mode_fails_at_once_in_one_line(tmp_path):
    # XVAL_CHROMIUM="" stands for a machine without chromium (nothing is uninstalled).
    done = pytest_in(tmp_path, XVAL_CI="1", XVAL_CHROMIUM="")
    assert done.returncode == 3, done.stdout + done.stderr
    assert done.stdout == ""  # no test ran, nothing else was said
    [line] = done.stderr.splitlines()
    assert line.startswith("XVAL_CI=1: missing ") and "chromium (apt-get install chromium; .ci/run does)" in line


def test_in_ci_mode_a_skip_is_a_failure_with_its_reason(tmp_path):
    # Every other requirement is present wherever this suite runs in CI mode (.ci/run installs them);
    # /bin/true stands for chromium, which this test does not start.
    done = pytest_in(tmp_path, XVAL_CI="1", XVAL_CHROMIUM="/bin/true")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "skipped in CI mode (XVAL_CI=1), which allows no skip: Skipped: no such thing here" in done.stdout
    assert "1 failed" in done.stdout


def test_outside_ci_mode_a_skip_is_printed_with_its_reason(tmp_path):
    done = pytest_in(tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "SKIPPED [1] test_skips.py:4: no such thing here" in done.stdout and "1 skipped" in done.stdout
