"""The memory budget: every large grid, mesh, image and buffer is estimated before it is made.

A request above the budget is refused with one sentence that names the setting that made
it large and the largest value that fits, instead of growing until the machine kills the
process. The budget is half of the memory available now (``MemAvailable``, and the room
left under an address-space limit such as ``ulimit -v``), unless ``--max-memory`` or the
environment variable ``PRINTAPP_MAX_MEMORY`` (e.g. ``8G``, ``512M``) sets it.

The costs per unit below were measured with ``/usr/bin/time -v`` on whole runs (peak
resident memory against grid samples or triangles, at three sizes each) and carry a
margin; they are estimates of a whole stage, not of one array.
"""

from __future__ import annotations

import math
import os
import re
import resource

from printapp.errors import DesignError

TILE_BYTES_PER_SAMPLE = 1_800
"""A tile design end to end, per sample of its height field (measured: 1.5 KB; 181 k samples
0.64 GB, 1.0 M 1.78 GB, 2.8 M 4.42 GB peak)."""
MESH_BYTES_PER_TRIANGLE = 1_000
"""A mesh design end to end, per triangle of the refined mesh (measured: 0.78 KB; 16.8 M
triangles 13.0 GB peak)."""
EMBOSS_BYTES_PER_SAMPLE = 600
"""``printapp emboss`` per sample of the resampled map: slab vertices and faces, the STL bytes."""
BRDF_BYTES_PER_SAMPLE = 120
"""The gonioreflectometer per sample of its height field: heights, max-mipmap, slopes."""
BASE_BYTES = 400_000_000
"""What a run holds before its grids: Python, numba, Mitsuba, trimesh (measured: 0.19-0.35 GB)."""

_override: int | None = None
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def parse_size(text: str) -> int:
    """``"8G"``, ``"512M"``, ``"1.5G"``, ``"2000000"`` (bytes) as a number of bytes.

    Raises
    ------
    ValueError
        For anything else, or a size that is not positive and finite.
    """
    match = re.fullmatch(
        r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([KMGT]?)(?:i?B)?\s*", text, re.IGNORECASE
    )
    if not match:
        raise ValueError(f"expected a size such as 8G or 512M, got {text!r}")
    value = float(match[1]) * _UNITS[match[2].upper()]
    if not (math.isfinite(value) and value >= 1):
        raise ValueError(f"expected a positive size, got {text!r}")
    return int(value)


def set_budget(size_bytes: int | None) -> None:
    """Fix the budget (``--max-memory``), or None to go back to half the available memory."""
    global _override
    _override = size_bytes


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _address_space_left() -> int | None:
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    try:
        with open("/proc/self/status", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("VmSize:"):
                    return max(0, soft - int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        return soft  # no /proc (not Linux) or an unreadable line: the whole limit, as an upper bound
    return soft


def available_bytes() -> int:
    """Memory a run can still use: ``MemAvailable``, capped by an address-space limit."""
    candidates = [v for v in (_meminfo_available(), _address_space_left()) if v is not None]
    if not candidates:
        pages = os.sysconf("SC_AVPHYS_PAGES") if hasattr(os, "sysconf") else 0
        candidates = [int(pages) * int(os.sysconf("SC_PAGE_SIZE"))] if pages else [8 << 30]
    return min(candidates)


def budget_bytes() -> int:
    """The budget: ``--max-memory`` / ``PRINTAPP_MAX_MEMORY`` if given, else half of what is available."""
    if _override is not None:
        return _override
    env = os.environ.get("PRINTAPP_MAX_MEMORY")
    if env:
        try:
            return parse_size(env)
        except ValueError as exc:
            raise DesignError(f"PRINTAPP_MAX_MEMORY: {exc}") from None
    return available_bytes() // 2


def human(size_bytes: float) -> str:
    """A byte count for people: ``1.2 GB``, ``640 MB``."""
    for unit, scale in (("TB", 1 << 40), ("GB", 1 << 30), ("MB", 1 << 20), ("KB", 1 << 10)):
        if size_bytes >= scale:
            return f"{size_bytes / scale:.3g} {unit}"
    return f"{int(size_bytes)} B"


def require(needed_bytes: float, *, what: str, setting: str, fitting: str | None = None) -> None:
    """Refuse a request that would need more than the budget.

    Parameters
    ----------
    needed_bytes : float
        The estimate (bytes).
    what : str
        What would be made, e.g. ``"a 20000 x 20000-sample relief"``.
    setting : str
        The key or flag that made it large (``relief.pitch_mm``, ``--size``).
    fitting : str, optional
        What would fit instead, e.g. ``"relief.pitch_mm = 0.02 fits"``.

    Raises
    ------
    DesignError
        When ``needed_bytes`` exceeds :func:`budget_bytes`.
    """
    budget = budget_bytes()
    if not (needed_bytes <= budget):
        hint = f"; {fitting}" if fitting else ""
        source = (
            "set by --max-memory or PRINTAPP_MAX_MEMORY"
            if _override is not None or os.environ.get("PRINTAPP_MAX_MEMORY")
            else "half the memory available; --max-memory or PRINTAPP_MAX_MEMORY to change"
        )
        raise DesignError(
            f"{setting}: {what} would need about {human(needed_bytes)}, more than the memory budget of "
            f"{human(budget)} ({source}){hint}"
        )


def fits(per_unit_bytes: float, base_bytes: float = BASE_BYTES) -> float:
    """How many units (samples, triangles, pixels) of ``per_unit_bytes`` fit in the budget."""
    return max(0.0, (budget_bytes() - base_bytes) / per_unit_bytes)
