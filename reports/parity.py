"""A model scene's parity table: each engine's import against Pinocchio, coloured by how far it is off.

The numbers are ``xval model check``'s (compare/model/parity.py), read from
``DIR/model_check/<scene id>.json``: the user's own JSON when it is there
(``xval model check MODEL --format json > DIR/model_check/ID.json``), else the
report runs the check on the scene's file (REPORT_STATES states, seed 0) and
writes that file first, so the next report reads it. Each cell's class grades the relative
difference: ``agree`` at or below the check's tolerance (the forward dynamics':
``forward_tolerance``), ``near`` up to 1e-3, ``far`` beyond, ``refused`` when
the engine did not load the file.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

#: Columns of the table: (heading, key of an engine's entry).
QUANTITIES = (("M", "mass_matrix"), ("bias", "bias"), ("forward", "forward"))
#: Above the check's tolerance and at most this, a difference is "near"; beyond it "far".
NEAR = 1e-3
#: States the report samples when it runs the check itself (each engine's import costs more than the states).
REPORT_STATES = 20


def grade(value: float | None, tolerance: float) -> str:
    """The colour class of one relative difference."""
    if value is None:
        return "refused"
    if value <= tolerance:
        return "agree"
    return "near" if value <= NEAR else "far"


def model_label(scene: dict[str, Any]) -> str | None:
    """What ``xval model check`` takes for a model scene's file: ``pybullet_data:<path>`` as given, else the
    path the run resolved (None when that file is no longer there)."""
    model = str(scene.get("model", ""))
    if model.startswith("pybullet_data:"):
        return model
    path = scene.get("path")
    return str(path) if path and Path(path).is_file() else None


def write_parity(path: Path, scene: dict[str, Any]) -> None:
    """Run ``xval model check`` on the scene's file and write its JSON to ``path``; nothing when the file
    cannot be found or read (the report then says how to make the table)."""
    from compare.model.parity import check
    from engines.files import atomic_write_text
    from engines.errors import UserError

    label = model_label(scene)
    if label is None:
        return
    try:
        report = check(label, states=REPORT_STATES)
    except UserError:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(report.to_dict(), indent=1, ensure_ascii=False))


def parity_view(directory: Path, scene_id: str, scene: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The table of ``DIR/model_check/<scene_id>.json`` (written first from ``scene``'s file when it is not
    there), or None when there is none and it cannot be made (the report says which file it looked for)."""
    path = Path(directory) / "model_check" / f"{scene_id}.json"
    if scene is not None and not path.exists():
        write_parity(path, scene)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        tolerance = float(document["tolerance"])
        engines = document["engines"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    bounds = {key: tolerance for _, key in QUANTITIES}
    if "forward_tolerance" in document:  # the forward bound M's conditioning gives (null: M singular, not judged)
        forward = document["forward_tolerance"]
        bounds["forward"] = float("inf") if forward is None else float(forward)
    rows = []
    for entry in engines:
        loaded = bool(entry.get("loaded"))
        # A loaded engine's null is a difference that was not finite (its M singular, its q̈ NaN).
        values = [(float("inf") if entry.get(key) is None else entry.get(key)) if loaded else None
                  for _, key in QUANTITIES]
        cells = [{"value": value, "grade": grade(value, bounds[key])} for value, (_, key) in zip(values, QUANTITIES)]
        rows.append({"engine": entry.get("engine", "?"), "version": entry.get("version", ""), "cells": cells,
                     "agrees": bool(entry.get("agrees")), "message": entry.get("message", ""),
                     "diagnosis": list(entry.get("diagnosis", []))})
    reference = document.get("reference", {})
    return {"file": f"model_check/{scene_id}.json", "model": document.get("model", ""), "states": document.get("states"),
            "tolerance": tolerance, "reference": f"{reference.get('name', '')} {reference.get('version', '')}".strip(),
            "headings": [heading for heading, _ in QUANTITIES], "rows": rows}
