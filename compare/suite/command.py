"""A suite's ``[[engines]]`` entry that is an outside program (the process protocol, docs/protocol.md)::

    [[engines]]
    command = ["python3", "solvers/bead.py"]   # argv, no shell; run in the suite file's folder
    label = "my-bead"                          # required: results call it command/my-bead
    version = "1.2"                            # optional: recorded; a change makes the gate say "not comparable"
    capabilities = ["3d", "constraint-forces"] # optional: scenes it cannot express are skipped with the reason
    options = { method = "rk4" }               # optional: passed to the program in the document

Relative paths in ``command`` resolve against the suite file's folder,
whatever the working directory xval runs in.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Mapping

from engines.external import command
from engines.errors import UserError

#: Keys a command entry may hold.
COMMAND_KEYS = ("command", "label", "version", "capabilities", "options")


def command_engine_spec(entry: Mapping[str, Any], key: str, suite_path: str,
                        error: Callable[[str, str], UserError]) -> tuple[command.CommandEngine, dict[str, Any]]:
    """The CommandEngine of one ``[[engines]]`` command entry, and its options.

    Reading registers nothing: the engine travels with the suite (EngineSpec.engine) to the run that
    uses it; no module-level registry learns of it.

    error(key, message) builds the reader's UserError (file, line, key). The
    program runs in the folder of ``suite_path`` (the current directory for
    a suite that is not a file).
    """
    for name in entry:
        if name not in COMMAND_KEYS:
            which = "id and command are alternatives: an entry names a built-in engine or runs a program" \
                if name == "id" else f"valid keys of a command entry are: {', '.join(COMMAND_KEYS)}"
            raise error(f"{key}.{name}", f"unknown key; {which}")
    if "label" not in entry:
        raise error(key, 'missing label; a command needs one, e.g. label = "my-bead" (results call it '
                         'command/my-bead)')
    options = entry.get("options", {})
    if not isinstance(options, dict):
        raise error(f"{key}.options", f"must be a table, e.g. options = {{ method = \"rk4\" }}, got {options!r}")
    try:
        json.dumps(options, allow_nan=False)
    except (TypeError, ValueError):
        raise error(f"{key}.options", "must hold JSON values (numbers, strings, booleans, arrays, tables; no dates, "
                                      "nan or inf): they are passed to the program in its JSON document") from None
    folder = Path(suite_path).resolve().parent if Path(suite_path).is_file() else Path.cwd()
    try:
        spec = command.make_spec(entry["label"], entry["command"], folder, entry.get("version"),
                                 entry.get("capabilities", ()), where=key)
    except command.SpecError as exc:
        raise error(f"{key}.{exc.field}", exc.reason) from None
    return command.CommandEngine(spec), dict(options)
