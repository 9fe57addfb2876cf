"""Stand-in model importers for the isolation tests of ``xval model check``: each really does to its own
process what an engine library might (a segmentation fault, an abort, a hang, C-level prints), so the test
sees the harness survive it. They stand in for no engine's results: a row of theirs is never compared."""

from __future__ import annotations

import ctypes
import os
import time

from engines.adapter import ModelImport
from engines.model import pinocchio


def version() -> str:
    return "0-stand-in"


def segfault(source, description, **options):
    """Reads address 0: the kernel sends SIGSEGV (faulthandler, when on, prints and re-raises it)."""
    ctypes.string_at(0)


def abort(source, description, **options):
    os.abort()


def hang(source, description, **options):
    time.sleep(3600)


def printing(source, description, **options):
    """Writes on file descriptors 1 and 2 as a C library does (and through C's stdio), then loads the file with
    Pinocchio's importer, so the row agrees and only the prints are under test."""
    os.write(1, b"b3Warning[examples/Importers/ImportMJCFDemo/BulletMJCFImporter.cpp,1220]: stand-in on fd 1\n")
    os.write(2, b"stand-in on fd 2\n")
    libc = ctypes.CDLL(None)
    libc.printf(b"stand-in through printf\n")
    with open("MUJOCO_LOG.TXT", "w") as log:  # as MuJoCo does, in the working directory
        log.write("stand-in log\n")
    return pinocchio.load(source, description)


def stand_in(load) -> ModelImport:
    """The model import (engines.adapter.ModelImport) of one of the functions above."""
    return ModelImport(version, load)
