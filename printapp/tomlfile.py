"""Reading the TOML files users give us (designs, fragments, material libraries) with one-sentence errors."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from printapp.errors import PrintappError
from printapp.inputs import TEXT_LIMIT_BYTES, read_text

MAX_DEPTH = 32
"""Deepest nesting of tables and arrays accepted (a design nests three deep)."""


def _depth(value: Any, limit: int) -> int:
    stack = [(value, 1)]
    deepest = 0
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if deepest > limit:
            return deepest
        if isinstance(node, dict):
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, depth + 1) for v in node)
    return deepest


def read_toml(path: Path | Any, label: str, what: str, error: type[PrintappError]) -> dict[str, Any]:
    """The TOML table in ``path`` (a path, or a packaged resource with ``read_bytes``).

    Raises ``error`` with one sentence naming ``label`` when the ``what`` file (e.g.
    "design") is missing, not a regular file, larger than 4 MB, unreadable, not UTF-8,
    not valid TOML (with the line), or nested deeper than :data:`MAX_DEPTH`. A leading
    UTF-8 byte-order mark is accepted.
    """
    try:
        if isinstance(path, (str, Path)):
            text = read_text(path, what, TEXT_LIMIT_BYTES)
        else:
            text = path.read_bytes().decode("utf-8").removeprefix("\ufeff")
    except PrintappError as exc:
        raise error(str(exc).replace(str(path), label, 1)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{label}: cannot read the {what} file ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{label}: TOML syntax error: {exc}") from None
    except RecursionError:
        raise error(f"{label}: the {what} file nests tables or arrays too deeply to read") from None
    if _depth(data, MAX_DEPTH) > MAX_DEPTH:
        raise error(f"{label}: the {what} file nests tables or arrays more than {MAX_DEPTH} deep")
    return data
