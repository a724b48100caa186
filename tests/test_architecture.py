"""The package's layout rules (docs/architecture.md), checked on the source with ``ast``.

- no module of ``sunlab/`` over 500 lines; no function or method over 80 lines outside numba
  kernels;
- no public function or class defined in two modules (re-exports in ``__init__`` aside);
- no module reaches into private names of another package or top-level module (sibling modules
  inside one sub-package may share them); no notebook imports a private module;
- the import direction of docs/architecture.md: the core layer never imports the layers above it;
- every package exports its ``.pyi`` stub through ``lazy_loader.attach_stub`` (scikit-image's
  pattern), and the public surface stays under :data:`MAX_PUBLIC_NAMES` names.
- the simulator imports only the foundations it needs and its own modules: what calibrates or
  computes statistics on its output lives above it (``sunlab.reproduce``) or outside the package
  (the repository's ``studies/``); Numba is imported only under ``sunlab/sim/``, where a
  benchmark shows compiling pays (``benchmarks/bench_kernels.py``).
"""

from __future__ import annotations

import ast
import collections
import json
import pkgutil
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "sunlab"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80


def _modules() -> list[tuple[str, Path, ast.Module]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out.append((".".join(parts), path, ast.parse(path.read_text(encoding="utf-8"))))
    return out


MODULES = _modules()


def _room(module: str, path: Path) -> str:
    """The unit whose modules may share private names: a sub-package, or a top-level module."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    return module if package == "sunlab" else package


def _is_kernel(func: ast.AST) -> bool:
    return any(re.search(r"\b(n?jit|vectorize|guvectorize|stencil)\b", ast.unparse(d))
               for d in func.decorator_list)


def _absolute(module: str, path: Path, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _target_room(target: str) -> str:
    """The room of an imported sunlab module (or of a name inside one)."""
    parts = target.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        file = ROOT.joinpath(*parts[:n])
        if (file / "__init__.py").exists():
            return candidate
        if file.with_suffix(".py").exists():
            package = ".".join(parts[: n - 1])
            return candidate if package == "sunlab" else package
    return target


def test_no_module_over_500_lines():
    long = {m: p.read_text().count("\n") for m, p, _ in MODULES}
    assert {m: n for m, n in long.items() if n > MAX_MODULE_LINES} == {}


def test_numba_is_imported_only_by_the_simulator():
    users = set()
    for module, _, tree in MODULES:
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n.split(".")[0] == "numba" for n in names):
                users.add(module)
    assert users and {m for m in users if not m.startswith("sunlab.sim")} == set()


def test_no_function_over_80_lines_outside_numba_kernels():
    long = {}
    for module, _, tree in MODULES:
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not _is_kernel(node):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long[f"{module}.{node.name}"] = n
    assert long == {}


def test_no_public_name_defined_in_two_modules():
    where = collections.defaultdict(set)
    for module, path, tree in MODULES:
        if path.name == "__init__.py":
            continue
        for node in tree.body:
            if isinstance(node, ast.FunctionDef | ast.ClassDef) and not _private(node.name):
                where[node.name].add(module)
    assert {k: sorted(v) for k, v in where.items() if len(v) > 1} == {}


def _reach_ins() -> list[str]:
    found = []
    for module, path, tree in MODULES:
        room = _room(module, path)
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or node.level):
                base = _absolute(module, path, node)
                if not base.startswith("sunlab"):
                    continue
                for alias in node.names:
                    target = f"{base}.{alias.name}"
                    aliases[alias.asname or alias.name] = target
                    private = _private(alias.name) or any(map(_private, base.split(".")))
                    if private and _target_room(base if not _private(alias.name) else target
                                                ) != room:
                        found.append(f"{module}: from {base} import {alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("sunlab") and any(map(_private,
                                                                   alias.name.split("."))):
                        if _target_room(alias.name) != room:
                            found.append(f"{module}: import {alias.name}")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and _private(node.attr)
                    and isinstance(node.value, ast.Name) and node.value.id in aliases):
                target = aliases[node.value.id]
                if (ROOT.joinpath(*target.split(".")).with_suffix(".py").exists()
                        or (ROOT.joinpath(*target.split(".")) / "__init__.py").exists()):
                    if _target_room(target) != room:
                        found.append(f"{module}: {target}.{node.attr}")
    return sorted(set(found))


def test_no_private_reach_ins_between_rooms():
    assert _reach_ins() == []


@pytest.mark.parametrize("notebook", sorted((ROOT / "notebooks").glob("*.ipynb")),
                         ids=lambda p: p.name[:2])
def test_notebooks_use_public_names_only(notebook):
    cells = json.loads(notebook.read_text(encoding="utf-8"))["cells"]
    code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    private = re.findall(r"sunlab(?:\.\w+)*\._\w+|from sunlab(?:\.\w+)* import [^\n]*?\b_\w+",
                         code)
    assert private == []


#: The layers of docs/architecture.md, lowest first; a module may import its own layer and
#: the layers below, never a layer above (lazy imports inside functions included).
LAYERS = [
    {"errors", "options", "extras", "atomic", "integrity", "schema", "parallel"},
    {"io", "geometry", "stats", "plans", "calibration", "centroid", "screening"},
    {"sim", "multihole", "export", "plots", "report", "hardware"},
    {"reproduce", "widgets", "cli", "data", "course"},
]


def _layer(room: str) -> int | None:
    top = room.split(".")[1] if room.count(".") else None
    for n, names in enumerate(LAYERS):
        if top in names:
            return n
    return None


def _imports(module: str, path: Path, tree: ast.Module) -> list[str]:
    """Every sunlab module or name ``module`` imports, at module level or inside a function,
    and every ``"sunlab.x.y:Name"`` string of a registry (an import by name)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or node.level):
            base = _absolute(module, path, node)
            out += [base] if base != "sunlab" else [f"sunlab.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            out += re.findall(r"^(sunlab(?:\.\w+)+):\w+$", node.value)
    return [t for t in out if t.startswith("sunlab.")]


def _room_graph() -> dict[str, set[str]]:
    """Room -> the other rooms it imports (top-level rooms: ``sunlab.sim``, ``sunlab.stats``)."""
    graph = collections.defaultdict(set)
    for module, path, tree in MODULES:
        own = ".".join(module.split(".")[:2])
        for target in _imports(module, path, tree):
            room = ".".join(target.split(".")[:2])
            if room != own:
                graph[own].add(room)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles between rooms (each as a path that returns to its start)."""
    found, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, [*stack, nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    return found


def test_no_import_cycles_between_rooms():
    # e.g. sim <-> multihole, multihole <-> plots: a room's modules may import each other, two
    # rooms may not import each other (lazy imports and registry strings count)
    assert _cycles(_room_graph()) == []


def test_every_room_has_a_layer():
    rooms = {".".join(m.split(".")[:2]) for m, _, _ in MODULES if m.count(".")}
    assert sorted(r for r in rooms if _layer(r) is None and not
                  r.split(".")[1].startswith("_")) == []


#: The most distinct public names: every ``__all__`` of a public module and every name a package's
#: stub exports, together (the submodules a stub lists aside). Issue 45's surface: infrastructure
#: (exceptions a user does not catch, the fake controller, table formatters, simulator internals)
#: stays importable from its defining module, off the listing.
MAX_PUBLIC_NAMES = 100


def _stub_entries(stub: Path) -> tuple[set[str], dict[str, str]]:
    """A package stub's submodules, and its names with the submodule each comes from."""
    submodules, names = set(), {}
    for node in ast.parse(stub.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if node.module:
                    names[alias.asname or alias.name] = node.module
                else:
                    submodules.add(alias.asname or alias.name)
    return submodules, names


def _literal_all(tree: ast.Module) -> list[str]:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__"
                                                for t in node.targets):
            if isinstance(node.value, ast.List | ast.Tuple):
                return list(ast.literal_eval(node.value))
    return []


def _bound_names(tree: ast.Module) -> set[str]:
    """The names a module binds at its top level (definitions, assignments, imports)."""
    found = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            found.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            found |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, ast.Import | ast.ImportFrom):
            found |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return found


