"""``printapp bench adaptive``: triangles of the top against the height error they leave.

The 10 mm, 0.2 mm-deep fBm map of ``bench mesh`` at the printer's pitch (resampled to a
257^2 grid, 39 um), slabbed with the adaptive (RTIN) top at several error bounds beside
the full grid: triangles, the largest error actually left at the samples, and time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from printapp.bench.timing import StageResult, median_seconds

BOUNDS_UM = (0.0, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0)


def bench_adaptive(repeats: int) -> StageResult:
    """Triangles of the adaptive top against the height error they leave, beside the full grid."""
    import noise
    from noise.heightfield import HeightField
    from printapp.slab import adaptive_slab_arrays, slab_arrays

    axis = np.linspace(0.0, 6.0, 257)
    relief = noise.fbm_grid(axis, axis, octaves=5, seed=3)
    relief = (relief - relief.min()) / (relief.max() - relief.min()) * 0.2
    full_s, _ = median_seconds(lambda: slab_arrays(HeightField(relief, 10 / 256, 10 / 256), 2.0), repeats)
    _, full_faces = slab_arrays(HeightField(relief, 10 / 256, 10 / 256), 2.0)
    rows = [
        {
            "bound_um": "full grid",
            "triangles": len(full_faces),
            "max_error_um": 0.0,
            "median_s": round(full_s, 4),
        }
    ]
    for bound in BOUNDS_UM:
        seconds, _ = median_seconds(
            lambda b=bound: adaptive_slab_arrays(relief, 10.0, 10.0, 2.0, b / 1000), repeats
        )
        _, faces, worst = adaptive_slab_arrays(relief, 10.0, 10.0, 2.0, bound / 1000)
        rows.append(
            {
                "bound_um": bound,
                "triangles": len(faces),
                "max_error_um": round(worst * 1000, 4),
                "median_s": round(seconds, 4),
            }
        )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4), dpi=110)
        adaptive = rows[1:]
        ax.semilogx(
            [r["triangles"] for r in adaptive],
            [r["max_error_um"] for r in adaptive],
            "o-",
            label="adaptive (RTIN)",
        )
        for r in adaptive:
            ax.annotate(f"bound {r['bound_um']:g}", (r["triangles"], r["max_error_um"]), fontsize=7)
        ax.plot([rows[0]["triangles"]], [0.0], "s", label="full grid")
        ax.axhline(50.0 / 2, color="grey", ls=":", label="half a 50 um layer")
        ax.set_xlabel("triangles in the slab")
        ax.set_ylabel("largest height error at the samples (um)")
        ax.set_title("adaptive top, 10 mm tile at 39 um")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult("adaptive", "error-bounded adaptive top: triangles against height error", rows, chart)
