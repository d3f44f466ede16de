"""``printapp bench``: the one place where speed is measured, always beside accuracy.

Each stage times settings with several repeats and reports medians (the machine is
shared and noisy), measures the error of each setting against a reference, prints a
table, and draws a time-versus-error chart. Tests never assert timings.

One module per stage, named after it (``printapp.bench.noise`` runs ``bench noise``),
loaded only when its stage runs; :mod:`printapp.bench.timing` holds what they share
and :mod:`printapp.bench.reference` the slow reference implementations they (and the
tests) measure against; :mod:`printapp.bench.peers` holds the files that drive the peer
tools.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from printapp.bench.timing import StageResult, interleaved_seconds, median_seconds
from printapp.errors import PrintappError

__all__ = ["STAGES", "StageResult", "interleaved_seconds", "median_seconds", "run_bench"]


def _lazy(stage: str) -> Callable[[int], StageResult]:
    """Stage ``stage``, whose module (and its heavy imports) loads only when the stage runs."""

    def run(repeats: int) -> StageResult:
        return getattr(importlib.import_module(f"printapp.bench.{stage}"), f"bench_{stage}")(repeats)

    return run


STAGES: dict[str, Callable[[int], StageResult]] = {
    "noise": _lazy("noise"),  # beside the plain kernel and pyfastnoisesimd
    "frames": _lazy("frames"),  # orthonormal bases
    "lic": _lazy("lic"),  # beside rlic
    "surface": _lazy("surface"),  # surface LIC: streamline reuse beside the per-vertex walk
    "slice": _lazy("slice"),  # beside PrusaSlicer
    "mesh": _lazy("mesh"),  # height map to STL beside Blender
    "brdf": _lazy("brdf"),  # beside embreex
    "pitch": _lazy("pitch"),
    "adaptive": _lazy("adaptive"),
    "mie": _lazy("mie"),  # Lorenz-Mie beside miepython's JIT; medium vs body albedo
    "pipeline": _lazy("pipeline"),
    "fit": _lazy("fit"),  # photos to noise parameters, beside the random-phase texture
    "render": _lazy("render"),  # model, table and geometry against distance
    "sampling": _lazy("sampling"),  # adaptive against uniform sampling of CAD previews
    "scale": _lazy("scale"),  # compact model against geometry by relief size, at printer pitch
    "translucency": _lazy("translucency"),  # body albedo, BSSRDF and medium against a converged medium
    "commands": _lazy("commands"),  # whole commands beside PrusaSlicer and Blender
    "solve": _lazy("solve"),  # time and evaluations to meet each example's targets
    "sweep": _lazy("sweep"),  # speed-up against workers, Dask's overhead per point
}


def run_bench(
    names: list[str], out_dir: Path, *, repeats: int = 5, console: Console | None = None
) -> list[Path]:
    """Run bench stages, print their tables, and write ``bench.json`` and ``<stage>.png``."""
    unknown = [n for n in names if n not in STAGES]
    if unknown:
        raise PrintappError(f"unknown bench stage '{unknown[0]}'; expected one of {', '.join(STAGES)}")
    console = console or Console()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PrintappError(f"{out_dir}: output folder is not writable ({exc.strerror})") from None
    written = []
    report: dict[str, Any] = {}
    for name in names:
        result = STAGES[name](repeats)
        columns = list(dict.fromkeys(key for row in result.rows for key in row))
        table = Table(*columns, title=f"{name}: {result.description}")
        for row in result.rows:
            table.add_row(*(str(row.get(c, "")) for c in columns))
        console.print(table)
        for note in result.notes:
            console.print(f"  {note}")
        report[name] = {
            "description": result.description,
            "rows": result.rows,
            "notes": result.notes,
            **result.extra,
        }
        if result.chart is not None:
            chart_path = out_dir / f"{name}.png"
            tmp = out_dir / f".{name}.png.partial.png"
            result.chart(tmp)
            tmp.replace(chart_path)
            written.append(chart_path)
    json_path = out_dir / "bench.json"
    tmp_json = out_dir / ".bench.json.partial"
    tmp_json.write_text(json.dumps(report, indent=2) + "\n")
    tmp_json.replace(json_path)
    written.append(json_path)
    return written
