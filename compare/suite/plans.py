"""The suite's optional tables, typed: ``[stability]``, ``[gainmap]`` and ``[verdict]``.

Read by :mod:`compare.suite.reader` with the rest of the file, so a bad
value is exit 2 (a UserError naming the file, line and key) before any case
runs; :mod:`compare.stability` receives these plans, never the TOML.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass
from typing import Any

from compare.results.consistency import DEFAULT_TOLERANCE
from engines.errors import UserError

from compare.suite.specs import EngineSpec, SceneSpec

# The reader (compare.suite.reader) imports this module and hands itself in as ``reader`` (typed Any: the
# reader's private _Reader); scenes and engines are compare.suite.specs' records.

#: Keys of ``[stability]``.
STABILITY_KEYS = ("scenes", "engines", "dt_max", "dt_min", "bracket_factor", "resolution", "sample_interval")
#: Keys of ``[gainmap]``.
GAINMAP_KEYS = ("scene", "engines", "x", "y", "x_values", "y_values", "dt", "theory_points", "sample_interval")
#: Keys of ``[verdict]``.
VERDICT_KEYS = ("tolerance",)


@dataclass(frozen=True)
class SearchSettings:
    """Where and how finely the stability search looks.

    dt_max, dt_min : s, the largest and smallest time step tried.
    bracket_factor : ratio between successive trials while stepping down (> 1).
    resolution : the search stops when (smallest unstable dt) / (largest stable dt) ≤ resolution (> 1).
    sample_interval : s between the samples the bounds are checked on (None: the suite's).
    """

    dt_max: float
    dt_min: float
    bracket_factor: float = math.sqrt(10.0)
    resolution: float = 1.1
    sample_interval: float | None = None


@dataclass(frozen=True)
class StabilityPlan:
    """Which pairs the stability search runs and its settings (from ``[stability]``, defaults: everything)."""

    scenes: tuple[SceneSpec, ...]
    engines: tuple[EngineSpec, ...]
    settings: SearchSettings


@dataclass(frozen=True)
class GainMapPlan:
    """A sweep of two numeric options of one or more engine variants on one scene at one dt.

    scene : a SceneSpec of the suite; engines : the variants mapped (EngineSpecs; their own
    options stay, x and y are set per cell); x, y : option names; x_values, y_values :
    ascending grids (the options' units); dt : s; theory_points : resolution of the drawn
    theory grid per axis; sample_interval : s (None: the suite's).
    """

    scene: SceneSpec
    engines: tuple[EngineSpec, ...]
    x: str
    y: str
    x_values: tuple[float, ...]
    y_values: tuple[float, ...]
    dt: float
    theory_points: int = 121
    sample_interval: float | None = None


def read_stability(reader: Any, table: Any, scenes, engines, dts) -> StabilityPlan:
    """``[stability]`` keys: ``scenes`` (ids, default all), ``engines`` (labels or shell patterns such as
    ``"mujoco/*"``, default all), ``dt_max`` / ``dt_min`` (s, default the suite's largest and smallest dt),
    ``bracket_factor`` (default √10), ``resolution`` (default 1.1), ``sample_interval`` (s)."""
    table = reader.table("stability", table, STABILITY_KEYS) if table is not None else {}
    chosen_scenes = scenes
    scene_ids = table.get("scenes")
    if scene_ids is not None:
        known = {s.id: s for s in scenes}
        if not isinstance(scene_ids, list) or not scene_ids:
            raise reader.error("stability.scenes", "must be a non-empty list of scene ids of this suite")
        for sid in scene_ids:
            if sid not in known:
                raise reader.error("stability.scenes", f"unknown scene id {sid!r}; this suite's are: {', '.join(known)}")
        chosen_scenes = tuple(known[sid] for sid in scene_ids)
    chosen_engines = engines
    patterns = table.get("engines")
    if patterns is not None:
        if not isinstance(patterns, list) or not patterns or not all(isinstance(p, str) for p in patterns):
            raise reader.error("stability.engines", 'must be a non-empty list of labels or patterns, e.g. ["mujoco/*"]')
        for pattern in patterns:
            if not any(fnmatch.fnmatchcase(e.label, pattern) for e in engines):
                raise reader.error("stability.engines", f"{pattern!r} matches no engine variant of this suite")
        chosen_engines = tuple(e for e in engines if any(fnmatch.fnmatchcase(e.label, p) for p in patterns))
    dt_max = reader.number("stability.dt_max", table.get("dt_max", max(dts)))
    dt_min = reader.number("stability.dt_min", table.get("dt_min", min(dts)))
    if dt_min > dt_max:
        raise reader.error("stability.dt_min", f"{dt_min:g} s is larger than dt_max {dt_max:g} s; swap them")
    factor = reader.number("stability.bracket_factor", table.get("bracket_factor", math.sqrt(10.0)))
    resolution = reader.number("stability.resolution", table.get("resolution", 1.1))
    for key, value in (("bracket_factor", factor), ("resolution", resolution)):
        if value <= 1:
            raise reader.error(f"stability.{key}", f"must be larger than 1, got {value!r}")
    if "dt_max" in table:
        for spec in chosen_scenes:
            if dt_max > spec.scene.duration:
                raise reader.error("stability.dt_max", f"{dt_max:g} s is longer than scene {spec.id!r}'s duration "
                                   f"{spec.scene.duration:g} s; lower dt_max or leave the scene out")
    interval = table.get("sample_interval")
    interval = None if interval is None else reader.number("stability.sample_interval", interval)
    return StabilityPlan(chosen_scenes, chosen_engines, SearchSettings(dt_max, dt_min, factor, resolution, interval))


def read_gainmap(reader: Any, table: Any, scenes, expand) -> GainMapPlan | None:
    """``[gainmap]``: ``scene`` (an id of the suite), ``engines`` (engine ids, e.g.
    ``["ours/baumgarte-rk4"]``), ``x`` and ``y`` (names of two numeric options of those variants),
    ``x_values`` / ``y_values`` (lists or {from, to, per_decade}), ``dt`` (s), ``theory_points``
    (default 121), ``sample_interval`` (s). None when the suite has no such table.

    expand(key, engine_id, options, label) -> [EngineSpec] is the reader's engine-id expander.
    """
    if table is None:
        return None
    if isinstance(table, dict) and "integrators" in table:
        raise reader.error("gainmap.integrators", 'the gain map now sweeps any engine: write engines = '
                           '["ours/baumgarte-rk4", ...], x = "k_s", y = "k_d", x_values = {...}, y_values = {...}')
    table = reader.table("gainmap", table, GAINMAP_KEYS)
    for key in ("scene", "engines", "x", "y", "x_values", "y_values", "dt"):
        if key not in table:
            raise reader.error("gainmap", f"missing {key}; keys are {', '.join(GAINMAP_KEYS)}")
    known = {s.id: s for s in scenes}
    if table["scene"] not in known:
        raise reader.error("gainmap.scene", f"unknown scene id {table['scene']!r}; this suite's are: {', '.join(known)}")
    scene = known[table["scene"]]
    ids = table["engines"]
    if not isinstance(ids, list) or not ids or not all(isinstance(i, str) for i in ids):
        raise reader.error("gainmap.engines", 'must be a non-empty list of engine ids, e.g. ["ours/baumgarte-rk4"]')
    x, y = reader.string("gainmap.x", table["x"]), reader.string("gainmap.y", table["y"])
    if x == y:
        raise reader.error("gainmap.y", f"must name another option than x ({x!r})")
    x_values = tuple(sorted(reader.sweep("gainmap.x_values", table["x_values"], "value", "[1e2, 1e4]",
                                         "{ from = 1, to = 1e8, per_decade = 2 }")))
    y_values = tuple(sorted(reader.sweep("gainmap.y_values", table["y_values"], "value", "[1, 1e2]",
                                         "{ from = 1e-1, to = 1e5, per_decade = 2 }")))
    engines = []
    for k, engine_id in enumerate(ids):
        for spec in expand(f"gainmap.engines[{k}]", engine_id, {}, None):
            if spec.engine is None:
                raise reader.error(f"gainmap.engines[{k}]", f"{engine_id!r} cannot run here: {spec.unavailable}")
            for name, values in ((x, x_values), (y, y_values)):
                if name not in spec.engine.options:
                    valid = ", ".join(spec.engine.options) or "none"
                    raise reader.error(f"gainmap.{'x' if name == x else 'y'}",
                                       f"{spec.engine.name} has no option {name!r}; its options are: {valid}")
                for value in (values[0], values[-1]):
                    try:
                        spec.engine.resolve(spec.variant, {name: value})
                    except UserError as exc:
                        raise reader.error(f"gainmap.{'x' if name == x else 'y'}_values", str(exc)) from None
            engines.append(spec)
    dt = reader.number("gainmap.dt", table["dt"])
    if dt > scene.scene.duration:
        raise reader.error("gainmap.dt", f"{dt:g} s is longer than scene {scene.id!r}'s duration")
    points = int(reader.number("gainmap.theory_points", table.get("theory_points", 121), integer=True))
    interval = table.get("sample_interval")
    interval = None if interval is None else reader.number("gainmap.sample_interval", interval)
    return GainMapPlan(scene, tuple(engines), x, y, x_values, y_values, dt, points, interval)


def read_verdict(reader: Any, table: Any) -> float:
    """``[verdict] tolerance``: the error plateau (a fraction of L) under which a variant counts as right
    (compare.results.consistency); default DEFAULT_TOLERANCE, 1e-6."""
    if table is None:
        return DEFAULT_TOLERANCE
    table = reader.table("verdict", table, VERDICT_KEYS)
    return reader.number("verdict.tolerance", table.get("tolerance", DEFAULT_TOLERANCE))
