"""The package layering of docs/architecture.md, checked on the source: ours ← engines ← compare ← reports, no circles.

Walks every module's imports with ast (module level and inside functions alike: a lazy import is still a
dependency) and fails on an import that points back up the stack, on a module of compare/ or reports/
naming ours, and on a cycle among the modules of the four packages.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Each package and the packages it may import.
ALLOWED = {
    "ours": {"ours"},
    "engines": {"engines", "ours"},
    "compare": {"compare", "engines"},
    "reports": {"reports", "compare", "engines"},
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path) -> set[str]:
    """Dotted names of the project modules ``path`` imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(), str(path))
    package = module_name(path).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return {name for name in found if name.split(".")[0] in ALLOWED}


def project_modules() -> dict[str, Path]:
    return {module_name(p): p for top in ALLOWED for p in (ROOT / top).rglob("*.py")}


def test_no_import_points_back_up_the_stack():
    wrong = []
    for name, path in project_modules().items():
        top = name.split(".")[0]
        for target in imports_of(path):
            if target.split(".")[0] not in ALLOWED[top]:
                wrong.append(f"{path.relative_to(ROOT)} imports {target}")
    assert wrong == []


def test_compare_and_reports_never_name_ours():
    """What only an engine knows (its stability theory) it says through the engine protocol."""
    offenders = []
    for name, path in project_modules().items():
        if name.split(".")[0] not in ("compare", "reports"):
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Compare) and any(
                isinstance(c, ast.Constant) and c.value == "ours" for c in [node.left, *node.comparators]
            ):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} compares with 'ours'")
            if isinstance(node, ast.JoinedStr) and any(
                isinstance(v, ast.Constant) and isinstance(v.value, str) and v.value.startswith("ours/")
                for v in node.values
            ):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} builds an ours/ engine id")
    assert offenders == []


def module_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports (an attribute import counts as its module)."""
    modules = project_modules()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = set()
        for target in imports_of(path):
            # "from a.b import c" names a.b.c, which may be a module or an attribute of a.b.
            while target and target not in modules:
                target = target.rpartition(".")[0]
            # A module importing its own package (or a package its submodule) is not a cycle.
            if target and target != name and not name.startswith(target + ".") and not target.startswith(name + "."):
                targets.add(target)
        graph[name] = targets
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[str]:
    """Every back edge of a depth-first walk, as the cycle it closes (``a -> b -> a``)."""
    cycles: list[str] = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)
    return cycles


def test_no_import_cycles_between_modules():
    assert find_cycles(module_graph()) == []


def folder_of(module: str) -> str:
    """The part of the house ``module`` belongs to: its folder under a package (``compare.results``,
    ``engines.scene``), or itself when it sits at a package's top (``engines.adapter``, ``compare.cli``)."""
    return ".".join(module.split(".")[:2])


