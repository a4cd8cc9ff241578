"""The house rules that code review would otherwise have to catch: package boundaries and public APIs."""

from __future__ import annotations

import ast
import importlib

import pytest

from tests.conftest import REPO

INDEPENDENT = ("sessions", "training", "labeling")
SHARED_ROOMS = ("figures", "running", "runtime")  # training's rooms that are not a family's


def imported_packages(package: str) -> dict[str, set[str]]:
    found: dict[str, set[str]] = {}
    for path in (REPO / package).rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.split(".")[0], set()).add(str(path.relative_to(REPO)))
    return found


@pytest.mark.parametrize("package", INDEPENDENT)
def test_core_packages_never_import_each_other(package: str) -> None:
    imports = imported_packages(package)
    for other in (*INDEPENDENT, "workbench"):
        if other != package:
            assert other not in imports, f"{package} imports {other} in {sorted(imports[other])}"


def test_labeling_imports_no_torch_and_no_ui() -> None:
    imports = imported_packages("labeling")
    assert not {"torch", "viser", "tyro"} & set(imports)


@pytest.mark.parametrize("package", (*INDEPENDENT, "workbench"))
def test_every_package_names_its_public_api(package: str) -> None:
    module = __import__(package)
    assert isinstance(module.__all__, list)
    for name in module.__all__:
        assert hasattr(module, name), f"{package}.__all__ names {name}, which it does not define"


def test_no_file_grows_past_500_lines() -> None:
    for package in (*INDEPENDENT, "workbench"):
        for path in (REPO / package).rglob("*.py"):
            n = len(path.read_text().splitlines())
            assert n <= 500, f"{path.relative_to(REPO)} has {n} lines: split it"


PACKAGES = (*INDEPENDENT, "workbench")
ROOMS = ("cli", "cycle", "demo", "evaluation", "ui")  # workbench's rooms, each used through its __init__ from outside


def _imports(path):
    """``(module, line)`` of every absolute import in a file: ``import a.b`` and ``from a.b import c``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module, node.lineno


def _owner(rel) -> str | None:
    """The package a file belongs to: its own, or the one its test folder mirrors (``tests/training/`` -> training).

    ``tests/safety/`` breaks things on purpose (it patches writers to fail, fuzzes the readers one by one), so it may
    reach into any module."""
    parts = rel.parts
    if parts[0] in PACKAGES:
        return parts[0]
    if parts[0] == "tests" and len(parts) > 2:
        return "*" if parts[1] == "safety" else parts[1]
    return None


def _outside_code():
    for folder in (*PACKAGES, "tests", "benchmarks"):
        for path in (REPO / folder).rglob("*.py"):
            yield path, path.relative_to(REPO)


def test_packages_are_used_through_their_public_names() -> None:
    """Outside a package, ``from training import fit_classifier``, never ``from training.classifier_fit import``;
    workbench's rooms likewise (``workbench.ui``, not ``workbench.ui.state``)."""
    bad = []
    for path, rel in _outside_code():
        owner = _owner(rel)
        for module, line in _imports(path):
            parts = module.split(".")
            if parts[0] not in PACKAGES or owner in (parts[0], "*"):
                continue
            deep = len(parts) > 1 if parts[0] in INDEPENDENT else (len(parts) > 2 and parts[1] in ROOMS)
            if deep:
                bad.append(f"{rel}:{line} imports {module}")
    assert not bad, "use the package's public names:\n" + "\n".join(bad)


def test_public_names_cover_what_outside_code_uses() -> None:
    """Every name outside code imports from a core package is in that package's ``__all__``."""
    missing = []
    for path, rel in _outside_code():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module in INDEPENDENT:
                if _owner(rel) == node.module:
                    continue
                public = __import__(node.module).__all__
                missing += [f"{rel}: {node.module}.{a.name}" for a in node.names if a.name not in public]
    assert not missing, "\n".join(missing)


def test_labeling_imports_no_plotting() -> None:
    imports = imported_packages("labeling")
    assert not {"torch", "viser", "tyro", "matplotlib"} & set(imports), sorted(imports)


