"""``printapp bench``: the one place where speed is measured, always beside accuracy.

Each stage times settings with several repeats and reports medians (the machine is
shared and noisy), measures the error of each setting against a reference, prints a
table, and draws a time-versus-error chart. Tests never assert timings.
"""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from printapp.errors import PrintappError


@dataclass
class StageResult:
    """Rows of one bench stage, and how to chart them."""

    name: str
    description: str
    rows: list[dict[str, Any]]
    chart: Callable[[Path], None] | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


def median_seconds(fn: Callable[[], object], repeats: int) -> tuple[float, list[float]]:
    """Median wall time of ``fn`` over ``repeats`` calls, after one untimed warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), times


def interleaved_seconds(
    fns: dict[str, Callable[[], Any]], repeats: int, warmups: dict[str, Callable[[], Any]] | None = None
) -> tuple[dict[str, float], dict[str, Any], dict[str, float]]:
    """Median wall time of each ``fn``, timed in turn within every repeat.

    Round-robin, so that the load of a shared machine falls on every contender alike.
    Each function is first called once untimed; ``warmups``, when given, replaces those
    calls (cheaper ones, or none). Returns the medians, each function's last result,
    and its process CPU time over wall time (how many cores it kept busy).
    """
    for warm in (fns if warmups is None else warmups).values():
        warm()
    times: dict[str, list[float]] = {k: [] for k in fns}
    cpu: dict[str, float] = dict.fromkeys(fns, 0.0)
    last: dict[str, Any] = {}
    for _ in range(max(1, repeats)):
        for key, fn in fns.items():
            cpu0, start = time.process_time(), time.perf_counter()
            last[key] = fn()
            times[key].append(time.perf_counter() - start)
            cpu[key] += time.process_time() - cpu0
    medians = {k: statistics.median(v) for k, v in times.items()}
    return medians, last, {k: cpu[k] / max(sum(times[k]), 1e-12) for k in fns}


def _triangulated_value(
    heights: np.ndarray, dx: float, dy: float, x: np.ndarray, y: np.ndarray
) -> np.ndarray:
    """Height of the slab's top triangulation (two triangles per cell, diagonal v00-v11) at (x, y)."""
    ny, nx = heights.shape
    fx = np.clip(x / dx, 0, nx - 1 - 1e-9)
    fy = np.clip(y / dy, 0, ny - 1 - 1e-9)
    c = np.floor(fx).astype(int)
    r = np.floor(fy).astype(int)
    u = fx - c
    v = fy - r
    h00 = heights[r, c]
    h10 = heights[r, c + 1]
    h01 = heights[r + 1, c]
    h11 = heights[r + 1, c + 1]
    lower = h00 + u * (h10 - h00) + v * (h11 - h10)
    upper = h00 + v * (h01 - h00) + u * (h11 - h01)
    return np.where(u >= v, lower, upper)