def folder_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Folder -> the folders its modules import (imports inside functions included, as in module_graph)."""
    folders: dict[str, set[str]] = {}
    for module, targets in graph.items():
        here = folder_of(module)
        folders.setdefault(here, set()).update(folder_of(t) for t in targets if folder_of(t) != here)
    return folders


def test_no_import_cycles_between_folders():
    """No circle between folders, imports inside functions included: an import deferred into a function is
    for cost (a heavy optional library), never a way round a circle (results <-> suite once was one)."""
    # A library module is a node of its own, but its home imports it: a path from it back to its home would
    # still show here as a circle.
    assert find_cycles(folder_graph(module_graph())) == []
    planted = {"compare.results.store": {"compare.suite.reader"}, "compare.suite.reader": {"compare.results.metrics"}}
    assert find_cycles(folder_graph(planted)) == ["compare.results -> compare.suite -> compare.results"]


def test_the_checker_resolves_imports_and_finds_a_planted_cycle():
    assert "compare.results.consistency" in imports_of(ROOT / "compare" / "results" / "sweep.py")
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a -> b -> c -> a"]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def builtin_adapters() -> dict[str, str]:
    """engines.registry.BUILTIN read from its source (engine name -> module), without importing an engine."""
    tree = ast.parse((ROOT / "engines" / "registry.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == "BUILTIN":
            return ast.literal_eval(node.value)
    raise AssertionError("engines/registry.py defines no BUILTIN")


#: The engines with a home of their own, engines/<engine>/ (its adapter, its model import, the one import of
#: its library); the reference is an engine too, but a shared part (engines/reference/: the ground truth the
#: model check and every comparison use), so it has no home and its name is not one the checks below look for.
HOMES = ("mujoco", "mjx", "pybullet", "pymunk", "drake", "dart", "ours")
#: Home -> what it may import from other homes: MJX steps MuJoCo's own model, built by MuJoCo's public builder
#: (engines/mujoco/builder.py), with MuJoCo's one import of the library.
HOME_USES = {"mjx": {"engines.mujoco.builder", "engines.mujoco.library", "engines.mujoco.library.mujoco",
                     *(f"engines.mujoco.builder.{name}" for name in ("HINGE_INERTIA_RATIO", "HingeModel", "check_hinge",
                                                                     "hinge_model", "hinge_readout", "read_hinge_samples",
                                                                     "tree_depth"))}}
#: Each home's engine library (top-level import names): imported only by that home's library.py.
LIBRARIES = {"mujoco": {"mujoco"}, "mjx": {"jax", "mujoco.mjx"}, "pybullet": {"pybullet"}, "pymunk": {"pymunk"},
             "drake": {"pydrake"}, "dart": {"dartpy"}}
#: Shared modules that may use an engine home's module: none. (The MJCF reader is MuJoCo's, in its home,
#: reached through engines.registry.describer: MJCF means what MuJoCo's compiler makes of it.)
SHARED_USES: dict[str, set[str]] = {}


def home_of(module: str) -> str | None:
    """The engine whose home ``module`` (or the package named) is in, else None."""
    parts = module.split(".")
    return parts[1] if parts[0] == "engines" and len(parts) > 1 and parts[1] in HOMES else None


def test_every_builtin_engine_but_the_reference_has_a_home_of_its_own():
    adapters = builtin_adapters()
    assert {name: module for name, module in adapters.items() if name not in HOMES} == {
        "reference": "engines.reference.reference"}
    assert {name: adapters[name] for name in HOMES} == {name: f"engines.{name}.adapter" for name in HOMES}
    assert sorted(p.name for p in (ROOT / "engines").iterdir() if p.is_dir() and p.name in HOMES) == sorted(HOMES)
    # Every home has its adapter; each engine with a library outside xval imports it in one module.
    for name in HOMES:
        assert (ROOT / "engines" / name / "adapter.py").is_file(), name
    assert sorted(n for n in HOMES if (ROOT / "engines" / n / "library.py").is_file()) == sorted(LIBRARIES)


def test_no_engine_home_imports_another():
    """An engine loads without another engine's library (Drake without MuJoCo); MJX reaches MuJoCo's public
    builder only, never a private helper."""
    assert {"engines.mujoco.adapter", "engines.drake.adapter", "engines.mjx.adapter"} <= set(builtin_adapters().values())
    wrong = []
    for module, path in project_modules().items():
        home = home_of(module)
        if home is None:
            continue
        for target in imports_of(path):
            other = home_of(target)
            if other not in (None, home) and target not in HOME_USES.get(home, set()):
                wrong.append(f"{module} imports {target}")
    assert wrong == []
    assert not any(name.rpartition(".")[2].startswith("_") for uses in HOME_USES.values() for name in uses)


def test_shared_parts_never_import_an_engine_home():
    """engines/scene, reference, model, external, the contract, the recorder and the registry (and compare,
    reports) reach an engine through the registry only."""
    wrong = []
    for module, path in project_modules().items():
        if home_of(module) is not None:
            continue
        for target in imports_of(path):
            if home_of(target) is not None and target not in SHARED_USES.get(module, set()):
                wrong.append(f"{module} imports {target}")
    assert wrong == []


def test_each_engine_library_is_imported_by_its_home_s_library_module_alone():
    owners = {library: home for home, libraries in LIBRARIES.items() for library in libraries}
    wrong = []
    for module, path in project_modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            for name in names:
                # "from mujoco import mjx" is MJX's library, "import mujoco" MuJoCo's.
                full = [f"{name}.{a.name}" for a in node.names] if isinstance(node, ast.ImportFrom) else [name]
                for imported in full:
                    owner = owners.get(".".join(imported.split(".")[:2])) or owners.get(imported.split(".")[0])
                    if owner is not None and module != f"engines.{owner}.library":
                        wrong.append(f"{module}:{node.lineno} imports {imported}")
    assert wrong == []


def engine_name_uses(tree: ast.AST, names: set[str]) -> list[int]:
    """Lines comparing a string constant with an engine's name (``==``, ``!=``, ``in``, ``match``) or keying a
    dict by one (a literal's key, ``dict.fromkeys`` of them, ``d["mujoco"]``, ``d.get("mujoco")``). A string in
    a docstring, a message or a call's argument is not a comparison."""
    def named(node: ast.AST | None) -> bool:
        if isinstance(node, ast.Constant) and node.value in names:
            return True
        return isinstance(node, (ast.Tuple, ast.List, ast.Set)) and any(named(e) for e in node.elts)

    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and any(named(c) for c in [node.left, *node.comparators]):
            lines.append(node.lineno)
        elif isinstance(node, ast.Dict) and any(named(k) for k in node.keys):
            lines.append(node.lineno)
        elif isinstance(node, ast.DictComp) and named(node.key):
            lines.append(node.lineno)
        elif isinstance(node, ast.Subscript) and named(node.slice):
            lines.append(node.lineno)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr in ("get", "pop", "setdefault", "fromkeys") and node.args and named(node.args[0])):
            lines.append(node.lineno)
        elif isinstance(node, ast.MatchValue) and named(node.value):
            lines.append(node.lineno)
    return lines


