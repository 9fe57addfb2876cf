"""Keeping what an engine's C library prints (PyBullet, DART, MuJoCo) out of xval's output: fds 1 and 2
silenced (:func:`quiet_output`); or, in a child process that keeps what its engine printed
(:func:`capture_into`), sent to a file; or captured and summarised for a case's record (:func:`capture_output`),
in a case host into a file its driver holds too (:func:`output_file`), read back if the host dies mid-case."""

from __future__ import annotations

import contextlib
import ctypes
import io
import os
import re
import sys
import tempfile
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any, BinaryIO, Iterator

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


def _redirect(target: int) -> None:
    """Point fds 1 and 2 at the descriptor ``target``, each saved first (one that is not open is left alone).
    Called under _quiet_lock by the outermost redirection only."""
    for fd in (1, 2):
        try:
            _saved_fds[fd] = os.dup(fd)
        except OSError:
            continue
        os.dup2(target, fd)


def _restore() -> None:
    """Flush what was printed into the redirection, then give fds 1 and 2 back what :func:`_redirect` saved."""
    _flush_all()
    for fd, saved in _saved_fds.items():
        os.dup2(saved, fd)
        os.close(saved)
    _saved_fds.clear()


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
                _redirect(devnull)
            finally:
                os.close(devnull)
        _quiet_depth += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if _quiet_depth == 0:
                _restore()


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


#: Lines an EngineOutput keeps from the start and from the end of what was printed.
KEPT_LINES = 5
#: Characters kept of each kept line (DART's lines are ~150; a binary dump would be unbounded).
LINE_CHARS = 300


@dataclass(frozen=True)
class EngineOutput:
    """What an engine's library printed during one case: the line count, its first and last lines.

    lines : how many lines (a last line without a newline counts). first : the first KEPT_LINES; last : the
    last KEPT_LINES after those (no line is in both), each cut to LINE_CHARS characters, read as UTF-8.
    """

    lines: int = 0
    first: tuple[str, ...] = ()
    last: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return self.lines > 0

    def to_dict(self) -> dict[str, Any]:
        return {"lines": self.lines, "first": list(self.first), "last": list(self.last)}

    @classmethod
    def of(cls, data: Any) -> "EngineOutput":
        """From :meth:`to_dict`'s document (a record's ``engine_output``); an empty one for anything else."""
        if not isinstance(data, dict) or not isinstance(data.get("lines"), int):
            return cls()
        return cls(data["lines"], tuple(str(s) for s in data.get("first") or ()),
                   tuple(str(s) for s in data.get("last") or ()))

    def describe(self) -> list[str]:
        """The kept lines for a person: first, ``… N more lines …``, last."""
        skipped = self.lines - len(self.first) - len(self.last)
        gap = [f"… {skipped} more line{'s' if skipped != 1 else ''} …"] if skipped > 0 else []
        return [*self.first, *gap, *self.last]


#: A terminal's colour and cursor codes (DART colours its warnings): not kept.
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _summary(file: BinaryIO) -> EngineOutput:
    """The EngineOutput of the text in ``file`` (read from its start, line by line: never held whole)."""
    file.seek(0)
    count = 0
    first: list[str] = []
    last: deque[str] = deque(maxlen=KEPT_LINES)
    for raw in file:
        line = _ANSI.sub("", raw[:4 * LINE_CHARS].decode("utf-8", "replace")).rstrip("\r\n")[:LINE_CHARS]
        count += 1
        if len(first) < KEPT_LINES:
            first.append(line)
        else:
            last.append(line)
    return EngineOutput(count, tuple(first), tuple(last))


class Captured:
    """What :func:`capture_output` yields: ``output`` is filled in when the block ends."""

    output: EngineOutput = EngineOutput()


def output_file() -> BinaryIO:
    """A file without a name for :func:`capture_output` to write into (removed when its last holder closes it).

    A case host's driver makes one before it forks the host: the host captures each case into it, and when
    the host dies mid-case (a segfault, a timeout's kill) the driver reads what the case printed from it
    (:func:`left_in`). Having no name, it outlives no process that holds it, even a ``kill -9``'d one.
    """
    return tempfile.TemporaryFile()


def left_in(file: BinaryIO) -> EngineOutput:
    """The EngineOutput of what ``file`` holds (:func:`output_file`; what a capture into it kept when its process
    died before the capture ended); empty when it holds nothing."""
    if os.fstat(file.fileno()).st_size == 0:
        return EngineOutput()
    return _summary(file)


def _empty(file: BinaryIO) -> None:
    """Truncate ``file`` and put its (shared) offset at 0, so fds 1 and 2, dup'ed from it, write from its start."""
    file.seek(0)
    file.truncate()


def line_buffered() -> None:
    """Flush C's stdout at every line, and Python's sys.stdout and sys.stderr: a process that dies (a segfault,
    a timeout's SIGKILL) then loses at most a part line, not a buffer of what it printed. For a case host, whose
    fds 1 and 2 go to a file (a file is fully buffered by default). A Python stream that is not on its fd (a
    test runner's capture, inherited through the fork) is replaced by one that is, so what the host prints
    reaches the file. glibc keeps line buffering whatever stdout points at; elsewhere this may do nothing."""
    for fd, name in ((1, "stdout"), (2, "stderr")):
        stream = getattr(sys, name)
        try:
            stream.flush()
            if stream.fileno() == fd:
                stream.reconfigure(line_buffering=True)
                continue
        except Exception:  # no fileno (an in-memory capture), or a stream that cannot reconfigure
            pass
        setattr(sys, name, io.TextIOWrapper(io.FileIO(fd, "w", closefd=False), line_buffering=True,
                                            errors="backslashreplace"))
    with contextlib.suppress(ValueError, AttributeError, OSError):
        stdout = ctypes.c_void_p.in_dll(_LIBC, "stdout")
        _LIBC.setvbuf(stdout, None, 1, 0)  # _IOLBF, the buffer C already has (glibc: only a flag)


@contextlib.contextmanager
def capture_output(into: BinaryIO | None = None) -> Iterator[Captured]:
    """Send file descriptors 1 and 2 to a file for the duration, and summarise what reached it.

    Catches what C and C++ libraries write (DART's per-step warnings, MuJoCo's, PyBullet's) and what Python
    writes to sys.stdout / sys.stderr meanwhile (a warning an engine lets through is printed there). Inside
    a capture already active in this process (another thread's case, not isolated), the inner one keeps
    nothing: the text goes to the outer capture; so does the text of a :func:`quiet_output` block inside one.

    into : the file to write to (:func:`output_file`), emptied at the start and again once summarised, so it
        holds only what the block in progress printed; None: a temporary file of its own.
    """
    global _quiet_depth
    captured = Captured()
    with _quiet_lock:
        outer = _quiet_depth > 0
        _quiet_depth += 1
        if not outer:
            _flush_all()
            file = tempfile.TemporaryFile() if into is None else into
            _empty(file)
            _redirect(file.fileno())
    try:
        yield captured
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if not outer:
                _restore()
                try:
                    captured.output = _summary(file)
                finally:
                    if into is None:
                        file.close()
                    else:
                        _empty(file)  # what the host holds between cases: nothing (see output_file)
