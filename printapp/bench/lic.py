"""``printapp bench lic``: pixels per second of printapp's 2-D LIC (the flow map, the default; Stalling &
Hege; the exact per-pixel method) beside the ``rlic`` package (Rust) in the same run,
all timed in turn within every repeat; and time against accuracy (correlation with a
slow reference: the exact method, RK4, 0.1-pixel steps) for the methods' settings.

rlic steps from pixel edge to pixel edge, one kernel tap per pixel crossed, so a kernel
of 2L + 1 taps reaches L pixels only along the axes (L / sqrt(2) on a diagonal). It is
timed twice: with 2L + 1 taps (the same tap count) and with the taps that span L
pixels on this field on average (the same streamline length in pixels, which is what
``length`` means here).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, interleaved_seconds

LENGTHS_PX = (10, 20, 30, 50)
TARGET_RATIO = 2.0
TARGET_CORRELATION = 0.99
DEFAULT_SETTING = "flow map, RK2, h 1.0"  # lic2d's defaults


def _test_field(n: int) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.mgrid[0:n, 0:n].astype(float)
    return -(y - n / 2 + 0.3), (x - n / 2 + 0.2) + 0.25 * n * np.sin(y / (n / 40))


def pixel_crossings_per_px(u: np.ndarray, v: np.ndarray) -> float:
    """Pixel edges a straight path crosses per pixel of length, |cos| + |sin|, averaged over the field."""
    norm = np.hypot(u, v)
    ok = norm > 0
    return float(np.mean((np.abs(u[ok]) + np.abs(v[ok])) / norm[ok]))


def _rlic_run(rlic: Any, texture: np.ndarray, u: np.ndarray, v: np.ndarray, taps: int) -> Any:
    """rlic with a box kernel of 2 * taps + 1 ones."""
    kernel = np.ones(2 * taps + 1)
    return lambda: rlic.convolve(texture, u, v, kernel=kernel)


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    return round(float(np.corrcoef(a.ravel(), b.ravel())[0, 1]), 4)


def bench_lic(repeats: int) -> StageResult:
    """2-D LIC throughput beside rlic, and time against accuracy for the methods' settings."""
    from noise.lic import lic2d

    try:
        import rlic
    except ImportError:
        rlic = None
    rng = np.random.default_rng(0)
    rows: list[dict[str, Any]] = []
    notes = ["reference: exact per-pixel method, RK4, 0.1-pixel steps, bilinear field and texture"]
    for size in (512, 2048):
        texture = rng.random((size, size)) + 1e-3  # rlic wants positive texture values
        u, v = _test_field(size)
        crossings = pixel_crossings_per_px(u, v)
        reps = repeats if size == 512 else max(1, min(repeats, 3))
        for length in LENGTHS_PX:
            fns = {
                "flowmap": lambda t=texture, u=u, v=v, n=length: lic2d(u, v, t, length=n),
                "stalling_hege": lambda t=texture, u=u, v=v, n=length: lic2d(
                    u, v, t, length=n, method="stalling-hege"
                ),
            }
            if size == 512:
                fns["exact"] = lambda t=texture, u=u, v=v, n=length: lic2d(u, v, t, length=n, method="exact")
            taps_px = round(length * crossings)
            if rlic is not None:
                fns["rlic_taps"] = _rlic_run(rlic, texture, u, v, length)
                fns["rlic_px"] = _rlic_run(rlic, texture, u, v, taps_px)
            seconds, _, cores = interleaved_seconds(fns, reps)
            row: dict[str, Any] = {"size": size, "length_px": length}
            for key, value in seconds.items():
                row[f"{key}_Mpx_s"] = round(size * size / value / 1e6, 2)
            row["flowmap_cores"] = round(cores["flowmap"], 2)
            if rlic is not None:
                row["rlic_taps_px"] = taps_px
                row["flowmap_vs_rlic_taps"] = round(seconds["rlic_taps"] / seconds["flowmap"], 2)
                row["flowmap_vs_rlic_px"] = round(seconds["rlic_px"] / seconds["flowmap"], 2)
            rows.append(row)
        notes.append(
            f"{size}²: the test field crosses {crossings:.3f} pixel edges per pixel of length, so rlic "
            "spans L pixels with about that many taps per pixel"
        )

    # Time against accuracy at 512^2.
    size = 512
    texture = rng.random((size, size)) + 1e-3
    u, v = _test_field(size)
    crossings = pixel_crossings_per_px(u, v)
    sweep: list[dict[str, Any]] = []
    settings: list[tuple[str, dict[str, Any]]] = [
        (f"flow map, {integ.upper()}, h {h}", {"integrator": integ, "step": h})
        for integ, h in (("rk4", 0.5), ("rk4", 0.75), ("rk4", 1.0), ("rk4", 1.25), ("rk2", 1.0))
    ]
    settings += [
        (f"exact, {integ.upper()}, h {h}", {"method": "exact", "integrator": integ, "step": h})
        for integ, h in (("rk2", 0.5), ("rk2", 1.0), ("rk4", 1.0))
    ]
    settings += [
        (f"Stalling-Hege, offset {o}, h {h}", {"method": "stalling-hege", "step": h, "max_offset": o})
        for h in (0.5, 1.0)
        for o in (0.25, 0.5)
    ]
    for length in (10, 30, 50):
        reference = lic2d(u, v, texture, length=length, method="exact", step=0.1)
        fns = {
            label: (lambda kw=kwargs, n=length: lic2d(u, v, texture, length=n, **kw))
            for label, kwargs in settings
        }
        if rlic is not None:
            fns["rlic, 2L+1 taps"] = _rlic_run(rlic, texture, u, v, length)
            fns["rlic, L pixels"] = _rlic_run(rlic, texture, u, v, round(length * crossings))
        seconds, last, _ = interleaved_seconds(fns, max(1, min(repeats, 3)))
        steps = dict(settings)
        for label, value in seconds.items():
            sweep.append(
                {
                    "length_px": length,
                    "method": label,
                    "step_px": steps[label]["step"] if label in steps else None,
                    "Mpx_s": round(size * size / value / 1e6, 2),
                    "correlation": _correlation(last[label], reference),
                }
            )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(12.5, 4.4), dpi=110)
        series = (
            ("flowmap", "printapp flow map", "-"),
            ("stalling_hege", "printapp Stalling-Hege", "-."),
            ("exact", "printapp exact", ":"),
            ("rlic_taps", "rlic, 2L+1 taps", "--"),
            ("rlic_px", "rlic, L pixels", (0, (1, 3))),
        )
        for size, marker in ((512, "o"), (2048, "s")):
            sel = [r for r in rows if r["size"] == size]
            lengths = [r["length_px"] for r in sel]
            for colour, (key, label, style) in enumerate(series):
                if f"{key}_Mpx_s" in sel[0]:
                    values = [r[f"{key}_Mpx_s"] for r in sel]
                    axes[0].plot(
                        lengths, values, marker, ls=style, color=f"C{colour}", label=f"{label}, {size}²"
                    )
        axes[0].set_xlabel("streamline half-length L (pixels)")
        axes[0].set_ylabel("million pixels per second")
        axes[0].set_yscale("log")
        axes[0].set_title("2-D LIC throughput, box kernel (printapp 2 threads, rlic 1)")
        axes[0].legend(fontsize=6, ncol=2)
        for length, colour in ((10, "C0"), (30, "C1"), (50, "C2")):
            for r in (r for r in sweep if r["length_px"] == length):
                method = r["method"]
                marker = "o" if method.startswith("flow") else "*" if method.startswith("rlic") else "s"
                point = (1.0 / r["Mpx_s"], max(1 - r["correlation"], 1e-4))
                axes[1].loglog(*point, marker, color=colour)
                tag = method.replace("Stalling-Hege, offset ", "S&H ").replace("flow map, ", "fm ")
                axes[1].annotate(tag, point, fontsize=5)
        axes[1].axhline(1 - TARGET_CORRELATION, color="grey", ls=":")
        axes[1].set_xlabel("seconds per million pixels")
        axes[1].set_ylabel("1 - correlation with the reference")
        axes[1].set_title("time vs accuracy, 512² (L = 10 blue, 30 orange, 50 green)")
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    if rlic is None:
        notes.append("rlic is not installed (pip install rlic): no peer in this run")
    else:
        flow = [r for r in sweep if r["method"] == DEFAULT_SETTING]
        worst_corr = min(r["correlation"] for r in flow)
        worst_ratio = min(r["flowmap_vs_rlic_px"] for r in rows)
        worst_taps = min(r["flowmap_vs_rlic_taps"] for r in rows)
        met = worst_ratio >= TARGET_RATIO and worst_corr >= TARGET_CORRELATION
        notes.append(
            f"target ({TARGET_RATIO}x rlic at the same length, correlation >= {TARGET_CORRELATION}): "
            f"{'met' if met else 'not met'} by the default flow map: worst ratio {worst_ratio}x at the same "
            f"length in pixels ({worst_taps}x at the same tap count), worst correlation {worst_corr}"
        )
    result = StageResult("lic", "2-D line integral convolution beside rlic", rows, chart, notes)
    result.extra = {"accuracy_sweep": sweep}
    return result