#: Module-level tables whose keys equal an engine's name without naming the engine: an MJCF file's root
#: element is <mujoco> (engines.model.source.FORMATS: root element -> format).
NOT_ENGINES = {("engines.model.source", "FORMATS")}


def test_no_module_outside_an_engine_s_home_and_the_registry_picks_code_by_an_engine_s_name():
    """What one engine does lives in its home: no shared module (nor compare, reports) tests a string for
    an engine's name or keys a table by engine names. The names are the registry's built-in ones, but for
    "reference": the shared ground truth, which compare picks on purpose (the reference run of every case)."""
    names = set(builtin_adapters()) - {"reference"}
    assert names == set(HOMES)
    wrong = []
    for module, path in project_modules().items():
        if home_of(module) is not None or module == "engines.registry":
            continue
        tree = ast.parse(path.read_text())
        tree.body = [node for node in tree.body if not (isinstance(node, ast.Assign) and any(
            (module, getattr(target, "id", None)) in NOT_ENGINES for target in node.targets))]
        wrong += [f"{module}:{line}" for line in engine_name_uses(tree, names)]
    assert wrong == []


def test_the_engine_name_check_sees_comparisons_and_tables_not_messages():
    names = {"mujoco", "drake"}
    code = ('if name == "mujoco": pass\nx = name in ("drake", "other")\nd = {"mujoco": 1}\ny = d["drake"]\n'
            'z = d.get("mujoco")\ndef f():\n    """mujoco == drake"""\n    raise ValueError("mujoco is missing")\n'
            'print("drake")\n')
    assert engine_name_uses(ast.parse(code), names) == [1, 2, 3, 4, 5]


def test_model_scenes_reach_adapters_through_one_dispatch():
    """engines.adapter.Engine routes a model file to _check_model / _run_model; no adapter tests a scene
    for being one (the special case each used to write)."""
    testing = [(path.parent.name, line.strip()) for path in sorted((ROOT / "engines").glob("*/adapter.py"))
               for line in path.read_text().splitlines() if "is_model" in line]
    # ours' preload passes over model scenes (nothing to compile ahead): a loop over scenes, not a dispatch.
    assert testing == [("ours", "if scene.is_model:  # rigid bodies: compiled when their run is set up")]


#: The parts of engines/, lowest first; a part imports only itself and lower ones (never a sibling of the
#: same rank). The errors, the silencing of C libraries' prints (stdio), the file helpers (which raise
#: those errors) and the scene language are what every engine speaks; the engine protocol (adapter) and
#: the one stepping loop on it (recorder) are built on them; each kind of engine from outside xval
#: (processes, plugins) on those; the registry names every engine (built-in homes by module name, never by
#: import); the robot models reach engines through it; the reference integrates scenes and models; each
#: engine's home uses all of these. Homes share a rank: test_no_engine_home_imports_another says which of
#: them may use another.
ENGINE_PARTS = {"errors": 0, "stdio": 0, "files": 1, "scene": 1, "adapter": 2, "recorder": 3, "external": 4,
                "registry": 5, "model": 6, "reference": 7, "gradients": 3,
                **dict.fromkeys(HOMES, 8)}


