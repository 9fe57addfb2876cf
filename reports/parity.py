"""A model scene's parity table: each engine's import against Pinocchio, coloured by how far it is off.

The numbers are ``xval model check``'s (compare/model/parity.py), read from
``DIR/model_check/<scene id>.json`` when the user put its JSON there
(``xval model check MODEL --format json > DIR/model_check/ID.json``); a
scene without one gets no table. Each cell's class grades the relative
difference: ``agree`` at or below the check's tolerance, ``near`` up to
1e-3, ``far`` beyond, ``refused`` when the engine did not load the file.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

#: Columns of the table: (heading, key of an engine's entry).
QUANTITIES = (("M", "mass_matrix"), ("bias", "bias"), ("forward", "forward"))
#: Above the check's tolerance and at most this, a difference is "near"; beyond it "far".
NEAR = 1e-3


def grade(value: float | None, tolerance: float) -> str:
    """The colour class of one relative difference."""
    if value is None:
        return "refused"
    if value <= tolerance:
        return "agree"
    return "near" if value <= NEAR else "far"


def parity_view(directory: Path, scene_id: str) -> dict[str, Any] | None:
    """The table of ``DIR/model_check/<scene_id>.json``, or None when there is none or it cannot be read
    (the report says which file it looked for)."""
    path = Path(directory) / "model_check" / f"{scene_id}.json"
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        tolerance = float(document["tolerance"])
        engines = document["engines"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    rows = []
    for entry in engines:
        loaded = bool(entry.get("loaded"))
        cells = [{"value": entry.get(key) if loaded else None,
                  "grade": grade(entry.get(key) if loaded else None, tolerance)} for _, key in QUANTITIES]
        rows.append({"engine": entry.get("engine", "?"), "version": entry.get("version", ""), "cells": cells,
                     "agrees": bool(entry.get("agrees")), "message": entry.get("message", ""),
                     "diagnosis": list(entry.get("diagnosis", []))})
    reference = document.get("reference", {})
    return {"file": f"model_check/{scene_id}.json", "model": document.get("model", ""), "states": document.get("states"),
            "tolerance": tolerance, "reference": f"{reference.get('name', '')} {reference.get('version', '')}".strip(),
            "headings": [heading for heading, _ in QUANTITIES], "rows": rows}