def _module_file(package_dir: Path, name: str) -> Path | None:
    for path in (package_dir / f"{name}.py", package_dir / name / "__init__.py"):
        if path.is_file():
            return path
    return None


def _attach_stub_problems(init: Path) -> list[str]:
    """What keeps a package from exporting exactly its stub through ``attach_stub``."""
    problems = []
    tree = ast.parse(init.read_text(encoding="utf-8"))
    if not any(isinstance(node, ast.Assign)
               and ast.unparse(node.targets[0]) == "(__getattr__, __dir__, __all__)"
               and isinstance(node.value, ast.Call)
               and ast.unparse(node.value.func).split(".")[-1] == "attach_stub"
               and [ast.unparse(a) for a in node.value.args] == ["__name__", "__file__"]
               for node in tree.body):
        problems.append(f"{init}: no `__getattr__, __dir__, __all__ = "
                        "lazy_loader.attach_stub(__name__, __file__)`")
    stub = init.with_suffix(".pyi")
    if not stub.is_file():
        return [*problems, f"{stub}: no stub"]
    submodules, names = _stub_entries(stub)
    for sub in sorted(submodules):
        if _module_file(init.parent, sub) is None:
            problems.append(f"{stub}: lists a submodule {sub} that does not exist")
    for name, sub in sorted(names.items()):
        path = _module_file(init.parent, sub)
        if path is None or name not in _bound_names(ast.parse(path.read_text(encoding="utf-8"))):
            problems.append(f"{stub}: {name} is not defined in .{sub}")
    on_disk = {info.name for info in pkgutil.iter_modules([str(init.parent)])
               if not info.name.startswith("_")}
    # a function may share its module's name and shadow it (sunlab.centroid.crlb)
    for sub in sorted(on_disk - submodules - set(names)):
        problems.append(f"{stub}: does not list the submodule {sub}")
    return problems


