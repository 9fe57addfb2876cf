"""Specialised copies of ``ours.kernel``: the same source with its sizes made compile-time constants.

``kernel_for(dim, sizes)`` returns ``ours.kernel``'s functions with the size functions of its SIZES
block returning constants, so LLVM unrolls those loops; results are the generic kernel's bit for bit
(but Cramer's rule for at most 3 constraints). The copy is written once per kernel source under the
user cache directory, named by a hash of the source it depends on. ``tangent_for`` is the same copy
with ``ours/tangent.py``'s tangent-linear step appended, a module of its own.

Details: docs/ours.md, "Module notes", ``ours/specialize.py``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Callable

from ours.files import atomic_write, cache_dir

_SIZES_START = "# ---- SIZES (ours.specialize replaces this block with constants) ----"
_SIZES_END = "# ---- END SIZES ----"
_loaded: dict[tuple, ModuleType] = {}

#: Systems at most this big get every size as a constant (``sizes_of``): the loops over
#: particles, constraints and the band unroll completely, which takes the double
#: pendulum's RK4 step from about 4× to about 3× a hand-fused kernel
#: (``bench/bench_ours.py``). Each such structure is one more compilation (a few
#: seconds, once: the machine code is cached), so larger systems share the
#: per-dimension copy, whose loops run over sizes read at run time.
SMALL_PARTICLES = 3
SMALL_CONSTRAINTS = 3
#: Specialised copies for at most this many constraints solve J W Jᵀ λ = r by Cramer's rule
#: (``ours.kernel.solve_closed``) instead of Cholesky: no square roots and one division.
CLOSED_FORM_CONSTRAINTS = 3


def sizes_of(n_particles: int, n_constraints: int, bandwidth: int, n_pairs: int) -> tuple[int, int, int, int] | None:
    """The sizes to bake into the kernel for a system of this structure, or None for the per-dim copy."""
    if n_particles <= SMALL_PARTICLES and n_constraints <= SMALL_CONSTRAINTS:
        return (n_particles, n_constraints, bandwidth, n_pairs)
    return None


def _source(dim: int, sizes: tuple[int, int, int, int] | None = None) -> str:
    """The text of ``ours.kernel`` with the SIZES block returning ``dim`` (and ``sizes``, if given)."""
    text = (Path(__file__).parent / "kernel.py").read_text(encoding="utf-8")
    head, rest = text.split(_SIZES_START, 1)
    _, tail = rest.split(_SIZES_END, 1)
    functions = {"_dim": dim}
    label = f"dim = {dim}"
    if sizes is not None:
        P, C, bandwidth, pairs = sizes
        functions.update(_particles=P, _constraints=C, _band_columns=bandwidth + 1, _pairs=pairs)
        label += f", P = {P}, C = {C}, bandwidth = {bandwidth}, {pairs} band entries"
    if sizes is not None and sizes[1] <= CLOSED_FORM_CONSTRAINTS:
        functions["_closed_form"] = True
        label += ", J W Jᵀ solved in closed form"
    generic = {"_particles": "x.shape[0]", "_constraints": "x.shape[0]", "_band_columns": "band.shape[1]",
               "_pairs": "pair_k.shape[0]", "_closed_form": False}
    arguments = {"_dim": "x", "_particles": "x", "_constraints": "x", "_band_columns": "band", "_pairs": "pair_k",
                 "_closed_form": "band"}
    blocks = []
    for name in ("_dim", "_particles", "_constraints", "_band_columns", "_pairs", "_closed_form"):
        value = functions.get(name, generic.get(name))
        blocks.append(f"@compiled\ndef {name}({arguments[name]}):\n    return {value}\n")
    sizes_text = f"{_SIZES_START}\n# Specialised by ours.specialize for {label}.\n\n\n" + "\n\n".join(blocks) + f"\n\n{_SIZES_END}"
    return f"# Generated from ours/kernel.py by ours.specialize; do not edit.\n{head}{sizes_text}{tail}"


_TANGENT = "# ---- TANGENT (ours.specialize appends what follows to the kernel's text) ----"


def kernel_for(dim: int, sizes: tuple[int, int, int, int] | None = None) -> ModuleType:
    """``ours.kernel`` specialised for ``dim`` (2 or 3) coordinates per particle, and for the sizes
    (P, C, bandwidth, band entries) when given (see :func:`sizes_of`)."""
    return _load("kernel", dim, sizes, lambda: _source(dim, sizes))


def tangent_for(dim: int, sizes: tuple[int, int, int, int] | None = None) -> ModuleType:
    """:func:`kernel_for`'s copy with ``ours.tangent``'s tangent-linear step appended (its text after the TANGENT
    line, which calls the kernel's functions by name): a module of its own, so the plain kernel's compiled code
    and cache stay as they are."""
    def source() -> str:
        tangent = (Path(__file__).parent / "tangent.py").read_text(encoding="utf-8").split(_TANGENT, 1)[1]
        return _source(dim, sizes) + f"\n\n{_TANGENT}\n{tangent}"

    return _load("tangent", dim, sizes, source)


def _load(kind: str, dim: int, sizes: tuple[int, int, int, int] | None, text: Callable[[], str]) -> ModuleType:
    """The module of the source ``text()`` makes, written once under the cache directory and imported once per
    process (the source is read and built only on the first call: every run of ours asks for its kernel)."""
    key = (kind, dim, sizes)
    module = _loaded.get(key)
    if module is not None:
        return module
    source = text()
    # The kernel calls ours.banded and ours.constraint, whose edits numba's cache would not notice
    # (it checks only the calling file): their text is part of the name, so an edit makes a new copy.
    here = Path(__file__).parent
    depends = "".join((here / f).read_text(encoding="utf-8") for f in ("banded.py", "constraint.py", "status.py"))
    digest = hashlib.sha256((source + depends).encode()).hexdigest()[:16]
    shape = "" if sizes is None else "_p{}c{}b{}n{}".format(*sizes)
    name = f"ours_{kind}_d{dim}{shape}_{digest}"
    folder = cache_dir() / "ours"
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(path, source.encode("utf-8"), durable=False)  # a concurrent process never imports half a file
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # a .py path always has a loader; say so if that ever changes
        raise ImportError(f"cannot load the specialised kernel module {path}")
    module = importlib.util.module_from_spec(spec)
    # Registered before it runs: numba's cache finds a function's module by this name.
    sys.modules[name] = module
    spec.loader.exec_module(module)
    _loaded[key] = module
    return module
