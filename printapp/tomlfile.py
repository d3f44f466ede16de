"""Reading the TOML files users give us (designs, material libraries) with one-sentence errors."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from printapp.errors import PrintappError


def read_toml(path: Path | Any, label: str, what: str, error: type[PrintappError]) -> dict[str, Any]:
    """The TOML table in ``path`` (a path or anything with ``read_bytes``).

    Raises ``error`` with one sentence naming ``label`` when the ``what`` file (e.g.
    "design") is missing, a folder, unreadable, not UTF-8 or not valid TOML (with the line).
    """
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise error(f"{label}: no such {what} file") from None
    except IsADirectoryError:
        raise error(f"{label}: expected a {what} file (.toml), found a folder") from None
    except OSError as exc:
        raise error(f"{label}: cannot read the {what} file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise error(f"{label}: expected a UTF-8 text TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{label}: TOML syntax error: {exc}") from None