def _public_names(package_dir: Path) -> set[str]:
    """Every public name: the ``__all__`` of each public module and the names of each stub."""
    names = set()
    for path in package_dir.rglob("*.py"):
        parts = path.relative_to(package_dir).with_suffix("").parts
        if any(p.startswith("_") and p != "__init__" for p in parts):
            continue  # a private module (sunlab.sim._kernels) exports nothing to users
        names |= set(_literal_all(ast.parse(path.read_text(encoding="utf-8"))))
        if path.name == "__init__.py" and path.with_suffix(".pyi").is_file():
            names |= set(_stub_entries(path.with_suffix(".pyi"))[1])
    return names


@pytest.mark.parametrize("init", sorted(PACKAGE.rglob("__init__.py")),
                         ids=lambda p: ".".join(p.parent.relative_to(ROOT).parts))
def test_every_package_exports_its_stub_through_attach_stub(init):
    # one export mechanism, scikit-image's: a .pyi stub lists the submodules and the names,
    # lazy_loader.attach_stub loads each on first use; every name in the stub exists
    assert _attach_stub_problems(init) == []


def test_the_public_surface_stays_small():
    assert len(_public_names(PACKAGE)) <= MAX_PUBLIC_NAMES


def test_import_sunlab_reaches_every_package_name_and_submodule():
    import importlib
    import types

    import sunlab

    assert isinstance(sunlab.screening, types.ModuleType)
    assert isinstance(sunlab.course, types.ModuleType)
    missing = []
    for init in sorted(PACKAGE.rglob("__init__.py")):
        package = importlib.import_module(".".join(init.parent.relative_to(ROOT).parts))
        submodules, names = _stub_entries(init.with_suffix(".pyi"))
        assert set(package.__all__) == submodules | set(names)
        missing += [f"{package.__name__}.{n}" for n in sorted(package.__all__)
                    if not hasattr(package, n)]
    assert missing == []


def test_calibration_registry_names_only_calibration_modules():
    from sunlab.calibration.registry import KINDS

    assert all("." not in target.partition(":")[0] for target in KINDS.values())


