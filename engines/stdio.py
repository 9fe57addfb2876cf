"""Keeping what an engine's C library prints (PyBullet, DART) out of xval's output: fds 1 and 2 silenced,
or, in a child process that keeps what its engine printed (:func:`capture_into`), sent to a file."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import threading
from typing import Iterator

_LIBC = ctypes.CDLL(None)
_quiet_lock = threading.Lock()
_quiet_depth = 0
_saved_fds: dict[int, int] = {}
#: Where :func:`quiet_output` points fds 1 and 2: /dev/null, or the file of :func:`capture_into`.
_sink = os.devnull


def _flush_all() -> None:
    """Flush Python's streams and C's stdio (fflush(NULL)) so text goes where fd 1 and 2 point now."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    _LIBC.fflush(None)


@contextlib.contextmanager
def quiet_output() -> Iterator[None]:
    """Point file descriptors 1 and 2 at /dev/null for the duration; nested and concurrent uses share one redirection.

    PyBullet writes to both (``pybullet build time`` to stderr on import,
    ``switched solver`` to stdout), DART to stdout. Everything already written
    through Python or C stdio is flushed on entry, so the caller's pending text
    reaches the real streams first; C's stdio is flushed again before the
    descriptors are restored, so the library's buffered text goes to /dev/null
    rather than out later. A descriptor that is not open is left alone.
    """
    global _quiet_depth
    with _quiet_lock:
        if _quiet_depth == 0:
            _flush_all()
            devnull = os.open(_sink, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
            try:
                for fd in (1, 2):
                    try:
                        _saved_fds[fd] = os.dup(fd)
                    except OSError:
                        continue
                    os.dup2(devnull, fd)
            finally:
                os.close(devnull)
        _quiet_depth += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if _quiet_depth == 0:
                _flush_all()
                for fd, saved in _saved_fds.items():
                    os.dup2(saved, fd)
                    os.close(saved)
                _saved_fds.clear()


def capture_into(path: str) -> None:
    """Point fds 1 and 2 at the file ``path`` (appended to) for the rest of this process, and make
    :func:`quiet_output` send there too: a child process that runs one engine keeps all it printed."""
    global _sink
    _flush_all()
    _sink = path
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
    try:
        for target in (1, 2):
            os.dup2(fd, target)
    finally:
        os.close(fd)


def flush_all() -> None:
    """Flush Python's streams and C's stdio, so what was printed reaches the file descriptors now."""
    _flush_all()
