"""The lock file: it pins every dependency pyproject.toml names, and each run records its hash."""

from __future__ import annotations

import hashlib
import re
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parent.parent
LOCK = ROOT / "requirements.lock"
#: The extras `make` installs (Makefile: LOCK_EXTRAS); `all` stands for the optional engines' extras.
LOCKED_EXTRAS = ("test", "all", "lint")


def locked() -> dict[str, str]:
    """Distribution name -> the exact version the lock pins."""
    pins = {}
    for line in LOCK.read_text(encoding="utf-8").splitlines():
        found = re.match(r"^([A-Za-z0-9_.\-]+)==([^\s;]+)", line)
        if found:
            pins[canonicalize_name(found.group(1))] = found.group(2)
    return pins


def required() -> list[Requirement]:
    """What pyproject.toml asks for with the locked extras (xval[...] self-references followed)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = project["optional-dependencies"]
    wanted, seen, requirements = list(LOCKED_EXTRAS), set(), [Requirement(r) for r in project["dependencies"]]
    while wanted:
        extra = wanted.pop()
        if extra in seen:
            continue
        seen.add(extra)
        for text in extras[extra]:
            requirement = Requirement(text)
            if canonicalize_name(requirement.name) == "xval":
                wanted.extend(requirement.extras)
            else:
                requirements.append(requirement)
    return requirements


def test_the_lock_pins_every_dependency_within_its_range():
    # Fails when a dependency was added to or narrowed in pyproject.toml without `make lock`.
    pins = locked()
    for requirement in required():
        name = canonicalize_name(requirement.name)
        assert name in pins, f"{requirement.name} is in pyproject.toml but not in requirements.lock: run make lock"
        assert requirement.specifier.contains(pins[name], prereleases=True), (
            f"requirements.lock pins {name}=={pins[name]}, outside pyproject.toml's {requirement}: run make lock")


def test_a_run_records_the_lock_files_hash():
    from compare.run.environment import environment, lock_hash

    expected = "sha256:" + hashlib.sha256(LOCK.read_bytes()).hexdigest()
    assert lock_hash() == expected
    assert environment(used=())["lock"] == expected
    assert lock_hash(ROOT / "no-such.lock") is None
