"""Package attributes that import their module on first use (PEP 562).

Importing a light module of a package (``noise.heightfield``, ``slicing.printers``) runs the
package's ``__init__`` first; with eager re-exports that pulled in numba and every kernel
module, most of the start-up of ``printapp emboss`` and ``printapp slice``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_attributes(
    package: str, namespace: dict[str, Any], homes: dict[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` whose names ``homes`` maps to their modules.

    A resolved name is stored in ``namespace`` (the package's globals), so it is looked up once.
    """

    def resolve(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home), name)
        namespace[name] = value
        return value

    def names() -> list[str]:
        return sorted({*namespace, *homes})

    return resolve, names
