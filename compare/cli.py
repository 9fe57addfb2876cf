"""The ``xval`` command line: a click group whose verbs live one per module in ``compare/commands``.

Layers above ``compare`` (``reports``) and third-party packages add verbs
through the ``xval.commands`` entry-point group, so nothing here imports
upward. ``main`` turns every UserError (and click's usage errors) into one
line on stderr and exit code 2, with no traceback.
"""

from __future__ import annotations

import errno
import gc
import importlib
import math
import re
import signal
import sys
from importlib.metadata import entry_points
from typing import Any, NoReturn

import click

from compare.text import InertStream, inert
from engines.errors import UserError

#: Built-in verbs: name -> the module defining a click command ``command`` of that name.
COMMAND_MODULES = {
    name: f"compare.commands.{name}"
    for name in ("scenes", "engines", "simulate", "score", "run", "show", "verdict", "baseline", "gate", "stability",
                 "history", "probe", "model", "grad")
}


class XvalGroup(click.Group):
    """Imports only the verb being run (``xval show`` never imports the runner, engines or reports);
    listing the verbs needs no import, ``xval --help`` imports each for its one-line help."""

    def _plugins(self) -> dict[str, Any]:
        found: dict[str, Any] = {}
        for entry in entry_points(group="xval.commands"):
            found.setdefault(entry.name, entry)
        return found

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*COMMAND_MODULES, *self._plugins()})

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in COMMAND_MODULES:  # a built-in name wins over a plug-in's
            return importlib.import_module(COMMAND_MODULES[name]).command
        entry = self._plugins().get(name)
        return None if entry is None else entry.load()


@click.group(cls=XvalGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="xval")
def cli() -> None:
    """Cross-validate constrained-dynamics solvers against MuJoCo, PyBullet, pymunk and a reference."""


def fail(message: str) -> NoReturn:
    """Print one error line (control characters in it made visible, see compare/text.py) and exit 2."""
    click.echo(f"xval: error: {inert(message)}", err=True)
    sys.exit(2)


#: OSError numbers that mean "no room to write": a run stopped by one keeps its finished cases (exit 1).
NO_SPACE = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread so a run stops as it does on Ctrl-C (workers killed, temporaries removed)."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated()


def os_error_line(exc: OSError) -> tuple[str, int]:
    """One line naming the file and the problem, and the exit code: 1 for a full disk, 2 otherwise."""
    where = f"{exc.filename}: " if exc.filename else ""
    reason = exc.strerror or str(exc)
    if exc.errno in NO_SPACE:
        return (f"{where}{reason}: no room to write; cases already finished are kept: free space, then run "
                f"the same command with --resume (xval run) or again", 1)
    if exc.errno == errno.ENAMETOOLONG:
        return f"{where}{reason}; choose a shorter path or name", 2
    return f"{where}{reason}", 2


def main(argv: list[str] | None = None) -> None:
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread (an embedding program): leave SIGTERM alone
        previous = None
    stdout = sys.stdout
    sys.stdout = InertStream(stdout)  # labels from files print as text, never as terminal commands
    try:
        _main(argv)
    finally:
        sys.stdout = stdout
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def console(argv: list[str] | None = None) -> None:
    """The ``xval`` program: :func:`main`, then nothing left for the interpreter's last collection to walk.

    Python collects garbage once more as it exits, walking every object still
    alive: after a run, the many that numba, scipy and the engines made, a
    measurable share of a short run's CPU
    (``bench/bench_harness.py``). The process is ending, so they are frozen
    (``gc.freeze``) and that walk skips them. :func:`main` itself, which other
    programs and the tests call, leaves the collector alone.
    """
    try:
        main(argv)
    finally:
        gc.freeze()


def _main(argv: list[str] | None) -> None:
    try:
        # Outside standalone mode click *returns* the code of a click.exceptions.Exit
        # (e.g. simulate's exit 1 for an unstable run) instead of exiting with it.
        code = cli.main(args=argv, prog_name="xval", standalone_mode=False)
        if isinstance(code, int) and code != 0:
            sys.exit(code)
    except UserError as exc:
        fail(str(exc))
    except click.UsageError as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx and exc.ctx.info_name != "xval" else ""
        fail(f"{exc.format_message()}{hint}")
    except click.ClickException as exc:
        fail(exc.format_message())
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except (click.Abort, KeyboardInterrupt) as exc:
        # click turns a KeyboardInterrupt (and so our Terminated) into Abort; its cause says which it was.
        if isinstance(exc, Terminated) or isinstance(exc.__cause__, Terminated):
            click.echo("xval: terminated", err=True)
            sys.exit(143)
        click.echo("xval: interrupted", err=True)
        sys.exit(130)
    except BrokenPipeError:
        sys.exit(0)
    except OSError as exc:  # a full disk, a name too long, a file that vanished: one line, never a traceback
        line, code = os_error_line(exc)
        click.echo(f"xval: error: {inert(line)}", err=True)
        sys.exit(code)


