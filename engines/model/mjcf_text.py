"""An MJCF file as one self-contained text: includes inlined, asset folders made absolute.

MuJoCo reads ``<include file="…">`` and the compiler's ``meshdir``,
``texturedir`` and ``assetdir`` relative to the model's folder; a copy of
the text loaded from anywhere else (a string, a temporary file) loses them.
:func:`flatten` replaces each ``<include>`` by the children of the file it
names (found relative to the file that names it, else to the main file's
folder, as MuJoCo 4 does), recursively, and gives every ``<compiler>`` the
effective mesh and texture folders as absolute paths (a ``<compiler>`` is
added when the file has none), so the text loads the same from anywhere.
:func:`main_tree` keeps the world body's tree with the most moving joints: a
separate tree (a puck, a target on slides) shares no joint with it, so with
contacts, equalities and tendons off it cannot change the model's M, bias or
q̈ (PyBullet and DART, which load one multibody, would refuse the file).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from engines.model.description import ModelError

#: Deepest include chain followed (a file that includes itself would never end).
MAX_DEPTH = 20


def flatten(text: str, path: Path) -> tuple[str, int]:
    """(the text of MJCF ``text`` read from ``path`` with includes inlined and asset folders absolute,
    the number of includes inlined); ModelError naming a missing or malformed included file."""
    root = ET.fromstring(text)
    folder = path.resolve().parent
    count = _inline(root, folder, folder, 0)
    _absolute_assets(root, folder)
    return ET.tostring(root, encoding="unicode"), count


def _inline(element: ET.Element, here: Path, main: Path, depth: int) -> int:
    count = 0
    for position, child in reversed(list(enumerate(list(element)))):
        if child.tag != "include":
            count += _inline(child, here, main, depth)
            continue
        name = child.get("file", "")
        found = next((p for p in (here / name, main / name) if name and p.is_file()), None)
        if found is None:
            raise ModelError(f"<include file=\"{name}\">: no such file next to {here} or {main}; "
                             f"give a path relative to the file that includes it")
        if depth >= MAX_DEPTH:
            raise ModelError(f"<include file=\"{name}\">: includes nested deeper than {MAX_DEPTH}; "
                             f"remove the include loop")
        try:
            included = ET.fromstring(found.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ET.ParseError) as exc:
            raise ModelError(f"<include file=\"{name}\">: cannot read {found} ({exc}); fix the file") from None
        count += 1 + _inline(included, found.parent, main, depth + 1)
        element.remove(child)
        for offset, grandchild in enumerate(list(included)):
            element.insert(position + offset, grandchild)
    return count


def _absolute_assets(root: ET.Element, folder: Path) -> None:
    compilers = list(root.iter("compiler"))
    effective = {"meshdir": "", "texturedir": "", "assetdir": ""}
    for compiler in compilers:  # later settings override earlier ones, as MuJoCo merges them
        effective.update({k: v for k, v in compiler.attrib.items() if k in effective})
    absolute = {key: str(folder / (effective[key] or effective["assetdir"])) for key in ("meshdir", "texturedir")}
    if not compilers:
        compilers = [ET.Element("compiler")]
        root.insert(0, compilers[0])
    for compiler in compilers:
        compiler.attrib.pop("assetdir", None)
        compiler.attrib.update(absolute)


#: Sections whose elements name joints, bodies, geoms or sites; an element naming a left-out one goes with it.
REFERRING = ("actuator", "sensor", "equality", "tendon", "contact")


def main_tree(text: str) -> tuple[str, str | None]:
    """(MJCF ``text`` with only its main tree among the world body's trees with moving joints, a note naming
    the trees and joints left out, or None when nothing was). The main tree has the most moving joints (ties:
    the first in the file); trees without joints (welded to the world) stay. Elements that name anything left
    out (actuators, sensors, equalities, tendons, contact pairs) go too, and keyframes (their qpos would no
    longer fit)."""
    root = ET.fromstring(text)
    worlds = [(world, body) for world in root.iter("worldbody") for body in world.findall("body")]
    counts = [sum(1 for e in body.iter() if e.tag in ("joint", "freejoint")) for _, body in worlds]
    moving = [i for i, count in enumerate(counts) if count]
    if len(moving) < 2:
        return text, None
    keep = max(moving, key=lambda i: (counts[i], -i))
    left: list[str] = []
    names: set[str] = set()
    for i in moving:
        if i == keep:
            continue
        world, body = worlds[i]
        joints = [e.get("name") or "(unnamed)" for e in body.iter() if e.tag in ("joint", "freejoint")]
        left.append(f"{body.get('name') or f'body {i + 1} of the world body'} (joint{'s' if len(joints) > 1 else ''} "
                    f"{', '.join(joints)})")
        names.update(e.get("name", "") for e in body.iter() if e.get("name"))
        world.remove(body)
    for section in [s for tag in REFERRING for s in root.iter(tag)]:
        for element in list(section):
            if any(value in names for e in element.iter() for value in e.attrib.values()):
                section.remove(element)
    for parent in list(root.iter()):
        for child in [c for c in parent if c.tag == "keyframe"]:
            parent.remove(child)
    main = worlds[keep][1].get("name") or f"body {keep + 1} of the world body"
    note = (f"{'; '.join(left)} left out: {'each' if len(left) > 1 else 'it'} is a separate tree of the world body "
            f"that shares no joint with the model ({main}), so it cannot change its M, bias or q̈")
    return ET.tostring(root, encoding="unicode"), note