def bench_pitch(repeats: int) -> StageResult:
    """Tile relief + closed slab at several pitches: time against height error."""
    from printapp.design import Design
    from printapp.mesh import slab_from_heightfield
    from printapp.texture import evaluate_texture, relief_heightfield, tile_grid_shape

    base_design = Design()
    texture, amplitude = base_design.texture, base_design.relief.amplitude_mm
    rng = np.random.default_rng(1)
    w, d = base_design.base.width_mm, base_design.base.depth_mm  # type: ignore[union-attr]
    probe = np.column_stack([rng.uniform(0, w, 20000), rng.uniform(0, d, 20000)])
    # Reference: the texture with all its octaves, evaluated exactly at the probe points,
    # on the value-to-height scale of a 10 um grid.
    ny, nx, ref_dy, ref_dx = tile_grid_shape(base_design.base, 0.01)  # type: ignore[arg-type]
    xx, yy = np.meshgrid(np.arange(nx) * ref_dx, np.arange(ny) * ref_dy)
    ref_grid = evaluate_texture(np.column_stack([xx.ravel(), yy.ravel()]), texture)
    lo, hi = float(ref_grid.min()), float(ref_grid.max())
    truth = (evaluate_texture(probe, texture) - lo) * (amplitude / (hi - lo))
    rows = []
    for pitch in (0.4, 0.2, 0.1, 0.05, 0.025):
        design = base_design.model_copy(
            update={"relief": base_design.relief.model_copy(update={"pitch_mm": pitch})}
        )

        def build(design: Design = design) -> Any:
            field_ = relief_heightfield(design)
            return field_, slab_from_heightfield(field_, 2.0)

        seconds, _ = median_seconds(build, repeats)
        field_, mesh = build()
        approx = _triangulated_value(
            field_.heights_mm, field_.pitch_x_mm, field_.pitch_y_mm, probe[:, 0], probe[:, 1]
        )
        # Compare shapes, not the per-grid peak-to-valley offset: remove the mean difference.
        diff = approx - truth
        diff -= diff.mean()
        rows.append(
            {
                "pitch_mm": pitch,
                "triangles": int(len(mesh.faces)),
                "median_s": round(seconds, 5),
                "rms_height_error_um": round(float(np.sqrt(np.mean(diff**2))) * 1000, 3),
                "max_height_error_um": round(float(np.max(np.abs(diff))) * 1000, 3),
            }
        )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4), dpi=110)
        t = [r["median_s"] for r in rows]
        e = [r["rms_height_error_um"] for r in rows]
        ax.loglog(t, e, "o-", label="printapp tile slab")
        for r in rows:
            ax.annotate(f"{r['pitch_mm']} mm", (r["median_s"], r["rms_height_error_um"]), fontsize=8)
        ax.axhline(50.0, color="grey", ls=":", label="one 50 um layer")
        ax.set_xlabel("median time per tile (s)")
        ax.set_ylabel("RMS height error vs full texture (um)")
        ax.set_title("relief + closed slab, 20x20 mm fBm tile")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "pitch",
        "relief height field + closed slab mesh at several pitches (0.04725 mm = SL1 pixel)",
        rows,
        chart,
        ["error: triangulated top against the texture with all octaves, at 20,000 random points"],
    )


def bench_pipeline(repeats: int) -> StageResult:
    """The demo design end to end: median seconds per stage."""
    from printapp.pipeline import load_default_design, run_design

    design = load_default_design()
    per_stage: dict[str, list[float]] = {}
    totals = []
    with tempfile.TemporaryDirectory() as tmp:
        run_design(design, Path(tmp) / "warm", quiet=True)
        for i in range(min(repeats, 3)):
            start = time.perf_counter()
            outcome = run_design(design, Path(tmp) / f"run{i}", quiet=True)
            totals.append(time.perf_counter() - start)
            for stage, seconds in outcome.manifest["stages_s"].items():
                per_stage.setdefault(stage, []).append(seconds)
    rows = [{"stage": s, "median_s": round(statistics.median(v), 4)} for s, v in per_stage.items()]
    rows.append({"stage": "total", "median_s": round(statistics.median(totals), 4)})

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3), dpi=110)
        ax.barh([r["stage"] for r in rows], [r["median_s"] for r in rows])
        ax.set_xlabel("median seconds")
        ax.set_title("printapp demo, per stage (warm)")
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "pipeline", "the demo design end to end, warm (numba caches and imports loaded)", rows, chart
    )


def _lazy(module: str, function: str) -> Callable[[int], StageResult]:
    """A stage whose module (and its heavy imports) loads only when the stage runs."""

    def run(repeats: int) -> StageResult:
        import importlib

        return getattr(importlib.import_module(f"printapp.{module}"), function)(repeats)

    return run


STAGES: dict[str, Callable[[int], StageResult]] = {
    "noise": _lazy("bench_noise", "bench_noise"),  # beside the plain kernel and pyfastnoisesimd
    "frames": _lazy("bench_lic", "bench_frames"),  # orthonormal bases
    "lic": _lazy("bench_lic", "bench_lic"),  # beside rlic
    "slice": _lazy("bench_slice", "bench_slice"),  # beside PrusaSlicer
    "mesh": _lazy("bench_emboss", "bench_emboss"),  # height map to STL beside Blender
    "brdf": _lazy("bench_brdf", "bench_brdf"),  # beside embreex
    "pitch": bench_pitch,
    "adaptive": _lazy("bench_adaptive", "bench_adaptive"),
    "mie": _lazy("bench_mie", "bench_mie"),  # Lorenz-Mie beside miepython's JIT; medium vs body albedo
    "pipeline": bench_pipeline,
    "fit": _lazy("bench_fit", "bench_fit"),  # photos to noise parameters, beside the random-phase texture
    "render": _lazy("bench_render", "bench_render"),  # model, table and geometry against distance
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
