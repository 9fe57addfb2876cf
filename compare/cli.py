"""The ``xval`` command line: a click group whose verbs live one per module in ``compare/commands``.

Layers above ``compare`` (``reports``) and third-party packages add verbs
through the ``xval.commands`` entry-point group, so nothing here imports
upward. ``main`` turns every UserError (and click's usage errors) into one
line on stderr and exit code 2, with no traceback.
"""

from __future__ import annotations

import importlib
import sys
from importlib.metadata import entry_points
from typing import Any, NoReturn

import click

from engines.errors import UserError

#: Built-in verbs: name -> the module defining a click command ``command`` of that name.
COMMAND_MODULES = {
    name: f"compare.commands.{name}"
    for name in ("scenes", "engines", "simulate", "score", "run", "show", "baseline", "gate", "stability", "history")
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
    """Print one error line and exit 2."""
    click.echo(f"xval: error: {message}", err=True)
    sys.exit(2)


def main(argv: list[str] | None = None) -> None:
    try:
        # Outside standalone mode click *returns* the code of a click.exceptions.Exit
        # (e.g. simulate's exit 1 for an unstable run) instead of exiting with it.
        code = cli.main(args=argv, prog_name="xval", standalone_mode=False)
        if isinstance(code, int) and code != 0:
            sys.exit(code)
    except UserError as exc:
        fail(str(exc))
    except click.UsageError as exc:
        hint = f" (see 'xval {exc.ctx.info_name} --help')" if exc.ctx and exc.ctx.info_name != "xval" else ""
        fail(f"{exc.format_message()}{hint}")
    except click.ClickException as exc:
        fail(exc.format_message())
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except (click.Abort, KeyboardInterrupt):
        click.echo("xval: interrupted", err=True)
        sys.exit(130)
    except BrokenPipeError:
        sys.exit(0)


def parse_assignments(pairs: tuple[str, ...], flag: str) -> dict[str, str]:
    """``("theta0=30", "m=2")`` -> ``{"theta0": "30", "m": "2"}``; UserError naming the flag for a malformed pair."""
    parsed: dict[str, str] = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise UserError(f"{flag}: expected NAME=VALUE, got {pair!r}")
        parsed[name.strip()] = value.strip()
    return parsed