def test_no_two_modules_share_a_name() -> None:
    seen: dict[str, list[str]] = {}
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            if path.name not in ("__init__.py", "__main__.py"):
                seen.setdefault(path.stem, []).append(str(path.relative_to(REPO)))
    shared = {name: paths for name, paths in seen.items() if len(paths) > 1}
    assert not shared, shared


def test_every_error_class_belongs_to_the_one_family() -> None:
    """Each ``*Error`` class the packages define derives from a root the CLI and the UI report as one line."""
    import importlib
    import inspect

    from workbench.user_errors import USER_ERRORS

    strays, checked = [], set()
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            rel = path.relative_to(REPO).with_suffix("")
            name = ".".join(p for p in rel.parts if p != "__init__")
            if name.endswith("__main__"):
                continue
            module = importlib.import_module(name)
            for cls_name, cls in inspect.getmembers(module, inspect.isclass):
                if cls.__module__ != name or not issubclass(cls, Exception) or not cls_name.endswith("Error"):
                    continue
                checked.add(cls_name)
                if not issubclass(cls, USER_ERRORS):
                    strays.append(f"{name}.{cls_name}")
    assert {"IngestError", "LabelError", "SessionError", "BundleError"} <= checked, sorted(checked)
    assert not strays, strays


def test_no_public_name_is_also_a_module_of_its_package() -> None:
    """``training`` loads its names on first use: a function named like a module of the package would be replaced by
    that module as soon as anything imports it (``from training import fit_predictor`` gave the module)."""
    import importlib

    clashes = []
    for folder in [REPO / "training", *(p.parent for p in (REPO / "training").glob("*/__init__.py"))]:
        package = importlib.import_module(".".join(folder.relative_to(REPO).parts))
        modules = {p.stem for p in folder.glob("*.py")} | {p.parent.name for p in folder.glob("*/__init__.py")}
        clashes += [f"{package.__name__}.{n}" for n in package.__all__ if n in modules and n != "distributed"]
    assert not clashes, clashes


def test_help_and_settings_never_load_torch() -> None:
    """``workbench --help`` and commands that need only settings start without PyTorch (about 2 s of imports)."""
    import subprocess
    import sys

    code = "import sys, workbench.cli, training; training.TrainConfig; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "False", out.stderr[-2000:]


# --- rooms: one per model family, the workbench's top level small, no circles -------------------------------------

FAMILY_ROOMS = ("minirocket", "paper_lstm", "spectral_cnn")


