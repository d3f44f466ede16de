"""``printapp bench pitch``: the tile's relief and closed slab at several pitches, time against error."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, median_seconds


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