class Seconds(click.ParamType):
    """A finite number of seconds, > 0 and at most ``maximum`` (click's FloatRange lets nan and inf through)."""

    name = "seconds"

    def __init__(self, maximum: float = 1e6) -> None:
        self.maximum = maximum

    def convert(self, value, param, ctx):
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number of seconds", param, ctx)
        if not math.isfinite(number) or not 0 < number <= self.maximum:
            self.fail(f"{value!r} is outside the allowed range: more than 0 and at most {self.maximum:g} s", param, ctx)
        return number


#: Multipliers of --memory-limit's suffixes (binary: 4G is 4 GiB).
_SIZE_SUFFIXES = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}
#: Smallest --memory-limit (address space a case may add to its host's): less fails ordinary cases.
MIN_MEMORY_LIMIT = 256 * 2**20


class MemorySize(click.ParamType):
    """``4G``, ``512M``, ``8589934592`` (bytes) or ``none``; converted to bytes (None for ``none``)."""

    name = "size"

    def convert(self, value, param, ctx):
        if value is None or isinstance(value, int):
            return value
        text = str(value).strip().upper()
        if text in ("NONE", "OFF", "UNLIMITED"):
            return None
        match = re.fullmatch(r"(\d+(?:\.\d+)?)\s*([KMGT]?)I?B?", text)
        if not match:
            self.fail(f"{value!r} is not a size; write e.g. 4G, 512M or none", param, ctx)
        size = int(float(match.group(1)) * _SIZE_SUFFIXES[match.group(2)])
        if size < MIN_MEMORY_LIMIT:
            self.fail(f"{value!r} is below the allowed minimum of 256M; write e.g. 4G, or none for no limit",
                      param, ctx)
        return size


def output_path(ctx: click.Context | None, param: click.Parameter | None, value: str | None) -> str | None:
    """A click callback refusing an empty or blank --output."""
    if value is not None and not value.strip():
        raise click.BadParameter("is empty; give a path (or - for standard output where the command allows it)")
    return value


def scene_from_params(name: str, overrides: dict[str, str]):
    """engines.scene.catalog.build, after printing a warning (stderr) for each angle that looks like radians."""
    from engines.scene import catalog

    for line in catalog.unit_warnings(name, overrides):
        click.echo(f"xval: warning: {line}", err=True)
    return catalog.build(name, overrides)


def parse_assignments(pairs: tuple[str, ...], flag: str) -> dict[str, str]:
    """``("theta0=30", "m=2")`` -> ``{"theta0": "30", "m": "2"}``; UserError naming the flag for a malformed pair."""
    parsed: dict[str, str] = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise UserError(f"{flag}: expected NAME=VALUE, got {pair!r}")
        parsed[name.strip()] = value.strip()
    return parsed


# -- options several commands share, each defined once ----------------------------------------


def history_option(help: str, name: str = "location"):
    """``--history FILE|URL``: a history (a SQLite file or a postgresql:// URL), checked as it is parsed."""
    from compare.history.location import check_option

    return click.option("--history", name, default=None, metavar="FILE|URL", callback=check_option, help=help)


def jobs_option(what: str):
    """``--jobs N``, 1 to MAX_JOBS; ``what`` says what runs at once (default: all cores)."""
    from engines.scene.limits import MAX_JOBS

    return click.option("--jobs", type=click.IntRange(min=1, max=MAX_JOBS), default=None,
                        help=f"{what}, 1 to {MAX_JOBS} (default: all cores).")


def timeout_option(help: str):
    """``--timeout S``: seconds (at most 1e6), default None (the suite's)."""
    return click.option("--timeout", type=Seconds(), default=None, metavar="S", help=help)


def param_option(help: str = "Scene parameter (see 'xval scenes'); repeatable."):
    """``--param NAME=VALUE`` (repeatable) into ``params``; read with ``parse_assignments(params, "--param")``."""
    return click.option("--param", "params", multiple=True, metavar="NAME=VALUE", help=help)


def engine_option_option(help: str = "Engine option (see 'xval engines'); repeatable."):
    """``--option NAME=VALUE`` (repeatable) into ``options``; read with ``parse_assignments(options, "--option")``."""
    return click.option("--option", "options", multiple=True, metavar="NAME=VALUE", help=help)


def model_option(use: str):
    """``--model MODEL`` into ``model``: a model file in place of a catalog SCENE; ``use`` says what is done with it."""
    return click.option("--model", "model", default=None, metavar="MODEL",
                        help=f"{use} a model file instead of a catalog SCENE (a URDF or MJCF path, or "
                             "pybullet_data:<path>); --param q0.JOINT=DEG (metres for prismatic), v0.JOINT=RAD/S "
                             "(docs/models.md).")