def test_imports_point_down_the_layers():
    upward = []
    for module, path, tree in MODULES:
        own = _layer(module)
        if own is None:
            continue
        for target in _imports(module, path, tree):
            layer = _layer(target)
            if layer is not None and layer > own:
                upward.append(f"{module} -> {target}")
    assert sorted(set(upward)) == []


#: What ``sunlab.sim`` may import (docs/architecture.md): the errors, the data contract, the
#: plans, the rotations, the compile notice and settings, and its own modules.
SIM_MAY_IMPORT = {"errors", "schema", "plans", "geometry", "options", "sim"}


def _imports_outside(package: str, allowed: set[str], modules=MODULES) -> list[str]:
    """``module -> target`` for each import of a module of ``package`` (module level or inside
    a function) whose room is not in ``allowed``."""
    return sorted({f"{m} -> {t}" for m, path, tree in modules
                   if m == package or m.startswith(package + ".")
                   for t in _imports(m, path, tree) if t.split(".")[1] not in allowed})


def test_the_simulator_imports_no_study_calibration_or_statistics():
    # the simulator is physics only: calibrating and computing the paper's statistics is the
    # work of sunlab.reproduce or of the repository's studies/, so sim sits below calibration,
    # multihole, stats and reproduce
    outside = _imports_outside("sunlab.sim", SIM_MAY_IMPORT)
    assert outside == []
    assert {"calibration", "multihole", "stats", "reproduce", "studies"}.isdisjoint(
        SIM_MAY_IMPORT)
    assert len([m for m, _, _ in MODULES if m.startswith("sunlab.sim.")]) >= 9


def test_the_checks_can_fail(tmp_path):
    """Each rule finds a planted violation (the checker is not vacuous)."""
    src = "def f():\n" + "    x = 1\n" * 90 + "    return x\n"
    tree = ast.parse(src)
    func = tree.body[0]
    assert func.end_lineno - func.lineno + 1 > MAX_FUNCTION_LINES and not _is_kernel(func)
    assert _is_kernel(ast.parse("@numba.njit(cache=True)\ndef k(): pass").body[0])
    assert _target_room("sunlab.centroid._kernels") != _room("sunlab.cli", PACKAGE / "cli.py")
    assert _layer("sunlab.reproduce") > _layer("sunlab.centroid")
    assert _cycles({"sunlab.a": {"sunlab.b"}, "sunlab.b": {"sunlab.a"}}) == [
        ["sunlab.a", "sunlab.b", "sunlab.a"]]
    tree = ast.parse('KINDS = {"x": "sunlab.multihole.strategies:GeometricCentre"}')
    assert _imports("sunlab.calibration.base", PACKAGE / "calibration" / "base.py", tree) == [
        "sunlab.multihole.strategies"]
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .a import f\n__all__ = ['f']\n")
    (pkg / "a.py").write_text("__all__ = ['f', 'g']\ndef f(): pass\ndef g(): pass\n")
    (pkg / "b.py").write_text(f"__all__ = {[f'n{i}' for i in range(MAX_PUBLIC_NAMES)]}\n")
    assert len(_public_names(pkg)) > MAX_PUBLIC_NAMES
    assert [p.split(": ", 1)[1] for p in _attach_stub_problems(pkg / "__init__.py")] == [
        "no `__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)`",
        "no stub"]
    (pkg / "__init__.py").write_text(
        "import lazy_loader as lazy\n"
        "__getattr__, __dir__, __all__ = lazy.attach_stub(__name__, __file__)\n")
    (pkg / "__init__.pyi").write_text("from . import a, c\nfrom .a import f, h\n")
    assert [p.split(": ", 1)[1] for p in _attach_stub_problems(pkg / "__init__.py")] == [
        "lists a submodule c that does not exist", "h is not defined in .a",
        "does not list the submodule b"]
    planted = ast.parse("from . import render\n\ndef f():\n    from .. import stats\n"
                        "    from ..calibration.methods import table4_methods\n")
    assert _imports_outside("sunlab.sim", SIM_MAY_IMPORT,
                            [("sunlab.sim.x", PACKAGE / "sim" / "x.py", planted)]) == [
        "sunlab.sim.x -> sunlab.calibration.methods", "sunlab.sim.x -> sunlab.stats"]
