"""``printapp bench render``: the three representations of a relief, time against image error.

A tile with many small relief features is rendered from several distances as (a) its
fitted compact BRDF on the flat base, (b) its traced BRDF table on the flat base, and
(c) its displaced geometry; each image is compared with a high-sample render of (c).
The chart backs the chooser's threshold (:data:`render.representation.GEOMETRY_FROM_FEATURES_PER_PIXEL`):
where features cover less than a pixel, a BRDF shows what geometry shows, far faster.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from printapp.bench.timing import StageResult

if TYPE_CHECKING:
    from printapp.design import Design

_DISTANCES = (0.5, 1.0, 2.0, 4.0, 8.0)
# Also the whole tile at coarser resolutions (a long lens from far away): the tile fills the
# frame while its features shrink below a pixel, so the representations' costs, not the
# background's, are compared.
_COARSE = ((240, 180), (120, 90), (60, 45))
_SPP = 64
_REFERENCE_SPP = 1024
_SIZE = (480, 360)


def bench_design() -> Design:
    """The test design: a 30 mm tile of 0.3 mm fBm features, sampled at 0.03 mm (2 million triangles)."""
    from printapp.design import Design

    return Design.model_validate(
        {
            "name": "bench render tile",
            "base": {"shape": "tile", "width_mm": 30.0, "depth_mm": 30.0, "thickness_mm": 2.0},
            "texture": {"kind": "fbm", "feature_size_mm": 0.3, "octaves": 2, "seed": 3},
            "relief": {"amplitude_mm": 0.06, "pitch_mm": 0.03},
            "brdf": {"rays": 200_000},
            "render": {"width_px": _SIZE[0], "height_px": _SIZE[1], "spp": _SPP},
        }
    )


def luma(image: np.ndarray) -> np.ndarray:
    return image @ np.array([0.2126, 0.7152, 0.0722])


def representation_error(
    first: np.ndarray, second: np.ndarray, reference: np.ndarray, reference_noise_var: float, mask: np.ndarray
) -> tuple[float, float]:
    """Systematic and noise error of a representation against the reference, relative to its mean.

    ``first`` and ``second`` are the same render with two seeds: half the mean squared
    difference between them is the render's noise variance per pixel. The systematic
    error is what remains of the mean squared difference to the reference once both
    noises are taken off: ``sqrt(max(mean (a - ref)^2 - var_a - var_ref, 0)) / mean ref``,
    over the object's pixels.
    """
    a1, a2, ref = luma(first)[mask], luma(second)[mask], luma(reference)[mask]
    var_a = float(np.mean((a1 - a2) ** 2)) / 2.0
    mse = float(np.mean((0.5 * (a1 + a2) - ref) ** 2))
    # The mean of the two renders has half the noise variance of one.
    bias2 = mse - var_a / 2.0 - reference_noise_var
    scale = max(float(np.mean(ref)), 1e-12)
    return float(np.sqrt(max(bias2, 0.0))) / scale, float(np.sqrt(var_a)) / scale


def render_shot(
    design: Design,
    target: Any,
    surface: Any,
    framed: Any,
    scale: float,
    spp: int,
    seed: int,
    size: tuple[int, int],
    *,
    coverage: bool = False,
) -> np.ndarray:
    """``target`` (a mesh; with ``surface`` its BRDF, else its own geometry) as the preview camera sees
    ``framed`` (the relief's mesh) from ``scale`` times the preview's distance, in linear RGB."""
    from render.mitsuba_adapter import PREVIEW_FOV_DEG, render_resin_mesh

    r = design.render
    return render_resin_mesh(
        np.asarray(target.vertices),
        np.asarray(target.faces),
        body_albedo=design.material.body_albedo,
        refractive_index=design.material.refractive_index,
        width_px=size[0],
        height_px=size[1],
        spp=spp,
        seed=seed,
        elevation_rad=r.elevation_rad,
        azimuth_rad=r.azimuth_rad,
        fov_deg=PREVIEW_FOV_DEG,
        surface=surface,
        distance_scale=scale,
        frame_vertices=np.asarray(framed.vertices),
        coverage=coverage,
    )


def render_chart(rows: list[dict[str, Any]], path: Path) -> None:
    """Error against pixels per feature, error against time, and time to 2 % noise, per representation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    from render.representation import GEOMETRY_FROM_FEATURES_PER_PIXEL

    fig, (left, right, third) = plt.subplots(1, 3, figsize=(15, 4), dpi=110)
    for mode, marker in (("model", "o"), ("table", "s"), ("geometry", "^")):
        for series, ls in (("distance", "-"), ("resolution", "--")):
            sel = sorted(
                (row for row in rows if row["mode"] == mode and row["series"] == series),
                key=lambda row: row["pixels_per_feature"],
            )
            label = f"{mode} ({'camera backs off' if series == 'distance' else 'coarser image'})"
            left.plot(
                [row["pixels_per_feature"] for row in sel],
                [row["error_vs_geometry"] * 100 for row in sel],
                marker=marker,
                ls=ls,
                label=label,
            )
            third.plot(
                [row["pixels_per_feature"] for row in sel],
                [row["time_to_2pct_s"] for row in sel],
                marker=marker,
                ls=ls,
                label=label,
            )
            right.plot(
                [row["median_s"] for row in sel],
                [row["error_vs_geometry"] * 100 for row in sel],
                marker=marker,
                ls="",
                label=label,
            )
    left.axhline(5.0, color="grey", ls=":", lw=1)
    left.axvline(GEOMETRY_FROM_FEATURES_PER_PIXEL, color="grey", ls="--", lw=1, label="chooser threshold")
    left.set_xscale("log")
    left.set_xticks([0.25, 0.5, 1, 2, 4], ["0.25", "0.5", "1", "2", "4"])
    left.minorticks_off()
    left.set_xlabel("pixels per relief feature (far <- -> near)")
    left.set_ylabel("image error vs geometry reference (%)")
    left.legend(fontsize=6)
    right.set_xscale("log")
    right.xaxis.set_minor_formatter(NullFormatter())  # crowded labels between decades
    right.set_xlabel(f"render time at {_SPP} spp (s)")
    right.set_ylabel("image error (%)")
    right.axhline(5.0, color="grey", ls=":", lw=1)
    right.legend(fontsize=6)
    third.set_xscale("log")
    third.set_yscale("log")
    third.set_xticks([0.25, 0.5, 1, 2, 4], ["0.25", "0.5", "1", "2", "4"])
    third.minorticks_off()
    third.set_xlabel("pixels per relief feature (far <- -> near)")
    third.set_ylabel(f"time to 2 % noise (s; from the noise at {_SPP} spp)")
    third.legend(fontsize=6)
    fig.suptitle("three representations of a relief: when a BRDF can stand in for geometry", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def bench_render(repeats: int) -> StageResult:
    """Compact BRDF, traced table and geometry of one relief: time against image error by distance."""
    from printapp.relief import build_relief
    from printapp.rendering import base_shape, predict_for_design
    from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing, choose_variant
    from render.representation import GEOMETRY_FROM_FEATURES_PER_PIXEL, compact_surface, table_surface

    choose_variant()
    design = bench_design()
    start = time.perf_counter()
    relief = build_relief(design)
    build_s = time.perf_counter() - start
    mesh = relief.mesh
    grey = float(np.dot(design.material.body_albedo, [0.2126, 0.7152, 0.0722]))
    start = time.perf_counter()
    predicted = predict_for_design(design, relief.patch)
    brdf_s = time.perf_counter() - start
    start = time.perf_counter()
    table = table_surface(
        relief.patch.heights_mm,
        relief.patch.pitch_x_mm,
        relief.patch.pitch_y_mm,
        ior=design.material.refractive_index,
        body_rgb=design.material.body_albedo,
        grey=grey,
        rays=40_000,
    )
    table_s = time.perf_counter() - start
    base = base_shape(design, relief)
    model = compact_surface(predicted.fit.model, design.material.body_albedo, grey)
    shapes = {"model": (base, model), "table": (base, table), "geometry": (mesh, None)}

    def shot(
        mode: str, scale: float, spp: int, seed: int, coverage: bool = False, size: tuple[int, int] = _SIZE
    ) -> np.ndarray:
        target, surface = shapes[mode]
        return render_shot(design, target, surface, mesh, scale, spp, seed, size, coverage=coverage)

    rows = []
    views = [("distance", scale, _SIZE) for scale in _DISTANCES] + [
        ("resolution", 1.0, size) for size in _COARSE
    ]
    for series, scale, size in views:
        frame = Framing.of(np.asarray(mesh.vertices), size[0], size[1], PREVIEW_FOV_DEG, scale)
        pixels = design.texture.feature_size_mm / frame.pixel_footprint_mm
        mask = shot("model", scale, 1, 0, coverage=True, size=size)
        start = time.perf_counter()
        reference = shot("geometry", scale, _REFERENCE_SPP, 1000, size=size)
        reference_s = time.perf_counter() - start
        renders: dict[str, tuple[np.ndarray, np.ndarray, list[float]]] = {}
        for mode in ("geometry", "model", "table"):
            shot(mode, scale, _SPP, 99, size=size)  # untimed: Dr.Jit compiles each new configuration
            times, images = [], []
            for seed in range(max(2, min(repeats, 3))):
                start = time.perf_counter()
                images.append(shot(mode, scale, _SPP, seed, size=size))
                times.append(time.perf_counter() - start)
            renders[mode] = (images[0], images[1], times)
        g1, g2, _ = renders["geometry"]
        g_noise_var = float(np.mean((luma(g1)[mask] - luma(g2)[mask]) ** 2)) / 2.0
        reference_noise_var = g_noise_var * _SPP / _REFERENCE_SPP
        for mode, (first, second, times) in renders.items():
            error, noise = representation_error(first, second, reference, reference_noise_var, mask)
            rows.append(
                {
                    "series": series,
                    "image_px": f"{size[0]}x{size[1]}",
                    "distance_scale": scale,
                    "pixels_per_feature": round(pixels, 3),
                    "lit_pixels": int(mask.sum()),
                    "mode": mode,
                    "spp": _SPP,
                    "median_s": round(float(np.median(times)), 3),
                    "error_vs_geometry": round(error, 4),
                    "noise": round(noise, 4),
                    # Noise falls as 1/sqrt(spp): the samples, hence (scene build included, so an
                    # upper bound) the time, that 2 % needs, from this render's own noise.
                    "time_to_2pct_s": round(float(np.median(times)) * max(1.0, (noise / 0.02) ** 2), 2),
                    "reference_s": round(reference_s, 2),
                }
            )
    by = {(row["image_px"], row["distance_scale"], row["mode"]): row for row in rows}
    notes = [
        f"test tile: {len(mesh.faces):,} triangles (relief built in {build_s:.1f} s); compact model fitted "
        f"from the traced BRDF in {brdf_s:.1f} s (fit error {predicted.fit.relative_error:.1%}); table of "
        f"10 x 12 incident directions traced in {table_s:.1f} s",
        f"reference: geometry at {_REFERENCE_SPP} spp; every representation at {_SPP} spp, twice (two "
        "seeds); error = the RMS luminance difference to the reference with both renders' noise taken off, "
        "relative to the mean, over the tile's pixels; noise = one render's RMS noise, same units; times "
        "include building the Mitsuba scene; time_to_2pct_s = the time scaled by the samples 2 % noise "
        "needs ((noise / 2 %)^2, noise falling as 1/sqrt(spp)), an upper bound since the scene is built once",
    ]
    for _, scale, size in views:
        m, g = by[(f"{size[0]}x{size[1]}", scale, "model")], by[(f"{size[0]}x{size[1]}", scale, "geometry")]
        notes.append(
            f"{size[0]}x{size[1]} px, distance x{scale:g} "
            f"({m['pixels_per_feature']:.2f} px per feature): model "
            f"{g['median_s'] / m['median_s']:.1f}x faster than geometry, "
            f"error {m['error_vs_geometry']:.1%} (noise at {_SPP} spp: model {m['noise']:.1%}, "
            f"geometry {g['noise']:.1%})"
        )
    notes.append(
        f"the chooser renders geometry from {GEOMETRY_FROM_FEATURES_PER_PIXEL:g} pixels per feature up "
        "(render.representation.GEOMETRY_FROM_FEATURES_PER_PIXEL)"
    )

    def chart(path: Path) -> None:
        render_chart(rows, path)

    return StageResult(
        "render",
        "relief as compact BRDF (a), traced table (b) and geometry (c), at several viewing distances",
        rows,
        chart,
        notes,
    )