def _module_name(path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    return ".".join(p for p in rel.parts if p != "__init__")


def _resolved_imports(path):
    """Modules a file imports, relative imports resolved, ``if TYPE_CHECKING:`` blocks skipped (hints only); imports
    inside functions count (a lazy import is still a dependency). ``from pkg import name`` is ``pkg.name`` when that
    is a module, else ``pkg``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    hints = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for n in ast.walk(node)
    }
    for node in ast.walk(tree):
        if id(node) in hints:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            base = node.module.split(".") if node.module else []
            if node.level:
                base = package[: len(package) - node.level + 1] + base
            for alias in node.names:
                as_module = REPO.joinpath(*base, alias.name)
                if as_module.with_suffix(".py").exists() or (as_module / "__init__.py").exists():
                    yield ".".join([*base, alias.name])
                else:
                    yield ".".join(base)


def test_each_family_lives_in_its_room_and_the_registry_finds_it_there() -> None:
    """Every registered family is a room whose modules define its parts, and every ``nn.Module`` of ``training``
    belongs to a room: the shared machinery at the top defines no model."""
    from training import FAMILY_ROOMS as registered
    from training import family, family_names

    assert sorted(registered.values()) == sorted(FAMILY_ROOMS)
    for name in family_names():
        fam, room = family(name), f"training.{registered[name]}"
        assert fam.name == name
        parts = [fam.new_classifier, fam.stream_step, fam.step_module, fam.zero_state, fam.describe, fam.fit]
        for part in filter(None, parts):
            assert part.__module__.startswith(room + "."), f"{name}: {part.__module__} is outside {room}"
    strays = []
    for path in (REPO / "training").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if isinstance(node, ast.ClassDef) and any("Module" in ast.unparse(b) for b in node.bases):
                strays.append(f"{path.name}: {node.name}")
    assert not strays, f"models at the top of training/, outside a family's room: {strays}"


def test_the_cycle_never_asks_which_family_it_runs() -> None:
    """Issue 67: ``workbench/cycle/`` calls a family through the registry (what it reads, how it fits, its stage 1)
    and never names one: no string in its code is a family's name, so a fourth family is a room and a registry
    line, with no edit here. Docstrings may name them."""
    from training import family_names

    names = set(family_names()) | set(FAMILY_ROOMS)
    found = []
    for path in sorted((REPO / "workbench" / "cycle").rglob("*.py")):
        tree = ast.parse(path.read_text())
        docs = {
            id(node.body[0].value)
            for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and node.body
            and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and id(node) not in docs and node.value in names:
                found.append(f"{path.relative_to(REPO)}:{node.lineno}: {node.value!r}")
    assert not found, f"the cycle names a family: {found}"


def test_nothing_outside_a_family_room_imports_its_private_modules() -> None:
    """A room is used through its ``__init__`` (``training.spectral_cnn``), as a package is. Its own tests
    (``tests/training/``) may reach into it, as tests of a package may."""
    bad = []
    for folder in ("training", "workbench", "benchmarks", "tests"):
        for path in (REPO / folder).rglob("*.py"):
            rel = path.relative_to(REPO)
            if rel.parts[:2] == ("tests", "training") or rel.parts[:2] == ("tests", "safety"):
                continue
            for module in _resolved_imports(path):
                parts = module.split(".")
                private = len(parts) > 2 and parts[0] == "training" and parts[1] in (*FAMILY_ROOMS, *SHARED_ROOMS)
                if private and rel.parts[:2] != ("training", parts[1]):
                    bad.append(f"{rel} imports {module}")
    assert not bad, "\n".join(bad)


def test_training_top_level_holds_at_most_ten_modules_and_each_room_says_what_it_is_for() -> None:
    top = sorted(p.name for p in (REPO / "training").glob("*.py") if p.name != "__init__.py")
    assert len(top) <= 10, f"training/ holds {len(top)} modules: put them in rooms by purpose: {top}"
    rooms = sorted((REPO / "training").glob("*/__init__.py"))
    assert {"figures", "running", "runtime"} <= {p.parent.name for p in rooms}
    for init in rooms:
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        assert len(doc) > 80, f"{init.relative_to(REPO)}: its docstring should say what the room is for"


def test_workbench_top_level_holds_at_most_five_modules() -> None:
    top = sorted(p.name for p in (REPO / "workbench").glob("*.py") if p.name != "__init__.py")
    assert len(top) <= 5, top


def test_no_import_circle_between_modules() -> None:
    """Modules of the four packages never import each other in a circle (a lazy import counts; a type hint does
    not)."""
    graph: dict[str, set[str]] = {}
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            name = _module_name(path)
            graph[name] = {m for m in _resolved_imports(path) if m.split(".")[0] in PACKAGES and m != name}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not circles, circles


def test_the_test_schedule_names_files_that_exist() -> None:
    """`tests/schedule.py` hands these files out first; a renamed file would silently lose its place."""
    from tests.schedule import LONGEST_FIRST

    missing = [f for f in LONGEST_FIRST if not (REPO / f).is_file()]
    assert not missing, f"tests/schedule.py names files that are gone: {missing}"


@pytest.mark.parametrize(
    "package",
    [
        "training",
        "training.running",
        "training.figures",
        "training.minirocket",
        "training.paper_lstm",
        "training.spectral_cnn",
    ],
)
def test_every_lazily_exported_name_resolves_in_the_module_it_is_mapped_to(package: str) -> None:
    """A package whose names load on first use (``training.lazy_names``) maps each to a module: moving a function
    to another module without the map breaks only its first caller, at run time (``frame_rows`` did)."""
    module = importlib.import_module(package)
    for name in module.__all__:
        assert getattr(module, name) is not None, f"{package}.{name}"
