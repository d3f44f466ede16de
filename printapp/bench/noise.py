"""``printapp bench noise``: noise kernels against the plain per-point version and a peer.

Speed: samples per second for scattered points (dense, as on a printed surface, and
sparse) and for regular 2-D and 3-D grids, measured in the same run for

* printapp's kernels (``noise.sparse_convolution`` and the ``*_grid`` fast paths),
* the plain per-point numba implementation of the same formula
  (:mod:`printapp.bench.reference.scn_plain_numba`),
* pyfastnoisesimd's SIMD Perlin noise, a cheaper noise, for scale (when installed).

Accuracy against cost: impulses per cell N against time per sample, the distance
of the value histogram from its large-N limit, and the error of the radially
averaged power spectrum against the analytic spectrum of the impulse process.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, median_seconds

IMPULSE_COUNTS = (1, 2, 4, 8, 16, 30, 64)
_REFERENCE_N = 256
SCATTERED_POINTS = 1_000_000
"""Points of each scattered case (and of the 2-D grid, its side squared; the 3-D grid, cubed)."""
SLICE_SIDE = 1024
"""Side of the 2-D slice whose histogram and spectrum the impulse sweep measures."""
SWEEP_POINTS = 200_000
"""Dense scattered points the impulse sweep times."""


def _perlin_peer() -> Any | None:
    try:
        import pyfastnoisesimd as fns
    except ImportError:
        return None
    generator = fns.Noise(seed=1, numWorkers=2)
    generator.noiseType = fns.NoiseType.Perlin
    generator.frequency = 1.0

    def perlin(points: np.ndarray) -> np.ndarray:
        coords = fns.empty_coords(points.shape[0])
        coords[:] = points.T.astype(np.float32)
        return generator.genFromCoords(coords)

    return perlin


def _count(n: int) -> str:
    exponent = round(math.log10(n))
    return f"1e{exponent}" if 10**exponent == n else f"{n:,}"


def _cases(rng: np.random.Generator) -> list[tuple[str, str, np.ndarray, tuple | None]]:
    n = SCATTERED_POINTS
    count = _count(n)
    side2 = round(n ** (1 / 2))
    side3 = round(n ** (1 / 3))
    x2 = np.arange(side2) * 0.05
    x3 = np.arange(side3) * 0.05
    gx, gy = np.meshgrid(x2, x2)
    g3 = np.stack(np.meshgrid(x3, x3, x3, indexing="ij"), axis=-1).reshape(-1, 3)[:, ::-1]
    return [
        (f"scattered 3-D, dense ({count} in 16^3 cells)", "dense points", rng.uniform(0, 16, (n, 3)), None),
        (
            f"scattered 3-D, sparse ({count} in 100^3 cells)",
            "sparse points",
            rng.uniform(0, 100, (n, 3)),
            None,
        ),
        (
            f"grid 2-D {side2}x{side2}, 20 samples/cell",
            "2-D grid",
            np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)]),
            (x2, x2),
        ),
        (f"grid 3-D {side3}^3, 20 samples/cell", "3-D grid", np.ascontiguousarray(g3), (x3, x3, x3)),
    ]


def _kernel_ft(rho: np.ndarray) -> np.ndarray:
    """3-D Fourier transform of cubic(v) = (1 - 4 v.v)^3 on |v| < 1/2, at frequency rho (cycles/unit)."""
    r = np.linspace(0.0, 0.5, 801)
    k = (1.0 - 4.0 * r**2) ** 3
    out = np.empty_like(rho)
    for i, f in enumerate(rho.ravel()):
        # 4 pi r^2 k(r) at f = 0, the limit of the sine transform below.
        integrand = 4.0 * np.pi * r**2 * k if f < 1e-9 else 2.0 * r * k * np.sin(2.0 * np.pi * f * r) / f
        out.flat[i] = np.trapezoid(integrand, r)
    return out


def analytic_slice_spectrum(freqs: np.ndarray) -> np.ndarray:
    """Radial power spectrum of the noise's z = 0 slice, up to a constant.

    Per cell, N impulses at independent uniform positions with amplitudes
    s_j a_j (a uniform on [0, 1), signs alternating) have the power spectrum
    N (E[a^2] - E[a]^2 |Phi(f)|^2) |K(f)|^2, Phi the cell's uniform-density transform
    (even N); a slice integrates it over f_z. Radially averaged over directions.

    Parameters
    ----------
    freqs : ndarray of float, shape (n,)
        Radial frequencies, in cycles per unit of the noise's coordinates (cells are 1 wide).

    Returns
    -------
    ndarray of float, shape (n,)
        The spectrum at ``freqs``, to an unknown constant factor: compare shapes only.
    """
    fz = np.linspace(-6.0, 6.0, 481)
    angles = np.linspace(0.0, np.pi / 2, 9)
    out = np.zeros_like(freqs)
    for theta in angles:
        fx = freqs[:, None] * math.cos(theta)
        fy = freqs[:, None] * math.sin(theta)
        rho = np.sqrt(fx**2 + fy**2 + fz[None, :] ** 2)
        phi2 = (np.sinc(fx) * np.sinc(fy) * np.sinc(fz[None, :])) ** 2
        p3 = (1.0 / 3.0 - 0.25 * phi2) * _kernel_ft(rho) ** 2
        out += np.trapezoid(p3, fz, axis=1)
    return out / len(angles)


def _radial_spectrum(values: np.ndarray, spacing: float, edges: np.ndarray) -> np.ndarray:
    spectrum = np.abs(np.fft.fft2(values - values.mean())) ** 2
    f = np.fft.fftfreq(values.shape[0], d=spacing)
    radius = np.hypot(f[:, None], f[None, :])
    sums = np.histogram(radius, bins=edges, weights=spectrum)[0]
    counts = np.histogram(radius, bins=edges)[0]
    return sums / np.maximum(counts, 1)


def _spectrum_error(measured: np.ndarray, analytic: np.ndarray) -> float:
    """RMS relative error of the spectrum's shape (both scaled to the same total)."""
    m = measured / measured.sum()
    a = analytic / analytic.sum()
    return float(np.sqrt(np.mean(((m - a) / a) ** 2)))


