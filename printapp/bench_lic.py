"""``printapp bench lic`` and ``printapp bench frames``.

lic: pixels per second of printapp's 2-D LIC (fast Stalling-Hege box kernel, and
per pixel) beside the ``rlic`` package (Rust) at the same kernel length, in the same
run; and time against accuracy (correlation with a slow reference: per pixel, RK4,
0.1-pixel steps) for step size and the fast method's deposit radius.

frames: normals per second for Duff's and Frisvad's bases, and their orthonormality
error against 1 + n.z, where Frisvad's fails.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench import StageResult, median_seconds


def _test_field(n: int) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.mgrid[0:n, 0:n].astype(float)
    return -(y - n / 2 + 0.3), (x - n / 2 + 0.2) + 0.25 * n * np.sin(y / (n / 40))


def bench_lic(repeats: int) -> StageResult:
    from noise.lic import lic2d

    try:
        import rlic
    except ImportError:
        rlic = None
    rng = np.random.default_rng(0)
    rows: list[dict[str, Any]] = []
    for size in (512, 2048):
        texture = rng.random((size, size)) + 1e-3  # rlic wants positive texture values
        u, v = _test_field(size)
        reps = repeats if size == 512 else max(1, min(repeats, 2))
        for length in (10, 20, 30, 50):
            fast_s, _ = median_seconds(lambda t=texture, u=u, v=v, n=length: lic2d(u, v, t, length=n), reps)
            row: dict[str, Any] = {
                "size": size,
                "length_px": length,
                "fast_Mpx_s": round(size * size / fast_s / 1e6, 2),
            }
            if size == 512:
                pp_s, _ = median_seconds(
                    lambda t=texture, u=u, v=v, n=length: lic2d(u, v, t, length=n, fast=False), reps
                )
                row["per_pixel_Mpx_s"] = round(size * size / pp_s / 1e6, 2)
            else:
                row["per_pixel_Mpx_s"] = None
            if rlic is not None:
                kernel = np.ones(2 * length + 1)
                rlic_s, _ = median_seconds(
                    lambda t=texture, u=u, v=v, k=kernel: rlic.convolve(t, u, v, kernel=k), reps
                )
                row["rlic_Mpx_s"] = round(size * size / rlic_s / 1e6, 2)
                row["fast_vs_rlic"] = round(rlic_s / fast_s, 2)
            else:
                row["rlic_Mpx_s"] = None
                row["fast_vs_rlic"] = None
            rows.append(row)

    # Time against accuracy at 512^2.
    size = 512
    texture = rng.random((size, size)) + 1e-3
    u, v = _test_field(size)
    sweep = []
    for length in (10, 30):
        reference = lic2d(u, v, texture, length=length, fast=False, step=0.1, integrator="rk4")
        settings = [("per pixel", {"fast": False, "step": s}) for s in (0.25, 0.5, 1.0)]
        settings += [
            (f"fast, offset {o}", {"step": s, "max_offset": o}) for s in (0.25, 0.5, 1.0) for o in (0.25, 0.5)
        ]
        for label, kwargs in settings:
            seconds, _ = median_seconds(lambda kw=kwargs, n=length: lic2d(u, v, texture, length=n, **kw), 1)
            out = lic2d(u, v, texture, length=length, **kwargs)
            sweep.append(
                {
                    "length_px": length,
                    "method": label,
                    "step_px": kwargs["step"],
                    "Mpx_s": round(size * size / seconds / 1e6, 2),
                    "correlation": round(float(np.corrcoef(out.ravel(), reference.ravel())[0, 1]), 4),
                }
            )
        if rlic is not None:
            kernel = np.ones(2 * length + 1)
            seconds, _ = median_seconds(lambda k=kernel: rlic.convolve(texture, u, v, kernel=k), 1)
            out = rlic.convolve(texture, u, v, kernel=kernel)
            sweep.append(
                {
                    "length_px": length,
                    "method": "rlic (nearest-pixel model)",
                    "step_px": None,
                    "Mpx_s": round(size * size / seconds / 1e6, 2),
                    "correlation": round(float(np.corrcoef(out.ravel(), reference.ravel())[0, 1]), 4),
                }
            )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), dpi=110)
        for size, marker in ((512, "o"), (2048, "s")):
            sel = [r for r in rows if r["size"] == size]
            lengths = [r["length_px"] for r in sel]
            axes[0].plot(
                lengths, [r["fast_Mpx_s"] for r in sel], marker + "-", label=f"printapp fast, {size}²"
            )
            if sel[0]["rlic_Mpx_s"] is not None:
                axes[0].plot(lengths, [r["rlic_Mpx_s"] for r in sel], marker + "--", label=f"rlic, {size}²")
            if sel[0]["per_pixel_Mpx_s"] is not None:
                axes[0].plot(
                    lengths,
                    [r["per_pixel_Mpx_s"] for r in sel],
                    marker + ":",
                    label=f"printapp per pixel, {size}²",
                )
        axes[0].set_xlabel("streamline half-length (pixels)")
        axes[0].set_ylabel("million pixels per second")
        axes[0].set_yscale("log")
        axes[0].set_title("2-D LIC throughput, box kernel, 2 cores")
        axes[0].legend(fontsize=7)
        for length, colour in ((10, "C0"), (30, "C1")):
            sel = [r for r in sweep if r["length_px"] == length]
            for r in sel:
                marker = "o" if r["method"].startswith("fast") else "s" if r["method"] == "per pixel" else "*"
                axes[1].loglog(1.0 / r["Mpx_s"], max(1 - r["correlation"], 1e-4), marker, color=colour)
                tag = r["method"].replace("fast, offset ", "f") + (
                    f" h{r['step_px']}" if r["step_px"] else ""
                )
                axes[1].annotate(tag, (1.0 / r["Mpx_s"], max(1 - r["correlation"], 1e-4)), fontsize=6)
        axes[1].axhline(0.01, color="grey", ls=":")
        axes[1].set_xlabel("seconds per million pixels")
        axes[1].set_ylabel("1 - correlation with the reference")
        axes[1].set_title("time vs accuracy (L = 10 blue, 30 orange)")
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    notes = ["reference: per pixel, RK4, 0.1-pixel steps, bilinear field and texture"]
    if rlic is None:
        notes.append("rlic is not installed (pip install rlic): no peer in this run")
    result = StageResult("lic", "2-D line integral convolution beside rlic", rows, chart, notes)
    result.extra = {"accuracy_sweep": sweep}
    return result


def bench_frames(repeats: int) -> StageResult:
    from noise.frames import onb

    rng = np.random.default_rng(0)
    n = 1_000_000
    uniform = rng.normal(size=(n // 2, 3))
    uniform /= np.linalg.norm(uniform, axis=1, keepdims=True)
    eps = 10 ** rng.uniform(-12, 0, n - n // 2)
    r = np.sqrt(eps * (2 - eps))
    phi = rng.uniform(0, 2 * np.pi, eps.size)
    clustered = np.column_stack([r * np.cos(phi), r * np.sin(phi), -1 + eps])
    normals64 = np.concatenate([uniform, clustered])
    one_plus_z = 1 + normals64[:, 2]
    rows = []
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    edges = np.logspace(-12, 0, 25)
    for dtype in (np.float32, np.float64):
        normals = normals64.astype(dtype)
        for method in ("duff", "frisvad"):
            seconds, _ = median_seconds(lambda m=method, x=normals: onb(x, m), repeats)
            b1, b2 = onb(normals, method)
            basis = np.stack([b1, b2, normals], axis=1).astype(np.float64)
            error = np.abs(np.einsum("kij,klj->kil", basis, basis) - np.eye(3)).max(axis=(1, 2))
            rows.append(
                {
                    "method": method,
                    "dtype": np.dtype(dtype).name,
                    "M_normals_s": round(n / seconds / 1e6, 1),
                    "max_error": float(f"{error.max():.3g}"),
                    "max_error_far_from_pole": float(f"{error[one_plus_z > 0.5].max():.3g}"),
                }
            )
            which = np.digitize(one_plus_z, edges)
            worst = np.array(
                [error[which == b].max() if np.any(which == b) else np.nan for b in range(1, len(edges))]
            )
            curves[f"{method} {np.dtype(dtype).name}"] = (np.sqrt(edges[1:] * edges[:-1]), worst)

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.5, 4), dpi=110)
        for label, (x, y) in curves.items():
            ax.loglog(x, np.maximum(y, 1e-18), "-" if "duff" in label else "--", label=label)
        ax.set_xlabel("1 + n.z (distance from the south pole)")
        ax.set_ylabel("max |B B^T - I|")
        ax.set_title("orthonormal bases near n = (0, 0, -1)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "frames", "orthonormal bases from 1e6 unit normals (half near the south pole)", rows, chart
    )
