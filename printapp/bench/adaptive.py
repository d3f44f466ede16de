"""``printapp bench adaptive``: triangles of the top against the height error they leave, beside QEM.

The 10 mm, 0.2 mm-deep fBm map of ``bench mesh`` at the printer's pitch (257^2 samples,
39 um), and the demo relief (424^2 samples, 47 um), slabbed with printapp's adaptive top
(greedy insertion, :mod:`printapp.adaptive_slab`) at several error bounds, beside the full
grid and beside quadric error metrics (``fast-simplification``, the peer), whose target
count is searched (bisection, 12 steps) for the fewest triangles that keep every sample
within the same bound: triangles, the largest error actually left, time (median).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, median_seconds

BOUNDS_UM = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)


def _qem_for_bound(
    heights: np.ndarray, px: float, base: float, bound_mm: float
) -> tuple[int, float, float] | None:
    """The fewest QEM triangles that keep every sample within the bound: (triangles, error, seconds)."""
    import time

    try:
        import fast_simplification
    except ImportError:
        return None
    from noise.heightfield import HeightField
    from printapp.adaptive_slab import top_heights
    from printapp.slab import slab_arrays

    vertices, faces = slab_arrays(HeightField(heights, px, px), base)

    def error_of(keep: int) -> tuple[int, float]:
        v, f = fast_simplification.simplify(vertices, faces, target_reduction=1.0 - keep / len(faces))
        top, covered = top_heights(v, f, heights.shape, px, px)
        err = np.where(covered >= 0, np.abs(top - base - heights), np.inf)
        return len(f), float(err.max())

    start = time.perf_counter()
    lo, hi = 16, len(faces)
    best = (len(faces), 0.0)
    for _ in range(12):
        mid = int(np.sqrt(lo * hi))
        if mid <= lo or mid >= hi:
            break
        count, err = error_of(mid)
        if err <= bound_mm:
            hi, best = mid, (count, err)
        else:
            lo = mid
    return best[0], best[1], time.perf_counter() - start


def _row(
    relief: str, method: str, bound_um: float, triangles: int, error_mm: float, seconds: float, full: int
) -> dict[str, Any]:
    return {
        "relief": relief,
        "method": method,
        "bound_um": bound_um,
        "triangles": triangles,
        "max_error_um": round(error_mm * 1000, 4),
        "median_s": round(seconds, 4),
        "fewer_than_full": round(full / triangles, 2),
    }


def adaptive_chart(rows: list[dict], reliefs: Iterable[str], path: Path) -> None:
    """Largest height error against triangles, one panel per relief, greedy insertion beside QEM."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    fig, axes = plt.subplots(1, len(reliefs), figsize=(11, 4), dpi=110)
    for ax, name in zip(axes, reliefs, strict=True):
        for method, style in (("greedy insertion", "o-"), ("QEM (fast-simplification), searched", "s--")):
            pick = [r for r in rows if r["relief"] == name and r["method"] == method]
            if pick:
                ax.semilogx(
                    [r["triangles"] for r in pick], [r["max_error_um"] for r in pick], style, label=method
                )
        full = next(r for r in rows if r["relief"] == name and r["method"] == "full grid")
        ax.plot([full["triangles"]], [0.0], "k^", label="full grid")
        ax.xaxis.set_minor_formatter(NullFormatter())  # crowded labels between decades
        ax.set_xlabel("triangles in the slab")
        ax.set_ylabel("largest height error at the samples (um)")
        ax.set_title(name, fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def bench_adaptive(repeats: int) -> StageResult:
    """Triangles of the adaptive top against the height error they leave, beside the full grid and QEM."""
    import noise
    from noise.heightfield import HeightField
    from printapp.adaptive_slab import adaptive_slab_arrays
    from printapp.design_io import load_default_design
    from printapp.slab import slab_arrays
    from printapp.texture import relief_heightfield

    axis = np.linspace(0.0, 6.0, 257)
    fbm = noise.fbm_grid(axis, axis, octaves=5, seed=3)
    fbm = (fbm - fbm.min()) / (fbm.max() - fbm.min()) * 0.2
    demo = relief_heightfield(load_default_design())
    reliefs = {
        "fBm 10 mm at 39 um": (fbm, 10.0 / 256),
        "demo relief 20 mm at 47 um": (demo.heights_mm, demo.pitch_x_mm),
    }
    rows: list[dict[str, Any]] = []
    for name, (relief, px) in reliefs.items():
        side = (relief.shape[1] - 1) * px
        full_s, _ = median_seconds(lambda r=relief, p=px: slab_arrays(HeightField(r, p, p), 2.0), repeats)
        _, full_faces = slab_arrays(HeightField(relief, px, px), 2.0)
        rows.append(_row(name, "full grid", 0.0, len(full_faces), 0.0, full_s, len(full_faces)))
        for bound in BOUNDS_UM:
            seconds, _ = median_seconds(
                lambda r=relief, s=side, b=bound: adaptive_slab_arrays(r, s, s, 2.0, b / 1000), repeats
            )
            _, faces, worst = adaptive_slab_arrays(relief, side, side, 2.0, bound / 1000)
            rows.append(_row(name, "greedy insertion", bound, len(faces), worst, seconds, len(full_faces)))
            qem = _qem_for_bound(relief, px, 2.0, bound / 1000) if bound >= 2.0 else None
            if qem is not None:
                method = "QEM (fast-simplification), searched"
                rows.append(_row(name, method, bound, qem[0], qem[1], qem[2], len(full_faces)))
    notes = (
        []
        if any("QEM" in r["method"] for r in rows)
        else ["fast-simplification is not installed: no QEM rows"]
    )

    def chart(path: Path) -> None:
        adaptive_chart(rows, reliefs, path)

    return StageResult(
        "adaptive",
        "error-bounded adaptive top: triangles against height error, beside QEM",
        rows,
        chart,
        notes,
    )
