"""Where a model file comes from and the text handed to each engine.

MODEL is a path or ``pybullet_data:<path>`` (a file PyBullet ships,
under ``pybullet_data.getDataPath()``). The format follows the root
element: ``<robot>`` is URDF, ``<mujoco>`` MJCF. Dynamics need no meshes:
:meth:`ModelSource.engine_text` drops every ``<visual>`` and ``<collision>``
of a URDF (and, when asked, every ``<mimic>``) before an engine sees it, so
missing mesh files cannot stop an import; the notes say what was dropped
(and blank lines before the XML declaration, which PyBullet reads). An MJCF keeps its geoms (MuJoCo derives inertias from them) and is made
self-contained instead (``engines.model.mjcf_text``: includes inlined, asset
folders absolute; it loads the same from anywhere) and keeps only its main
kinematic tree (a separate one cannot change its dynamics; a note says so).
:meth:`ModelSource.engine_file` is that text in a temporary file, for the
loaders that read only files.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from engines.model.description import ModelError

PREFIX = "pybullet_data:"
FORMATS = {"robot": "urdf", "mujoco": "mjcf"}


@dataclass(frozen=True)
class ModelSource:
    """label : MODEL as given. path : the file. format : 'urdf' or 'mjcf'. text : the file's text (any blank
    lines before its XML declaration removed). notes : what reading it changed.
    lock : ((joint, value), …) welded at that value (rad or m) in every text engines get (engines.model.lock)."""

    label: str
    path: Path
    format: str
    text: str
    notes: tuple[str, ...] = ()
    #: False: a <limit> with lower above upper (no limit) reaches the engines as ±NO_LIMIT (Drake refuses
    #: lower > upper); True: as it is (PyBullet's stepper empties every range so that PyBullet makes no limit).
    keep_empty_ranges: bool = False
    lock: tuple[tuple[str, float], ...] = ()

    @property
    def root(self) -> ET.Element:
        """The file's root element, locked joints fixed (a URDF's; an MJCF's are removed in engine_text)."""
        if self.lock and self.format == "urdf":
            from engines.model.lock import lock_urdf

            return ET.fromstring(lock_urdf(self.text, dict(self.lock)))
        return ET.fromstring(self.text)

    def lock_notes(self) -> tuple[str, ...]:
        if not self.lock:
            return ()
        return (f"joint{'s' if len(self.lock) > 1 else ''} {', '.join(name for name, _ in self.lock)} welded at "
                f"their initial value (lock)",)

    def engine_text(self, drop_mimic: bool = False) -> tuple[str, tuple[str, ...]]:
        """The text engines load (URDF without <visual>/<collision>, MJCF self-contained) and notes saying
        what changed."""
        if self.format != "urdf":
            from engines.model.mjcf_text import flatten, main_tree

            text, count = flatten(self.text, self.path)
            text, separate = main_tree(text)
            if self.lock:
                from engines.model.lock import lock_mjcf

                text = lock_mjcf(text, dict(self.lock))
            return text, ((f"{count} <include> element{'s' if count > 1 else ''} inlined (each file found relative "
                           f"to the file that names it)",) if count else ()) + ((separate,) if separate else ()) + \
                self.notes + self.lock_notes()
        root = self.root
        dropped = {"visual": 0, "collision": 0, "mimic": 0}
        missing: set[str] = set()
        widened = [] if self.keep_empty_ranges else _widen_empty_ranges(root)
        cones = _drop_ball_limits(root)
        for parent in root.iter():
            for child in list(parent):
                if child.tag in ("visual", "collision") or (drop_mimic and child.tag == "mimic"):
                    dropped[child.tag] += 1
                    missing.update(self._missing_meshes(child))
                    parent.remove(child)
        notes = list(self.notes)
        if widened:
            notes.append(f"{', '.join(widened)}: lower above upper (no limit, PyBullet's convention) given to every "
                         f"engine as lower {-NO_LIMIT:g}, upper {NO_LIMIT:g} (Drake refuses lower > upper)")
        if cones:
            notes.append(f"{', '.join(cones)}: the spherical joint's <limit> (a cone) removed (limits are off; "
                         f"MuJoCo refuses a ball joint's range that does not start at 0)")
        if dropped["visual"] or dropped["collision"]:
            note = (f"dynamics need no geometry: {dropped['visual']} <visual> and {dropped['collision']} "
                    f"<collision> elements removed before import")
            if missing:
                note += f" ({len(missing)} mesh files they name are not there: {', '.join(sorted(missing)[:3])}"
                note += ", …)" if len(missing) > 3 else ")"
            notes.append(note)
        if dropped["mimic"]:
            count = dropped["mimic"]
            notes.append(f"{count} <mimic> element{'s' if count > 1 else ''} removed: each mimic joint is an "
                         f"independent coordinate here (the tree's M, bias and accelerations, no coupling constraint)")
        return ET.tostring(root, encoding="unicode"), tuple(notes) + self.lock_notes()

    @contextlib.contextmanager
    def engine_file(self, drop_mimic: bool = False, text: str | None = None) -> Iterator[str]:
        """The path of a temporary file holding :meth:`engine_text` (or ``text``, an engine's rewrite of it;
        removed on exit), for loaders that read files only; its suffix is the format's (.urdf, .xml)."""
        handle, name = tempfile.mkstemp(suffix=".urdf" if self.format == "urdf" else ".xml", prefix="xval-model-")
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as stream:
                stream.write(self.engine_text(drop_mimic)[0] if text is None else text)
            yield name
        finally:
            os.unlink(name)

    def _missing_meshes(self, element: ET.Element) -> set[str]:
        names = set()
        for mesh in element.iter("mesh"):
            name = mesh.get("filename", "")
            local = name.removeprefix("file://")
            if local.startswith("package://"):  # no ROS workspace: try the package's path under the file's folder
                rest = local[len("package://"):]
                tries = [rest, rest.partition("/")[2]]
            else:
                tries = [local]
            if local and not any(t and (self.path.parent / t).is_file() for t in tries):
                names.add(name)
        return names


