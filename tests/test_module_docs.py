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


ARCHITECTURE = ROOT / "docs" / "architecture.md"
#: The house in one page: the architecture doc's length limit.
ARCHITECTURE_LINES = 250
#: Where a relative path in the architecture doc may start: the root, a package (its tables name
#: ``scene/`` or ``run/`` inside one), or docs/ (its links).
PATH_ROOTS = ("", "engines", "compare", "reports", "docs")
#: Suffixes that make a bare word a file name.
SUFFIXES = (".py", ".md", ".toml", ".j2", ".json", ".npz")
_SLASHED = re.compile(r"[\w.<>*:-]+(?:/[\w.<>*:-]*)+")
_CODE = re.compile(r"`([^`\n]+)`")
_FENCED = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
_BARE_FILE = re.compile(r"(?<![\w/.])\w+\.py\b")


def named_paths(text: str) -> set[str]:
    """Every repository path ``text`` names: a slashed word in backticks, or one ending in ``/`` or a file
    suffix anywhere; placeholders (``<engine>``, ``*``, ``DIR/``) and URLs left out."""
    code = " ".join(_CODE.findall(_FENCED.sub("", text)))
    found = set()
    for source, anywhere in ((code, True), (text, False)):
        for match in _SLASHED.findall(source):
            word = match.split("::")[0].rstrip(".,;:)")
            if any(mark in word for mark in "<>*") or word.startswith(("DIR/", "http", "//")) or ":/" in word:
                continue
            if anywhere or word.endswith("/") or word.endswith(SUFFIXES):
                found.add(word)
    return found


def test_the_architecture_doc_is_one_page_and_names_only_paths_that_exist():
    text = ARCHITECTURE.read_text()
    assert len(text.splitlines()) <= ARCHITECTURE_LINES
    paths = named_paths(text)
    assert {"engines/registry.py", "compare/run/hosts.py", "../bench/README.md"} <= paths  # the pattern reads
    missing = sorted(p for p in paths if not any((ROOT / base / p).exists() for base in PATH_ROOTS))
    assert missing == []
    # A file named without its folder (a table row's "plan.py") is one the repository has.
    names = {path.name for path in ROOT.rglob("*.py") if ".venv" not in path.parts}
    assert sorted(set(_BARE_FILE.findall(text)) - names) == []
    # A module named by its dotted name (compare.results.measure.measure) is a module or a package.
    dotted = {m.group(0) for m in _DOTTED.finditer(text)}
    assert "compare.results.measure.measure" in dotted
    assert sorted(name for name in dotted if not _is_module(name)) == []


_DOTTED = re.compile(r"(?<![/\w.-])(?:ours|engines|compare|reports)(?:\.\w+)+")


def _is_module(dotted: str) -> bool:
    """True when ``dotted`` is a module or package of the repository, or a name inside one."""
    parts = dotted.split(".")
    return any((ROOT.joinpath(*parts[:n]).with_suffix(".py")).is_file() or ROOT.joinpath(*parts[:n]).is_dir()
               for n in range(2, len(parts) + 1))


#: The docs that state what is, not how it came to be.
STATED = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "bench" / "README.md"]
#: A commit hash: 7 to 40 hex digits with a letter and a digit among them, standing alone (not the
#: digits of a number such as 1.000000000000001e+299, nor part of a longer word).
COMMIT = re.compile(r"(?<![\w.+-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w+-])")
#: One of this project's issues by number ("issue 20", "Issue #4"); an upstream tracker's "bullet3 issues
#: #3116" names a library's bug and stays.
ISSUE = re.compile(r"\bissue\s+#?\d+", re.IGNORECASE)


def test_the_commit_and_issue_patterns_read_what_they_should():
    assert COMMIT.findall("on 71a79d8, and 0a48fd5's; at 09e03c3.") == ["71a79d8", "0a48fd5", "09e03c3"]
    assert COMMIT.findall("1.000000000000001e+299, 1000000, 660254037844387e-5, deadbeef, 1e-6") == []
    assert ISSUE.findall("Issue 20 asks; issue #4 too; bullet3 issues #3116") == ["Issue 20", "issue #4"]


def test_no_doc_carries_a_commit_hash_or_an_issue_number():
    found = [f"{path.relative_to(ROOT)}:{n}: {match}" for path in STATED
             for n, line in enumerate(path.read_text().splitlines(), 1)
             for match in COMMIT.findall(line) + ISSUE.findall(line)]
    assert found == []
