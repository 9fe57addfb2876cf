"""Running the xval CLI in-process from a test."""

from __future__ import annotations

from typing import Any

import pytest

from compare.cli import main


def run_cli(capsys: pytest.CaptureFixture, *argv: Any) -> tuple[int, str, str]:
    """Run ``xval ARGV...`` in this process: (exit code, stdout, stderr)."""
    try:
        main([str(a) for a in argv])
        code = 0
    except SystemExit as stop:
        code = stop.code or 0
    out, err = capsys.readouterr()
    return code, out, err