#: rad or m: the range a ``<limit>`` with lower above upper (no limit) is given to the engines as.
NO_LIMIT = 1e6


def _widen_empty_ranges(root: ET.Element) -> list[str]:
    """Give every joint whose <limit> has lower above upper the range ±NO_LIMIT; the joints' names."""
    widened = []
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        try:
            empty = limit is not None and float(limit.get("lower", "0")) > float(limit.get("upper", "0"))
        except ValueError:  # the description has already refused a non-numeric limit
            empty = False
        if empty and limit is not None:
            limit.set("lower", f"{-NO_LIMIT:g}")
            limit.set("upper", f"{NO_LIMIT:g}")
            widened.append(f"joint {joint.get('name', '?')}")
    return widened


def _drop_ball_limits(root: ET.Element) -> list[str]:
    """Remove the <limit> of every spherical joint (PyBullet's cone: lower, upper, twist); the joints' names."""
    dropped = []
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if joint.get("type") == "spherical" and limit is not None:
            joint.remove(limit)
            dropped.append(f"joint {joint.get('name', '?')}")
    return dropped


def unexpanded_xacro(model: str) -> ModelError:
    """The error for a file that still holds xacro macros (ROS's macro language for URDF)."""
    return ModelError(f"model {model}: unexpanded xacro (xacro: elements); expand it into a URDF first: "
                      f"xacro FILE > model.urdf")


def resolve(model: str, base: Path | None = None) -> ModelSource:
    """Read MODEL (a path, relative to ``base`` when given, or ``pybullet_data:<path>``); ModelError if unusable."""
    if model.startswith(PREFIX):
        import pybullet_data

        path = Path(pybullet_data.getDataPath()) / model[len(PREFIX):]
    else:
        path = Path(model) if base is None or Path(model).is_absolute() else base / model
    if not path.is_file():
        raise ModelError(f"model {model}: no such file ({path}); give a path to a .urdf or MJCF .xml file, "
                         f"or pybullet_data:<path> such as pybullet_data:kuka_iiwa/model.urdf")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"model {model}: cannot read {path} ({exc}); give a readable UTF-8 text file") from None
    notes: tuple[str, ...] = ()
    if text[:1].isspace() and text.lstrip().startswith("<?xml"):
        text = text.lstrip()
        notes = ("blank lines before the XML declaration removed (XML allows nothing before it)",)
    try:
        tag = ET.fromstring(text).tag
    except ET.ParseError as exc:
        if "unbound prefix" in str(exc) and "xacro:" in text:
            raise unexpanded_xacro(model) from None
        raise ModelError(f"model {model}: not well-formed XML ({exc}); fix the file") from None
    if tag not in FORMATS:
        raise ModelError(f"model {model}: root element <{tag}> is neither URDF's <robot> nor MJCF's <mujoco>; "
                         f"give a URDF or MJCF file")
    return ModelSource(model, path, FORMATS[tag], text, notes)
