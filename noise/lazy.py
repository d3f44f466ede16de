"""Package attributes that import their module on first use.

Importing a light module of a package (``noise.heightfield``, ``slicing.printers``) runs the
package's ``__init__`` first; with eager re-exports that pulled in numba and every kernel
module, most of the start-up of ``printapp emboss`` and ``printapp slice``.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any


class _LazyPackage(types.ModuleType):
    """A package whose re-exported names resolve on first use (PEP 562 semantics, in the class).

    A function named like its own submodule (``noise.veins.veins``) must win over the
    submodule, which the import system binds on the package whenever the submodule is first
    imported, by whoever imports it: that binding is replaced by the function.
    """

    _lazy_homes: dict[str, str]

    def __getattr__(self, name: str) -> Any:
        home = type(self)._lazy_homes.get(name)
        if home is None:
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home), name)
        super().__setattr__(name, value)
        return value

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and type(self)._lazy_homes.get(name) == value.__name__:
            value = getattr(value, name)
        super().__setattr__(name, value)

    def __dir__(self) -> list[str]:
        return sorted({*self.__dict__, *type(self)._lazy_homes})


def lazy_package(package: str, homes: dict[str, str]) -> None:
    """Make ``package`` (already in ``sys.modules``) resolve each name in ``homes`` from its module."""
    cls = type(f"_Lazy_{package}", (_LazyPackage,), {"_lazy_homes": dict(homes)})
    sys.modules[package].__class__ = cls
