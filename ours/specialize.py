"""Specialised copies of ``ours.kernel``: the same source with its sizes made compile-time constants.

``kernel_for(dim)`` returns a module with the functions of ``ours.kernel`` in
which ``_dim`` returns the constant ``dim``: the per-coordinate loops unroll and
their values stay in registers (about 1.7× faster per step on the double
pendulum, ``bench/bench_ours.py``), the arithmetic and its order are
unchanged, so the results are the generic kernel's bit for bit.

The copy is written once per kernel source to
``<cache>/ours/kernel_d<dim>_<hash>.py`` (``<cache>`` from
:func:`ours.cache.cache_dir`) and imported from there; numba caches its
machine code next to it like any other module, so a later process compiles
nothing. A new constraint kind added to ``ours.kernel`` reaches the copies
through the source hash: nothing here names a kind or a scene.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

from ours.cache import cache_dir

_SIZES_START = "# ---- SIZES (ours.specialize replaces this block with constants) ----"
_SIZES_END = "# ---- END SIZES ----"
_loaded: dict[int, ModuleType] = {}


def _source(dim: int) -> str:
    """The text of ``ours.kernel`` with the SIZES block returning ``dim``."""
    text = (Path(__file__).parent / "kernel.py").read_text(encoding="utf-8")
    head, rest = text.split(_SIZES_START, 1)
    _, tail = rest.split(_SIZES_END, 1)
    sizes = (
        f"{_SIZES_START}\n# Specialised by ours.specialize for dim = {dim}.\n\n\n"
        f"@compiled\ndef _dim(x):\n    return {dim}\n\n\n{_SIZES_END}"
    )
    return f"# Generated from ours/kernel.py by ours.specialize; do not edit.\n{head}{sizes}{tail}"


def kernel_for(dim: int) -> ModuleType:
    """``ours.kernel`` specialised for ``dim`` (2 or 3) coordinates per particle."""
    module = _loaded.get(dim)
    if module is not None:
        return module
    source = _source(dim)
    digest = hashlib.sha256(source.encode()).hexdigest()[:16]
    name = f"ours_kernel_d{dim}_{digest}"
    folder = cache_dir() / "ours"
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        folder.mkdir(parents=True, exist_ok=True)
        # Write then rename, so a concurrent process never imports half a file.
        temporary = folder / f".{name}.{os.getpid()}.tmp"
        temporary.write_text(source, encoding="utf-8")
        os.replace(temporary, path)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    _loaded[dim] = module
    return module