def _histogram_distance(values: np.ndarray, reference: np.ndarray) -> float:
    """Total-variation distance between the standardised value histograms (64 bins on [-4, 4])."""
    edges = np.linspace(-4, 4, 65)
    h = np.histogram((values - values.mean()) / values.std(), bins=edges)[0] / values.size
    r = np.histogram((reference - reference.mean()) / reference.std(), bins=edges)[0] / reference.size
    return 0.5 * float(np.abs(h - r).sum())


def bench_noise(repeats: int) -> StageResult:
    """Speed beside the plain reference and a peer; accuracy against impulses per cell."""
    import noise
    from printapp.bench.reference.scn_plain_numba import plain_sparse_convolution as plain

    perlin = _perlin_peer()
    rng = np.random.default_rng(0)
    rows: list[dict[str, Any]] = []
    short_names = []
    plain(np.zeros((1, 3)))  # compiled once here: each case then runs the slow kernel only as timed
    for name, short, points, axes in _cases(rng):
        short_names.append(short)
        fast_s, _ = median_seconds(lambda p=points: noise.sparse_convolution(p), repeats)
        kept: list[np.ndarray] = []
        plain_s, _ = median_seconds(
            lambda p=points, out=kept: out.append(plain(p)), max(1, min(repeats, 3)), warm=False
        )
        plain_values = kept[-1]
        worst = float(np.max(np.abs(noise.sparse_convolution(points) - plain_values)))
        row: dict[str, Any] = {
            "case": name,
            "printapp_Msps": round(points.shape[0] / fast_s / 1e6, 2),
            "plain_Msps": round(points.shape[0] / plain_s / 1e6, 2),
            "speedup_vs_plain": round(plain_s / fast_s, 1),
        }
        if axes is not None:
            grid_s, _ = median_seconds(lambda a=axes: noise.sparse_convolution_grid(*a), repeats)
            row["grid_path_Msps"] = round(points.shape[0] / grid_s / 1e6, 2)
            row["grid_speedup_vs_plain"] = round(plain_s / grid_s, 1)
            grid_values = noise.sparse_convolution_grid(*axes).ravel()
            worst = max(worst, float(np.max(np.abs(grid_values - plain_values))))
        else:
            row["grid_path_Msps"] = None
            row["grid_speedup_vs_plain"] = None
        row["max_abs_diff_vs_plain"] = float(f"{worst:.2e}")
        if perlin is not None:
            perlin_s, _ = median_seconds(lambda p=points: perlin(p), repeats)
            row["perlin_peer_Msps"] = round(points.shape[0] / perlin_s / 1e6, 1)
        else:
            row["perlin_peer_Msps"] = None
        rows.append(row)

    # Accuracy against N: values on a 1024^2 slice at 1/8 unit, timing on dense scattered points.
    spacing = 0.125
    axis = np.arange(SLICE_SIDE) * spacing
    # 0.25 to 2 cycles per unit holds nearly all the power; beyond, the kernel's spectrum
    # nears its first zero and relative errors measure aliasing, not the noise.
    edges = np.linspace(0.25, 2.0, 15)
    centres = 0.5 * (edges[1:] + edges[:-1])
    analytic = analytic_slice_spectrum(centres)
    reference = noise.sparse_convolution_grid(axis, axis, impulses=_REFERENCE_N).ravel()
    timing_points = rng.uniform(0, 16, (SWEEP_POINTS, 3))
    sweep = []
    for n_impulses in IMPULSE_COUNTS:
        seconds, _ = median_seconds(
            lambda n=n_impulses: noise.sparse_convolution(timing_points, impulses=n), repeats
        )
        values = noise.sparse_convolution_grid(axis, axis, impulses=n_impulses)
        sweep.append(
            {
                "impulses": n_impulses,
                "ns_per_sample": round(seconds / timing_points.shape[0] * 1e9, 1),
                "histogram_tv_distance": round(_histogram_distance(values.ravel(), reference), 4),
                "spectrum_rms_rel_error": round(
                    _spectrum_error(_radial_spectrum(values, spacing, edges), analytic), 4
                ),
            }
        )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes_ = plt.subplots(1, 3, figsize=(13, 4), dpi=110)
        labels = short_names
        x = np.arange(len(rows))
        axes_[0].bar(x - 0.3, [r["plain_Msps"] for r in rows], 0.2, label="plain per-point (numba)")
        axes_[0].bar(x - 0.1, [r["printapp_Msps"] for r in rows], 0.2, label="printapp, points")
        axes_[0].bar(x + 0.1, [r["grid_path_Msps"] or 0 for r in rows], 0.2, label="printapp, grid path")
        if perlin is not None:
            axes_[0].bar(
                x + 0.3, [r["perlin_peer_Msps"] for r in rows], 0.2, label="pyfastnoisesimd Perlin (peer)"
            )
        axes_[0].set_yscale("log")
        axes_[0].set_xticks(x, labels, fontsize=8)
        axes_[0].set_ylabel("million samples per second")
        axes_[0].set_title("sparse convolution noise, N = 30, 2 cores")
        axes_[0].legend(fontsize=7)
        t = [r["ns_per_sample"] for r in sweep]
        for ax, key, title in (
            (axes_[1], "histogram_tv_distance", "value histogram vs N = 256"),
            (axes_[2], "spectrum_rms_rel_error", "radial spectrum vs analytic"),
        ):
            ax.loglog(t, [r[key] for r in sweep], "o-")
            for r in sweep:
                ax.annotate(f"N={r['impulses']}", (r["ns_per_sample"], r[key]), fontsize=8)
            ax.set_xlabel("ns per sample (dense scattered points)")
            ax.set_ylabel(key.replace("_", " "))
            ax.set_title(title)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    notes = [
        "speedups are medians measured in this run; "
        "max_abs_diff_vs_plain checks that the fast paths compute the same noise",
        "Perlin noise is a different, cheaper noise (float32 SIMD gradient noise), shown for scale only",
    ]
    if perlin is None:
        notes.append("pyfastnoisesimd is not installed: `make bench` installs it")
    notes.append(
        "impulse sweep: "
        + "; ".join(
            f"N={r['impulses']}: {r['ns_per_sample']} ns, TV {r['histogram_tv_distance']}, "
            f"spectrum {r['spectrum_rms_rel_error']}"
            for r in sweep
        )
    )
    result = StageResult(
        "noise", "sparse convolution noise, samples per second beside the plain kernel", rows, chart, notes
    )
    result.extra = {"impulse_sweep": sweep}
    return result
