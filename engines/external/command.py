"""``command/<label>``: an engine that is an outside program speaking the process protocol (docs/protocol.md).

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/external/command.py``.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import resource
import selectors
import shlex
import signal
import subprocess
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterator, Mapping

from engines.external import protocol
from engines.adapter import INITIAL_STATE_TOLERANCE, Engine, RawRun, Schedule
from engines.errors import UserError
from engines.scene.scene import Scene, SceneLike
from engines.scene.trajectory import Status, Trajectory

#: The engine name every command engine shares; its variant is the label (``command/my-bead``).
NAME = "command"
#: Capabilities a command may declare (docs/protocol.md).
KNOWN_CAPABILITIES = ("3d", "constraint-forces", "tolerance")
#: The exit code by which a program says "I cannot express this scene" (its last stderr line says why): the
#: case is ``skipped`` with that reason, as for a built-in engine's refusal. 77 is the "skip" of automake's
#: test harness.
UNSUPPORTED_EXIT_CODE = 77
#: Bytes of stderr kept (the tail), for the last line in messages.
STDERR_TAIL = 64 * 1024
#: s between checks for exit once stdout is closed.
_POLL = 0.002

#: (time.monotonic() at which to kill, the timeout in s) of the case running in this context, or None.
_deadline: contextvars.ContextVar[tuple[float, float] | None] = contextvars.ContextVar("xval_command_deadline",
                                                                                      default=None)


#: Process groups of programs running now (their leaders' pids): a case host that must die at once
#: (its worker died, compare/run/isolation.py) kills these too, since they left its own group.
LIVE_GROUPS: set[int] = set()


@contextlib.contextmanager
def deadline(seconds: float | None) -> Iterator[None]:
    """Within this context a command engine kills its program ``seconds`` s from now (None: no limit).

    The suite runner wraps each case in it with the case's timeout, so a
    command case times out by the engine killing its process group (nothing
    survives), before the runner would kill the case's host process.
    """
    token = _deadline.set(None if seconds is None else (time.monotonic() + float(seconds), float(seconds)))
    try:
        yield
    finally:
        _deadline.reset(token)


class CommandFailed(RuntimeError):
    """The program could not start, exited non-zero, or broke the protocol; the message says which and how."""


class CommandTimeout(RuntimeError):
    """The program ran past its deadline and its process group was killed."""


@dataclass(frozen=True)
class CommandSpec:
    """One outside program as an engine.

    label : the name results show (``command/<label>``).
    argv : the program and its arguments (no shell). A relative program path
        (one with a ``/``) is resolved against ``cwd``.
    cwd : the working directory it runs in (a suite file's folder), absolute.
    version : recorded with every case; a change makes the gate call its cases "not comparable".
    capabilities : ``"3d"``, ``"constraint-forces"``, ``"tolerance"`` (the program is error-controlled:
        on a suite's tolerance axis it gets ``options.tolerance`` and takes dt as its largest step).
    options : passed through to the program in the document's ``options``.
    """

    label: str
    argv: tuple[str, ...]
    cwd: str
    version: str = ""
    capabilities: frozenset[str] = frozenset()
    options: Mapping[str, Any] = field(default_factory=dict)

    @property
    def engine_id(self) -> str:
        return f"{NAME}/{self.label}"

    @property
    def display(self) -> str:
        """The command as one line a user could paste into a shell (for messages)."""
        return shlex.join(self.argv)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; :meth:`from_dict` inverts it (a case carries it to a worker on another machine)."""
        return {"label": self.label, "argv": list(self.argv), "cwd": self.cwd, "version": self.version,
                "capabilities": sorted(self.capabilities), "options": dict(self.options)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "CommandSpec":
        return cls(data["label"], tuple(data["argv"]), data["cwd"], data.get("version", ""),
                   frozenset(data.get("capabilities", ())), dict(data.get("options", {})))


class SpecError(UserError):
    """A malformed command spec; ``field`` is the key at fault and ``reason`` the message without the place."""

    def __init__(self, where: str, field_name: str, reason: str) -> None:
        super().__init__(f"{where}.{field_name}: {reason}")
        self.field, self.reason = field_name, reason


def make_spec(label: Any, argv: Any, cwd: str | os.PathLike | None = None, version: Any = None,
              capabilities: Any = (), options: Any = None, where: str = "command") -> CommandSpec:
    """A checked :class:`CommandSpec`; SpecError (a UserError) naming ``where``, the field and the fix.

    argv : a list of strings (a single string is split like a shell would, without running one).
    cwd : relative to the current directory when relative; default the current directory.
    """
    if not isinstance(label, str) or not label.strip() or "/" in label or ":" in label or label != label.strip():
        raise SpecError(where, "label", f"must be a non-empty name without '/', ':' or surrounding spaces "
                                        f"(results call it command/<label>), got {label!r}")
    if isinstance(argv, str):
        try:
            argv = shlex.split(argv)
        except ValueError as exc:
            raise SpecError(where, "command", f"cannot split {argv!r}: {exc}") from None
    if (not isinstance(argv, (list, tuple)) or not argv
            or not all(isinstance(a, str) for a in argv) or not argv[0]):
        raise SpecError(where, "command", f"must be a non-empty list of strings, e.g. "
                                          f"command = [\"python3\", \"solvers/bead.py\"], got {argv!r}")
    folder = Path(cwd if cwd is not None else os.getcwd()).resolve()
    program = argv[0]
    if "/" in program and not os.path.isabs(program):
        program = str(folder / program)
    if version is not None and (isinstance(version, bool) or not isinstance(version, (str, int, float))):
        raise SpecError(where, "version", f"must be a string such as \"1.2\", got {version!r}")
    if isinstance(capabilities, str):
        capabilities = [capabilities]
    if not isinstance(capabilities, (list, tuple, set, frozenset)):
        raise SpecError(where, "capabilities", f"must be a list, e.g. [\"3d\", \"constraint-forces\"], "
                                               f"got {capabilities!r}")
    for capability in capabilities:
        if capability not in KNOWN_CAPABILITIES:
            raise SpecError(where, "capabilities", f"unknown capability {capability!r}; use any of "
                                                   f"{', '.join(KNOWN_CAPABILITIES)}")
    if options is None:
        options = {}
    if not isinstance(options, Mapping):
        raise SpecError(where, "options", f"must be a table of name = value, got {options!r}")
    try:
        json.dumps(dict(options), allow_nan=False)
    except (TypeError, ValueError):
        raise SpecError(where, "options", f"must be JSON values (numbers, strings, booleans, lists, tables), "
                                          f"got {options!r}") from None
    return CommandSpec(label, (program, *argv[1:]), str(folder), "" if version is None else str(version),
                       frozenset(capabilities), dict(options))


class CommandEngine(Engine):
    """An outside program as an engine; see the module docstring."""

    name = NAME
    options = {}
    #: Nothing to warm up in xval's process: every run starts the program afresh (its start-up is
    #: outside the stepping time it reports, or inside the process time it is timed by).
    needs_warm_up = False

    def __init__(self, spec: CommandSpec) -> None:
        self.spec = spec
        self.capabilities = spec.capabilities  # type: ignore[misc]
        self.variants = {spec.label: {}}  # type: ignore[misc]
        self.variant_docs = {spec.label: spec.display}  # type: ignore[misc]
        self._outcome = threading.local()  # (status, message) that Engine.simulate cannot express itself

    def version(self) -> str:
        return self.spec.version or "unversioned"

    def program(self) -> tuple[list[str], str]:
        """(argv, version) of the program, as the spec gives them (the version may be empty)."""
        return list(self.spec.argv), self.spec.version

    #: The option a suite's tolerance axis sets (compare/suite/tolerance_axis.py), for a program that
    #: declares the capability "tolerance"; it reaches the program as ``options.tolerance``.
    tolerance_options = ("tolerance",)

    def tolerance_capable(self, settings: Mapping[str, Any]) -> bool:
        """Every run of a program that declares "tolerance" is error-controlled (it says so itself)."""
        return "tolerance" in self.capabilities

    def resolve(self, variant: str | None = None, options: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The spec's options with ``options`` on top, passed to the program untouched (it owns their meaning)."""
        variant = variant or self.spec.label
        if variant != self.spec.label:
            raise UserError(f"unknown variant {NAME}/{variant}; this command engine is {self.spec.engine_id}")
        settings = dict(self.spec.options)
        settings.update(options or {})
        return settings

    def _lacking(self, scene: SceneLike, missing: frozenset[str]) -> str:
        if "3d" in missing:
            return (f"{self.spec.engine_id} declares no '3d' capability and cannot express the 3-D scene "
                    f"{scene.name!r}; add \"3d\" to its capabilities if the program handles it")
        return super()._lacking(scene, missing)

    def simulate(self, scene: SceneLike, dt: float, *, variant: str | None = None,
                 options: Mapping[str, Any] | None = None, sample_interval: float | None = None) -> Trajectory:
        """:meth:`Engine.simulate`, with a program killed at its deadline reported as ``timeout`` and one that
        exits with :data:`UNSUPPORTED_EXIT_CODE` as ``skipped``."""
        self._outcome.value = None
        trajectory = super().simulate(scene, dt, variant=variant, options=options, sample_interval=sample_interval)
        outcome = getattr(self._outcome, "value", None)
        if outcome is not None:
            status, message = outcome
            trajectory = replace(trajectory, info=replace(trajectory.info, status=status, message=message))
        elif trajectory.info.message.startswith(f"{CommandFailed.__name__}: "):  # the message names the command
            message = trajectory.info.message.removeprefix(f"{CommandFailed.__name__}: ")
            trajectory = replace(trajectory, info=replace(trajectory.info, message=message))
        return trajectory

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        doc = protocol.document(scene, schedule.dt, schedule.n_steps, schedule.sample_steps, settings)
        try:
            payload = json.dumps(doc, allow_nan=False).encode()
        except ValueError:
            raise CommandFailed(f"{self.spec.engine_id}: an option is not finite; options must be JSON numbers") from None
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        try:
            result = run_program(self.spec, payload, _deadline.get())
        except CommandTimeout as exc:
            self._outcome.value = (Status.TIMEOUT, str(exc))
            raise
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        raw = self._parse(scene, schedule, result)
        # The program's own CPU time (user + system; it is reaped by now): this process's thread did none of
        # the stepping, so its thread time would say nothing of the program's cost.
        raw.cpu_time = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        raw.settings["cpu_time_source"] = "the program's process (user + system, startup included)"
        return raw

    def _parse(self, scene: Scene, schedule: Schedule, result: "ProgramResult") -> RawRun:
        where = f"{self.spec.engine_id}: stdout"
        label = self.spec.engine_id
        if result.returncode == UNSUPPORTED_EXIT_CODE:
            reason = result.last_stderr_line() or "it gave no reason on stderr"
            self._outcome.value = (Status.SKIPPED, f"{label} cannot express {scene.name!r}: {reason}")
            raise CommandFailed(reason)
        if result.returncode != 0:
            raise CommandFailed(f"{label}: {self.spec.display} {result.exit_description()}{result.stderr_suffix()}")
        try:
            table = protocol.read_csv(result.stdout, where)
            state = protocol.match_columns(table, scene, where)
            wall = table.wall_time()
        except protocol.ProtocolError as exc:
            raise CommandFailed(str(exc)) from None
        expected = len(schedule.sample_steps)
        first_bad = protocol.first_nonfinite_row(state.positions, state.velocities)
        n = table.n_rows
        if n > expected:
            raise CommandFailed(f"{where}: line {int(table.data_lines[expected])} (sample {expected}) is one row too "
                                f"many: the document asked for {expected} rows (one per sample_steps entry, "
                                f"step 0 included)")
        if n < expected and first_bad is None:
            last = f"the last at line {int(table.data_lines[-1])}" if n else "none"
            raise CommandFailed(f"{where}: {n} rows ({last}), expected {expected} (one per sample_steps entry, "
                                f"step 0 included); the program ended early{result.stderr_suffix()}")
        try:
            protocol.check_times(state.t, schedule.sample_steps, schedule.dt, table.data_lines, where, first_bad)
        except protocol.ProtocolError as exc:
            raise CommandFailed(str(exc)) from None
        if n:
            try:
                protocol.check_initial_state(scene, state.positions[0], state.velocities[0], where,
                                             int(table.data_lines[0]), "the first row must be the initial state, in "
                                             "the scene frame (metres, z up, particles in scene order)",
                                             INITIAL_STATE_TOLERANCE)
            except protocol.ProtocolError as exc:
                raise CommandFailed(str(exc)) from None
        if wall is not None and wall > 1.05 * result.elapsed + 1e-3:  # its clock is not ours: allow granularity
            raise CommandFailed(f"{where}: '# wall_time = {table.comments['wall_time']}' is longer than the program "
                                f"ran ({result.elapsed:.3g} s); write the stepping loop's time in seconds")
        if "constraint-forces" in self.capabilities and state.forces is None and scene.constraints:
            raise CommandFailed(f"{where}: no force columns, but {label} declares 'constraint-forces'; write "
                                f"f{{k}}_x,f{{k}}_y,f{{k}}_z for each constraint k, or drop the capability")
        settings: dict[str, Any] = {"command": self.spec.display, "cwd": self.spec.cwd}
        if wall is None:
            wall = result.elapsed
            settings["wall_time_source"] = "process (the program wrote no '# wall_time' line)"
        else:
            settings["wall_time_source"] = "program ('# wall_time')"
        if "version" in table.comments:
            settings["program_version"] = table.comments["version"]
        stop = n if first_bad is None else first_bad + 1
        steps = int(schedule.sample_steps[stop - 1]) if stop else 0
        forces = None if state.forces is None else state.forces[:stop]
        return RawRun(state.positions[:stop], state.velocities[:stop], forces, steps=steps, wall_time=wall,
                      settings=settings)


# -- running the program ------------------------------------------------------------


@dataclass(frozen=True)
class ProgramResult:
    """What a finished program left: returncode (negative: killed by that signal), stdout, stderr's tail, elapsed s."""

    returncode: int
    stdout: bytes
    stderr: bytes
    elapsed: float

    def last_stderr_line(self) -> str:
        lines = [line.strip() for line in self.stderr.decode("utf-8", "replace").splitlines() if line.strip()]
        return lines[-1] if lines else ""

    def stderr_suffix(self) -> str:
        line = self.last_stderr_line()
        return f"; last stderr line: {line}" if line else "; it wrote nothing to stderr"

    def exit_description(self) -> str:
        if self.returncode < 0:
            try:
                name = signal.Signals(-self.returncode).name
            except ValueError:
                name = str(-self.returncode)
            return f"was killed by signal {name} (exit code {self.returncode})"
        return f"exited with code {self.returncode}"


def run_program(spec: CommandSpec, payload: bytes, limit: tuple[float, float] | None) -> ProgramResult:
    """Run ``spec``'s program with ``payload`` on stdin until it exits; kill its whole group after.

    limit : (time.monotonic() value after which the group is killed, that
    timeout in s), or None for no limit; past it, CommandTimeout. Raises
    CommandFailed when the program cannot start.
    """
    deadline_at = None if limit is None else limit[0]
    started = time.perf_counter()
    try:
        process = subprocess.Popen(
            spec.argv, cwd=spec.cwd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            start_new_session=True, close_fds=True,
        )
    except FileNotFoundError:
        where = f"in {spec.cwd}" if "/" in spec.argv[0] else "on PATH"
        raise CommandFailed(f"{spec.engine_id}: cannot start {spec.display}: {spec.argv[0]!r} not found {where}") from None
    except PermissionError:
        raise CommandFailed(f"{spec.engine_id}: cannot start {spec.display}: {spec.argv[0]!r} is not executable "
                            f"(chmod +x it, or name its interpreter first)") from None
    except OSError as exc:
        raise CommandFailed(f"{spec.engine_id}: cannot start {spec.display}: {exc.strerror or exc}") from None
    LIVE_GROUPS.add(process.pid)
    try:
        stdout, stderr = _exchange(process, payload, deadline_at)
        timed_out = stdout is None
        if not timed_out:
            timed_out = not _wait_unreaped(process.pid, deadline_at)
    finally:
        # The group goes whatever happened (an exception, Ctrl-C, a timeout, or normal exit with
        # children left behind). The leader is not reaped yet, so its pid (= the group id) is not reused.
        _kill_group(process.pid)
        with contextlib.suppress(ProcessLookupError):
            process.kill()  # the leader too, should it have left its group (setsid)
        for stream in (process.stdin, process.stdout, process.stderr):
            with contextlib.suppress(OSError):
                stream.close()
        process.wait()
        _kill_stragglers(process.pid)
        LIVE_GROUPS.discard(process.pid)
    elapsed = time.perf_counter() - started
    if timed_out:
        seconds = limit[1] if limit is not None else elapsed
        raise CommandTimeout(f"{spec.engine_id}: {spec.display} ran past the timeout of {seconds:g} s and its "
                             f"process group was killed; raise the timeout if it is only slow")
    return ProgramResult(process.returncode, stdout, stderr, elapsed)


def _exchange(process: subprocess.Popen, payload: bytes, deadline_at: float | None) -> tuple[bytes | None, bytes]:
    """Write ``payload`` to stdin (then close it) while reading stdout and stderr to EOF.

    Returns (stdout, stderr tail), or (None, stderr tail) when the deadline passed first.
    """
    out, err = bytearray(), bytearray()
    view = memoryview(payload)
    with selectors.DefaultSelector() as selector:
        os.set_blocking(process.stdin.fileno(), False)
        if view:
            selector.register(process.stdin, selectors.EVENT_WRITE)
        else:
            process.stdin.close()
        selector.register(process.stdout, selectors.EVENT_READ)
        selector.register(process.stderr, selectors.EVENT_READ)
        while selector.get_map():
            timeout = None if deadline_at is None else deadline_at - time.monotonic()
            if timeout is not None and timeout <= 0:
                return None, bytes(err)
            for key, _ in selector.select(timeout):
                stream = key.fileobj
                if stream is process.stdin:
                    try:
                        written = os.write(stream.fileno(), view[:65536])  # type: ignore[union-attr]
                    except BlockingIOError:
                        continue
                    except (BrokenPipeError, OSError):
                        written = len(view)  # it stopped reading: fine, its output tells what it did
                    view = view[written:]
                    if not view:
                        selector.unregister(stream)
                        with contextlib.suppress(OSError):
                            stream.close()  # type: ignore[union-attr]
                    continue
                chunk = os.read(stream.fileno(), 1 << 20)  # type: ignore[union-attr]
                if not chunk:
                    selector.unregister(stream)
                    continue
                if stream is process.stdout:
                    out += chunk
                else:
                    err += chunk
                    if len(err) > 2 * STDERR_TAIL:
                        del err[:-STDERR_TAIL]
    return bytes(out), bytes(err[-STDERR_TAIL:])


def _wait_unreaped(pid: int, deadline_at: float | None) -> bool:
    """Wait for ``pid`` to exit without reaping it (so its group id stays ours); False when the deadline passed."""
    while True:
        try:
            info = os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT | os.WNOHANG)
        except ChildProcessError:
            return True
        if info is not None and info.si_pid == pid:
            return True
        if deadline_at is not None and time.monotonic() >= deadline_at:
            return False
        time.sleep(_POLL)


def _kill_group(pgid: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, signal.SIGKILL)


def _kill_stragglers(pgid: int, patience: float = 2.0) -> None:
    """After the leader is reaped: SIGKILL group ``pgid`` again until no live member is left.

    One killpg can miss a child that a member was forking at that instant (it joins the group after
    the signal), so the kill is repeated while /proc still lists a member that is not a zombie, for
    at most ``patience`` s. A group that is already empty costs one system call.
    """
    end = time.monotonic() + patience
    while True:
        try:
            os.killpg(pgid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            return
        if not _live_members(pgid) or time.monotonic() > end:
            return
        time.sleep(0.01)


def _live_members(pgid: int) -> bool:
    """Whether a process of group ``pgid`` is alive (not a zombie); True when /proc cannot tell."""
    try:
        entries = os.listdir("/proc")
    except OSError:
        return True
    for name in entries:
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as file:
                stat = file.read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # state, ppid, pgrp, ...
        if int(fields[2]) == pgid and fields[0] != "Z":
            return True
    return False


# -- the engines this process knows ---------------------------------------------------

_REGISTERED: dict[str, CommandEngine] = {}


def command_engine(label: Any, argv: Any, cwd: str | os.PathLike | None = None, version: Any = None,
                   capabilities: Any = (), options: Any = None, where: str = "command") -> CommandEngine:
    """A :class:`CommandEngine` for the program ``argv`` run in ``cwd``, registered under its label.

    SpecError (a UserError) naming the field when the spec is malformed.
    """
    return register(make_spec(label, argv, cwd, version, capabilities, options, where))


def register(spec: CommandSpec) -> CommandEngine:
    """Register ``spec`` by its label and return its engine (the same spec again: the engine made before).

    A different spec under a label already registered replaces it (the
    latest suite read in this process wins; a suite itself refuses a label
    used twice).
    """
    known = _REGISTERED.get(spec.label)
    if known is not None and known.spec == spec:
        return known
    engine = CommandEngine(spec)
    _REGISTERED[spec.label] = engine
    return engine


def unregister(label: str) -> None:
    """Forget ``label`` (tests, and a CLI that runs one command and is done)."""
    _REGISTERED.pop(label, None)


def registered(label: str) -> CommandEngine:
    """The engine registered as ``label``; UserError saying how to declare one when none is."""
    try:
        return _REGISTERED[label]
    except KeyError:
        known = ", ".join(f"{NAME}/{name}" for name in sorted(_REGISTERED)) or "none"
        raise UserError(f"no command engine labelled {label!r} here (known: {known}); declare it in the suite as "
                        f"[[engines]] command = [\"prog\", \"args\"], label = \"{label}\"") from None


def registered_labels() -> list[str]:
    return sorted(_REGISTERED)


def spec_of(engine: Any) -> dict[str, Any] | None:
    """The JSON-ready spec of a command engine (for a case sent to another process), or None for any other engine."""
    return engine.spec.to_dict() if isinstance(engine, CommandEngine) else None


def adopt(spec: Mapping[str, Any]) -> CommandEngine:
    """Register (here, in a worker) the spec a case carried, and return its engine."""
    return register(CommandSpec.from_dict(spec))
