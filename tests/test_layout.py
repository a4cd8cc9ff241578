"""The house rules that code review would otherwise have to catch: package boundaries and public APIs."""

from __future__ import annotations

import ast

import pytest

from tests.conftest import REPO

INDEPENDENT = ("sessions", "training", "labeling")


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
