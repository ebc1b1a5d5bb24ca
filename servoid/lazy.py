"""Packages whose public names are imported on first use: ``servoid.ident`` and the other pillars stay light to import.

A leaf like :mod:`servoid.errors` (it imports nothing of servoid), so the
pillars may use it. A package calls :func:`install` with the map of its
public names to the modules that define them; ``import servoid.ident.paper``
(what the command line's help reads) then runs none of the other modules,
and ``servoid.ident.identify`` is still the function once the module of the
same name has been imported.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Mapping
from typing import Any

__all__ = ["install"]


class LazyPackage(types.ModuleType):
    """A package module that imports a public name from its module when it is first used (PEP 562, on the class)."""

    _EXPORTS: Mapping[str, str]

    def __getattr__(self, name: str) -> Any:
        exports = self.__dict__.get("_EXPORTS", {})
        if name not in exports:
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(exports[name]), name)
        setattr(self, name, value)
        return value

    def __setattr__(self, name: str, value: Any) -> None:
        # The import system binds a submodule to its package by name once it has run
        # (servoid.ident.identify, the module), which would hide the function of the same
        # name the package exports: the function is bound instead, as an eager
        # `from .identify import identify` did.
        exports = self.__dict__.get("_EXPORTS", {})
        if isinstance(value, types.ModuleType) and exports.get(name) == value.__name__:
            value = getattr(value, name)
        super().__setattr__(name, value)

    def __dir__(self) -> list[str]:
        return sorted(set(self.__dict__) | set(self.__dict__.get("_EXPORTS", {})))


def install(package: str, exports: Mapping[str, str]) -> None:
    """Make ``package`` (its ``__name__``) import each name of ``exports`` from its module on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : mapping
        Public name to the module that defines it.
    """
    module = sys.modules[package]
    module.__class__ = LazyPackage
    module.__dict__["_EXPORTS"] = dict(exports)