def test_no_import_in_engines_points_back_up_or_across():
    present = {p.stem for p in (ROOT / "engines").iterdir() if p.suffix == ".py" or (p / "__init__.py").is_file()}
    assert sorted(present - {"__init__"} - set(ENGINE_PARTS)) == []  # a new part is given its rank here
    wrong = []
    for name, path in project_modules().items():
        parts = name.split(".")
        if parts[0] != "engines" or len(parts) < 2:
            continue
        for target in imports_of(path):
            to = target.split(".")
            if to[0] != "engines" or len(to) < 2 or to[1] not in ENGINE_PARTS or to[1] == parts[1]:
                continue
            if (to[1] in HOMES and parts[1] in HOMES) or target in SHARED_USES.get(name, set()):
                continue  # between homes: test_no_engine_home_imports_another; the MJCF reader's MuJoCo
            if ENGINE_PARTS[to[1]] >= ENGINE_PARTS[parts[1]]:
                wrong.append(f"{path.relative_to(ROOT)} ({parts[1]}) imports {target} ({to[1]})")
    assert wrong == []


def test_a_model_import_uses_only_its_own_engine_s_home():
    """engines/<engine>/model.py loads a file with <engine>'s library: importing another engine's home would
    make it fail where that other library is missing (DART's import without PyBullet)."""
    wrong, checked = [], set()
    for engine in HOMES:
        path = ROOT / "engines" / engine / "model.py"
        if not path.is_file():  # an engine without a model importer of its own (pymunk, MJX)
            continue
        checked.add(engine)
        for target in imports_of(path):
            if home_of(target) not in (None, engine):
                wrong.append(f"engines.{engine}.model imports {target}")
    # Every engine that loads models was checked: a moved or renamed import module would otherwise pass unread.
    assert checked == {"dart", "drake", "mujoco", "ours", "pybullet"}
    assert wrong == []


#: The stages of compare/, lowest first; a stage imports only its own and lower ones (imports inside
#: functions included). The record and its metrics are the vocabulary every stage speaks; the suite names
#: metrics and bounds in that vocabulary; run measures cases into records, and reads a finished run back
#: with the suite kept beside it (compare.run.results); then what reads runs back.
STAGES = {"results": 0, "gradients": 0, "suite": 1, "run": 2, "gate": 3, "stability": 3, "history": 3}


def test_no_import_in_compare_runs_from_a_lower_stage_to_a_higher_one():
    # A stage renamed or moved would otherwise leave its imports unchecked and this test passing.
    assert sorted(s for s in STAGES if not (ROOT / "compare" / s / "__init__.py").is_file()) == []
    wrong = []
    for name, path in project_modules().items():
        parts = name.split(".")
        if parts[0] != "compare" or len(parts) < 3 or parts[1] not in STAGES:
            continue
        for target in imports_of(path):
            stage = target.split(".")[1] if target.startswith("compare.") else None
            if stage in STAGES and STAGES[stage] > STAGES[parts[1]]:
                wrong.append(f"{path.relative_to(ROOT)} ({parts[1]}) imports {target} ({stage})")
    assert wrong == []


#: Modules of compare/ and reports/ that may name a results directory's cases/ folder: the store reads and
#: writes it (into and from CaseRecords), and names it to keep every output off a run's inputs (results_inputs).
CASES_FOLDER_NAMED_BY = {"compare.results.store"}


def names_the_cases_folder(tree: ast.AST) -> bool:
    """Whether the code builds a path into a cases/ folder (``x / "cases"``, or a string with "cases/")."""
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div) and isinstance(node.right, ast.Constant) \
                and node.right.value == "cases":
            return True
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and "cases/" in node.value \
                and "\n" not in node.value:  # a docstring may say where cases live
            return True
    return False


def test_compare_reads_case_files_only_through_the_case_record():
    """The case files (DIR/cases/*.json) are read by compare.results.store alone, into CaseRecords, in one loop."""
    readers = [name for name, path in project_modules().items()
               if name.split(".")[0] in ("compare", "reports") and name not in CASES_FOLDER_NAMED_BY
               and names_the_cases_folder(ast.parse(path.read_text()))]
    assert readers == []
    store = (ROOT / "compare" / "results" / "store.py").read_text()
    assert store.count('glob("*.json")') == 1  # store.read_records
    assert names_the_cases_folder(ast.parse('open(run / "cases" / name)'))


