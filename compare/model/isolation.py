"""One part of a model check (reading the file, the reference, one engine) in a child process of its own.

Engine libraries can crash (DART's MJCF parser segfaults on a two-link
acrobot), abort, hang, print on the C-level stdout, or leave files in the
working directory (MuJoCo's MUJOCO_LOG.TXT). :func:`run` forks a child that
leads a process group of its own and dies with its parent, works in a
temporary directory (removed afterwards, with whatever was left in it) and
has its file descriptors 1 and 2 pointed at a file there: what the engine
printed comes back as lines, never on xval's stdout. The child tells the
parent what it is doing (:func:`report`: ``stage`` "loading",
"evaluating", the engine's ``version``), then sends the function's value or
the exception it raised. A signal, an exit without an answer or no answer
within ``timeout`` s (the group is then killed) is the outcome's ``failure``.
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import pickle
import re
import select
import shutil
import signal
import struct
import tempfile
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from compare.run.isolation import die_with_parent
from engines import stdio

#: s a child may take before it is killed (``--timeout``).
DEFAULT_TIMEOUT = 60.0
#: Lines of printed output kept per child (the rest are counted).
KEPT_LINES = 20
_HEADER = struct.Struct("!Q")
#: Terminal colour and cursor sequences (DART colours its errors): dropped from the printed lines.
_ESCAPE = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")
#: The pipe to the parent, in a child that :func:`run` started; None elsewhere.
_channel: int | None = None


@dataclass(frozen=True)
class Outcome:
    """What came back from a child.

    value : the function's return value (None when it raised or failed). error : the exception it raised.
    failure : "" when the child answered, else "crashed (SIGSEGV)", "timed out after 60 s", "exited with
    code 3 without an answer". reported : what the child said with :func:`report` (its last ``stage``).
    printed : the distinct lines it wrote on fds 1 and 2 (at most KEPT_LINES, then a count of the rest).
    """

    value: Any = None
    error: BaseException | None = None
    failure: str = ""
    reported: dict[str, str] = field(default_factory=dict)
    printed: tuple[str, ...] = ()

    @property
    def stage(self) -> str:
        return self.reported.get("stage", "")


def report(key: str, value: str) -> None:
    """In a child of :func:`run`, tell the parent ``key`` = ``value`` (the last one of a key counts); else nothing."""
    if _channel is not None:
        _send(_channel, ("report", key, value))


def run(fn: Callable[..., Any], *args: Any, timeout: float = DEFAULT_TIMEOUT,
        prepare: Callable[[], Any] | None = None) -> Outcome:
    """``fn(*args)`` in a forked child (the arguments are inherited, not pickled; the answer is pickled).
    prepare : called first, its prints dropped (importing an engine's library: its banner is not about the file);
    what it raises is ignored (``fn`` meets it again and answers for it)."""
    workdir = tempfile.mkdtemp(prefix="xval-model-")
    printed_path = os.path.join(workdir, ".printed")
    read_end, write_end = os.pipe()
    stdio.flush_all()  # nothing buffered here may be written twice, by the child too
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child: measured through its answers
        os.close(read_end)
        _child(fn, args, workdir, printed_path, write_end, prepare)
    os.close(write_end)
    try:
        os.setpgid(pid, pid)  # also done by the child: whichever runs first
    except OSError:
        pass
    try:
        return _wait(pid, read_end, timeout, printed_path)
    except BaseException:  # Ctrl-C or SIGTERM while waiting: the child goes with us
        _kill(pid)
        with contextlib.suppress(ChildProcessError):  # already reaped
            _reap(pid, kill_after=0.0)
        raise
    finally:
        os.close(read_end)
        shutil.rmtree(workdir, ignore_errors=True)


def _child(fn: Callable[..., Any], args: tuple, workdir: str, printed_path: str, channel: int,
           prepare: Callable[[], Any] | None) -> None:
    global _channel
    code = 0
    try:
        os.setpgid(0, 0)
        die_with_parent()
        os.chdir(workdir)
        if prepare is not None:
            with stdio.quiet_output(), contextlib.suppress(Exception):
                prepare()
        stdio.capture_into(printed_path)
        if faulthandler.is_enabled():  # its dump goes where it was pointed (pytest: a copy of stderr): here instead
            faulthandler.enable(file=2)
        _channel = channel
        try:
            message: tuple = ("value", fn(*args))
        except BaseException as exc:  # noqa: BLE001 - every exception is the answer
            message = ("error", exc)
        try:
            _send(channel, message)
        except Exception as exc:  # an answer that does not pickle still answers
            _send(channel, ("error", RuntimeError(f"{type(exc).__name__}: {exc}")))
        stdio.flush_all()
    except BaseException:  # noqa: BLE001 - the child must never return into the parent's code
        code = 70
    finally:
        os._exit(code)


def _send(fd: int, message: tuple) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def _wait(pid: int, fd: int, timeout: float, printed_path: str) -> Outcome:
    deadline = time.monotonic() + timeout
    buffer, reported = b"", {}
    answer: tuple | None = None
    timed_out = False
    while answer is None:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            timed_out = True
            break
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            break  # the child closed its end: it answered or died
        buffer += chunk
        while len(buffer) >= _HEADER.size:
            (size,) = _HEADER.unpack_from(buffer)
            if len(buffer) < _HEADER.size + size:
                break
            message = pickle.loads(buffer[_HEADER.size:_HEADER.size + size])
            buffer = buffer[_HEADER.size + size:]
            if message[0] == "report":
                reported[message[1]] = message[2]
            else:
                answer = message
    if timed_out:
        _kill(pid)
    status = _reap(pid, kill_after=5.0)
    printed = _printed(printed_path)
    if answer is not None:
        kind, payload = answer
        return Outcome(payload if kind == "value" else None, payload if kind == "error" else None,
                       reported=reported, printed=printed)
    if timed_out:
        failure = f"timed out after {timeout:g} s"
    elif os.WIFSIGNALED(status):
        failure = f"crashed ({_signal_name(os.WTERMSIG(status))})"
    else:
        failure = f"exited with code {os.WEXITSTATUS(status)} without an answer"
    return Outcome(failure=failure, reported=reported, printed=printed)


def _kill(pid: int) -> None:
    for kill in (lambda: os.killpg(pid, signal.SIGKILL), lambda: os.kill(pid, signal.SIGKILL)):
        try:
            kill()
            return
        except OSError:
            continue


def _reap(pid: int, kill_after: float) -> int:
    """The child's wait status; a child that lingers after closing its pipe is killed after ``kill_after`` s."""
    deadline = time.monotonic() + kill_after
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return status
        if time.monotonic() > deadline:
            _kill(pid)
            return os.waitpid(pid, 0)[1]
        time.sleep(0.002)


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _printed(path: str) -> tuple[str, ...]:
    try:
        with open(path, "rb") as stream:
            text = stream.read().decode("utf-8", "replace")
    except OSError:
        return ()
    seen: dict[str, int] = {}
    for line in text.splitlines():
        line = " ".join(_ESCAPE.sub("", line).split())
        if line:
            seen[line] = seen.get(line, 0) + 1
    lines = [line if count == 1 else f"{line} ({count} times)" for line, count in seen.items()]
    if len(lines) <= KEPT_LINES:
        return tuple(lines)
    return (*lines[:KEPT_LINES], f"… and {len(lines) - KEPT_LINES} more lines")
