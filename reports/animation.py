"""The data of a scene's particle animation (drawn by the page on a canvas: play, pause, scrub).

Every variant with stored positions at the scene's chosen dt is overlaid
on the reference, in the x–z plane (a 3-D scene seen from the side). The
JSON is small: x and z only, at most :data:`MAX_FRAMES` frames and
:data:`MAX_POINTS` positions in all (a long chain gets fewer frames, and
when even :data:`MIN_FRAMES` would pass that, only its ok runs), rounded to
4 significant digits; a particle that left the scene's box (a blow-up) is
left out of the frame rather than stretching the view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from compare.results.record import Status

from reports.figures import CLIP_FACTOR, _by_family, _chosen_cases, _label, _reference_positions, _round
from reports.load import SceneResults
from reports.palette import REFERENCE_COLOUR, Palette

#: Most frames kept (the stored series hold about 100).
MAX_FRAMES = 400
#: Fewest frames kept, and most (frame, particle, run) positions in one animation otherwise.
MIN_FRAMES = 20
MAX_POINTS = 40_000
#: Wall-clock seconds one pass of the animation takes, whatever the simulated duration.
PLAY_SECONDS = 8.0


@dataclass(frozen=True)
class AnimationData:
    """frames : how many; data : the JSON the page's script reads (see the module docstring)."""

    frames: int
    data: dict[str, Any]


def _frame(sample: Any, box: float) -> list[Any] | None:
    """One sample (P, 3) m as [[x, z] | None per particle]; None for a missing sample."""
    if sample is None:
        return None
    out: list[Any] = []
    for p in sample:
        if p is None or p[0] is None or p[2] is None or abs(p[0]) > box or abs(p[2]) > box:
            out.append(None)
        else:
            out.append([_round(p[0]), _round(p[2])])
    return out


#: On a model, a link whose largest distance from the base is more than this many times the median link's
#: runs away: the view is fitted to the others.
RUNAWAY_FACTOR = 3.0


def runaway(runs: list[dict[str, Any]], model: bool) -> set[int]:
    """Indices of a model's links that go more than RUNAWAY_FACTOR × the median link's reach from the base in
    ``runs`` (each {"positions": frames of [x, z] per link}); empty for a catalog scene or under 3 links."""
    if not model:
        return set()
    reach: dict[int, float] = {}
    for run in runs:
        for frame in run["positions"]:
            for k, p in enumerate(frame or []):
                if p:
                    reach[k] = max(reach.get(k, 0.0), math.hypot(p[0], p[1]))
    if len(reach) < 3:
        return set()
    middle = sorted(reach.values())[len(reach) // 2]
    return {k for k, r in reach.items() if middle > 0 and r > RUNAWAY_FACTOR * middle}


def animation_data(scene: SceneResults, palette: Palette) -> AnimationData | None:
    """The animation of ``scene`` at its chosen dt, or None when no variant stored positions there."""
    chosen = [c for c in _by_family(_chosen_cases(scene), lambda c: c[1].engine) if (c[2].series or {}).get("positions")]
    if not chosen:
        return None
    longest = max((c[2].series["t"] for c in chosen), key=len)
    # Frames × particles × runs is bounded, so a 128-link chain plays with fewer frames (and, if that is not
    # enough, only its ok runs), not a bigger file.
    n_particles = max(1, len(scene.scene.get("particles", [])))
    only_ok = (len(chosen) + 1) * n_particles * MIN_FRAMES > MAX_POINTS
    if only_ok:
        chosen = [c for c in chosen if c[2].status is Status.OK] or chosen[:1]
    frames = max(MIN_FRAMES, min(MAX_FRAMES, MAX_POINTS // ((len(chosen) + 1) * n_particles)))
    step = max(1, math.ceil(len(longest) / frames))
    keep = list(range(0, len(longest), step))
    box = CLIP_FACTOR * scene.length
    runs: list[dict[str, Any]] = []
    reference, _ = _reference_positions(scene)
    if reference:
        runs.append({"name": "reference", "colour": REFERENCE_COLOUR, "reference": True,
                     "positions": [_frame(reference[k], box) if k < len(reference) else None for k in keep]})
    for _, sweep, record in chosen:
        positions = record.series["positions"]
        runs.append({"name": _label(sweep, record), "colour": palette.colour(sweep.engine), "reference": False,
                     "positions": [_frame(positions[k], box) if k < len(positions) else None for k in keep]})
    anchors, links = [], []
    if scene.scene.get("kind") == "model":  # links drawn between joint frames; the root is fixed at the origin
        anchors.append([0.0, 0.0])
        links += [[parent, k, 0 if parent is None else None]
                  for k, parent in enumerate(scene.scene.get("frame_parents", []))]
    for constraint in scene.scene.get("constraints", []):
        if constraint.get("kind") == "pin":
            anchors.append([constraint["anchor"][0], constraint["anchor"][2]])
            links.append([None, constraint["particle"], len(anchors) - 1])
        elif constraint.get("kind") == "rod":
            links.append([constraint["a"], constraint["b"], None])
    # The view: the reference's (else every run's) extent and the anchors, with a margin; on a model, without
    # the links that run away from the base (a free prismatic finger falling), which are named instead.
    source = runs[:1] if reference else runs
    away = runaway(source, scene.scene.get("kind") == "model")
    xs = [p[0] for run in source for frame in run["positions"] if frame for k, p in enumerate(frame)
          if p and k not in away] + [a[0] for a in anchors]
    zs = [p[1] for run in source for frame in run["positions"] if frame for k, p in enumerate(frame)
          if p and k not in away] + [a[1] for a in anchors]
    if not xs:
        xs, zs = [-scene.length, scene.length], [-scene.length, scene.length]
    margin = 0.1 * max(max(xs) - min(xs), max(zs) - min(zs), 1e-3)
    data = {
        "t": [_round(longest[k]) for k in keep],
        "seconds": PLAY_SECONDS,
        "box": [min(xs) - margin, max(xs) + margin, min(zs) - margin, max(zs) + margin],
        "anchors": anchors,
        "links": links,
        "runs": runs,
        "only_ok": only_ok,
        "runaway": [scene.scene["particles"][k].get("link", str(k)) for k in sorted(away)],
    }
    return AnimationData(len(keep), data)