def calls_to(name: str, attribute: str | None = None) -> dict[str, list[int]]:
    """Module of compare/ or reports/ -> lines calling ``name(...)`` (or ``name.attribute(...)``)."""
    found: dict[str, list[int]] = {}
    for module, path in project_modules().items():
        if module.split(".")[0] not in ("compare", "reports"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            if attribute is None:
                hit = (isinstance(func, ast.Name) and func.id == name) or (
                    isinstance(func, ast.Attribute) and func.attr == name)
            else:
                hit = (isinstance(func, ast.Attribute) and func.attr == attribute
                       and isinstance(func.value, ast.Name) and func.value.id == name)
            if hit:
                found.setdefault(module, []).append(node.lineno)
    return found


def test_a_case_has_one_shape_from_the_runner_to_disk_to_gate_baseline_and_history():
    """The runner builds the CaseRecord and writes its to_json; only the two stores of records parse them
    (case files, the history's record column); no module builds a case document as a dict of its own."""
    assert set(calls_to("CaseRecord", "from_json")) == {"compare.results.store", "compare.history.store"}
    assert set(calls_to("write_case")) == {"compare.run.runner"}
    documents = []
    for module, path in project_modules().items():
        if module.split(".")[0] in ("compare", "reports") and module != "compare.results.record":
            for node in ast.walk(ast.parse(path.read_text())):
                keys = {k.value for k in getattr(node, "keys", ()) if isinstance(k, ast.Constant)}
                if isinstance(node, ast.Dict) and {"case", "status", "metrics"} <= keys:
                    documents.append(f"{module}:{node.lineno}")
    assert documents == []


#: Fields of a case record or a baseline entry: read as attributes of the typed objects, never by key.
CASE_FIELDS = {"case", "status", "message", "metrics", "run_info", "series", "timing", "engine_version", "scene_hash",
               "consistent", "consistency", "scene_id", "engine", "engine_id", "dt", "position", "cases", "wall_times",
               "cpu_times", "calibrations", "reference_horizon", "characteristic", "variant", "options"}
#: The modules that move cases from the runner to the gate: none indexes a raw case or entry.
TYPED_ONLY = ("compare.run.runner", "compare.gate.gate", "compare.gate.report", "compare.gate.junit",
              "compare.history.window", "compare.history.trend", "compare.commands.gate", "compare.commands.baseline")


def test_baseline_entries_are_typed_and_made_from_case_records_in_one_place():
    assert set(calls_to("BaselineEntry")) == {"compare.gate.entry"}  # entry_of and from_json
    assert set(calls_to("entry_of")) == {"compare.gate.baseline"}  # a baseline's, the history's, the gate's current
    modules = project_modules()
    keyed = []
    for module in TYPED_ONLY:
        for node in ast.walk(ast.parse(modules[module].read_text())):
            key = None
            if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
                key = node.slice.value
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr in ("get", "pop", "setdefault") and node.args
                  and isinstance(node.args[0], ast.Constant)):
                key = node.args[0].value
            if key in CASE_FIELDS:
                keyed.append(f"{module}:{node.lineno} [{key!r}]")
    assert keyed == []


def engine_hook_names() -> set[str]:
    """Names an engine class defines: the base Engine's and every built-in adapter's methods and attributes."""
    names: set[str] = set()
    for path in [ROOT / "engines" / "adapter.py", ROOT / "engines" / "external" / "command.py",
                 ROOT / "engines" / "reference" / "reference.py", *(ROOT / "engines" / h / "adapter.py" for h in HOMES)]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and (node.name == "Engine" or any(
                    isinstance(b, ast.Name) and b.id.endswith("Engine") for b in node.bases)):
                for item in node.body:
                    if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        names.add(item.name)
                    elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                        names.add(item.target.id)
                    elif isinstance(item, ast.Assign):
                        names.update(t.id for t in item.targets if isinstance(t, ast.Name))
    # "name" is everything's (a task's too, which the cluster's progress reads with getattr).
    return names - {"__init__", "name"}


def test_every_engine_hook_is_declared_never_looked_up_by_name():
    """The harness calls what Engine declares (with its default); getattr/hasattr with an engine hook's name
    outside the engines' own classes would mean a hook an engine may or may not have."""
    hooks = engine_hook_names()
    assert {"preload", "tolerance_options", "tolerance_capable", "program", "needs_warm_up"} <= hooks
    found = []
    for module, path in project_modules().items():
        if home_of(module) is not None:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr")
                    and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and node.args[1].value in hooks):
                found.append(f"{module}:{node.lineno} {node.func.id}(..., {node.args[1].value!r})")
    assert found == []
