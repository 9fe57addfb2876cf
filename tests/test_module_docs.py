"""Module docstrings stay short (<= 15 lines), and every one that sends the reader to a doc's notes
(``Details: docs/X.md, "Section", ``path``.``) names a heading that is there, under that section."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The packages held to the limit.
PACKAGES = ("ours", "engines", "compare", "reports")
LIMIT = 15
POINTER = re.compile(r'(docs/[\w/]+\.md), "([^"]+)",\s+``([^`]+)``')


def module_docstrings():
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            tree = ast.parse(path.read_text())
            first = tree.body[0] if tree.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                yield path, first


def test_module_docstrings_are_at_most_15_lines():
    long = [f"{path.relative_to(ROOT)}: {node.end_lineno - node.lineno + 1} lines"
            for path, node in module_docstrings() if node.end_lineno - node.lineno + 1 > LIMIT]
    assert long == []


def sections(doc: str) -> dict[str, set[str]]:
    """``## section`` -> the ``### `path` `` headings under it."""
    found: dict[str, set[str]] = {}
    current = None
    for line in (ROOT / doc).read_text().splitlines():
        if line.startswith("## "):
            current = found.setdefault(line[3:].strip(), set())
        elif line.startswith("### `") and current is not None:
            current.add(line[4:].strip().strip("`"))
    return found


def test_every_pointer_to_a_doc_names_a_heading_there():
    pointers = [(path, m.groups()) for path, node in module_docstrings() for m in POINTER.finditer(node.value.value)]
    assert len(pointers) > 20  # the pattern still matches the pointers the modules carry
    wrong = [f"{path.relative_to(ROOT)} -> {doc}, {section!r}, {target}" for path, (doc, section, target) in pointers
             if target not in sections(doc).get(section, set())]
    assert wrong == []
