"""Names of a package loaded on first use (PEP 562), so that importing a setting never loads PyTorch."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(
    package: str, table: Mapping[str, tuple[str, ...]], namespace: dict[str, Any], *, submodules: tuple[str, ...] = ()
) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``__all__``, ``__getattr__`` and ``__dir__`` of a package whose names live in its modules.

    Args:
        package: The package's ``__name__``.
        table: Module (relative to the package) -> the public names it defines.
        namespace: The package's ``globals()``: a name, once loaded, is stored there and never looked up again.
        submodules: Modules that are themselves public names, by their path in the package: ``running.distributed``
            is ``training.distributed``.
    """
    owner = {name: module for module, names in table.items() for name in names}
    paths = {path.rsplit(".", 1)[-1]: path for path in submodules}
    public = sorted([*owner, *paths])

    def getattr_(name: str) -> Any:
        if name in paths:
            return importlib.import_module(f".{paths[name]}", package)
        module = owner.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{module}", package), name)
        namespace[name] = value  # later lookups skip this function
        return value

    def dir_() -> list[str]:
        return public

    return public, getattr_, dir_
