"""Body albedo, BSSRDF and medium against a converged volumetric render (``printapp bench translucency``).

A 12 x 12 x 3 mm relief tile (2 mm fBm features, 0.3 mm relief: the translucent example's),
96 x 72 px, of a resin that absorbs nothing, whose transport mean free path ``ell*`` runs from
a third of a pixel footprint to the tile's thickness. Each is rendered as the body albedo
(``plastic``, 64 spp), the BSSRDF (:mod:`render.subsurface`, 16 spp), and the medium at 64 spp,
two seeds each, and compared with the medium at 2 x ``REFERENCE_SPP`` samples. The error is the
RMS luminance difference over 4 x 4 pixel blocks inside the tile, both images' own noise taken
off (estimated from their two seeds), relative to the reference's mean; for the 64-spp medium,
whose error is its noise, the noise too, and the time it would take to bring it down to the
BSSRDF's error (noise falling as one over the square root of the samples). The chart backs the
chooser's thresholds (:mod:`render.translucency`).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult

RATIOS = (0.3, 1.0, 2.0, 4.0, 6.0, 11.0)
"""``ell*`` in pixel footprints."""
REFERENCE_SPP = 1024
WIDTH, HEIGHT = 96, 72
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def _blocks(image: np.ndarray) -> np.ndarray:
    lum = image.astype(np.float64) @ _LUMA
    return lum.reshape(HEIGHT // 4, 4, WIDTH // 4, 4).mean(axis=(1, 3))


def _error(
    candidate: tuple[np.ndarray, np.ndarray], reference: tuple[np.ndarray, np.ndarray], inside: np.ndarray
) -> float:
    """Relative RMS block difference of the two seeds' means, their noise variances taken off."""
    c1, c2 = (_blocks(x)[inside] for x in candidate)
    r1, r2 = (_blocks(x)[inside] for x in reference)
    c, r = (c1 + c2) / 2, (r1 + r2) / 2
    var = np.mean((c1 - c2) ** 2) / 4 + np.mean((r1 - r2) ** 2) / 4
    return math.sqrt(max(float(np.mean((c - r) ** 2)) - var, 0.0)) / float(r.mean())


def _renders() -> tuple[list[dict[str, Any]], float, float]:
    from printapp.design import design_from_dict
    from printapp.relief import build_relief
    from render.mitsuba_adapter import Framing, choose_variant, render_resin_mesh, resin_scene_dict
    from render.subsurface import eye_of, lights_of, resolves, subsurface_tile
    from render.translucency import MediumRGB

    choose_variant()
    thickness = 3.0
    design = design_from_dict(
        {
            "base": {"width_mm": 12, "depth_mm": 12, "thickness_mm": thickness},
            "texture": {"feature_size_mm": 2.0, "seed": 11},
            "relief": {"amplitude_mm": 0.3, "pitch_mm": 0.1},
        }
    )
    relief = build_relief(design)
    vertices, faces = np.asarray(relief.mesh.vertices), np.asarray(relief.mesh.faces)
    footprint = Framing.of(vertices, WIDTH, HEIGHT, 30.0).pixel_footprint_mm
    eta = 1.49
    common: dict[str, Any] = {
        "refractive_index": eta,
        "width_px": WIDTH,
        "height_px": HEIGHT,
        "body_albedo": (1.0, 1.0, 1.0),
    }
    cover = render_resin_mesh(vertices, faces, spp=4, coverage=True, **common)
    inside = cover.reshape(HEIGHT // 4, 4, WIDTH // 4, 4).all(axis=(1, 3))
    scene, _ = resin_scene_dict(
        vertices,
        faces,
        **{k: v for k, v in common.items() if k != "body_albedo"},
        body_albedo=(1.0, 1.0, 1.0),
    )
    lights, eye = lights_of(scene), eye_of(scene)
    patch = relief.patch
    rows = []
    for ratio in RATIOS:
        mfp = ratio * footprint
        medium = MediumRGB((2.0 / mfp,) * 3, (0.0,) * 3, 0.5)  # sigma_s' = 1 / ell*, g = 0.5

        def timed(fn: Any) -> tuple[Any, float]:
            start = time.perf_counter()
            out = fn()
            return out, time.perf_counter() - start

        ref = [
            render_resin_mesh(vertices, faces, spp=REFERENCE_SPP, medium=medium, seed=10 + s, **common)
            for s in (0, 1)
        ]
        albedo = [render_resin_mesh(vertices, faces, spp=64, seed=s, **common) for s in (0, 1)]
        (_, albedo_s) = timed(lambda: render_resin_mesh(vertices, faces, spp=64, **common))
        medium_64, medium_s = timed(
            lambda m=medium: render_resin_mesh(vertices, faces, spp=64, medium=m, **common)
        )
        medium_64b = render_resin_mesh(vertices, faces, spp=64, medium=medium, seed=1, **common)

        def bssrdf(seed: int, medium: MediumRGB = medium) -> np.ndarray:
            v, f, radiance = subsurface_tile(
                patch.heights_mm,
                patch.pitch_x_mm,
                patch.pitch_y_mm,
                patch.origin_x_mm,
                patch.origin_y_mm,
                thickness,
                medium,
                eta,
                lights,
                eye,
            )
            return render_resin_mesh(
                v, f, spp=16, seed=seed, emission=radiance, frame_vertices=vertices, **common
            )

        first, bssrdf_s = timed(lambda: bssrdf(0))
        second = bssrdf(1)
        error_b = _error((first, second), (ref[0], ref[1]), inside)
        mean_ref = float(_blocks((ref[0] + ref[1]) / 2)[inside].mean())
        # one 64-spp render's noise per block: half the squared difference of two
        diff = _blocks(medium_64)[inside] - _blocks(medium_64b)[inside]
        noise_64 = math.sqrt(float(np.mean(diff**2)) / 2) / mean_ref
        rows.append(
            {
                "mfp_over_footprint": ratio,
                "transport_mfp_mm": round(mfp, 4),
                "mfp_over_thickness": round(mfp / thickness, 3),
                "bssrdf_grid_resolves": resolves((thickness, 12.0, 12.0), mfp),
                "albedo_error": round(_error((albedo[0], albedo[1]), (ref[0], ref[1]), inside), 4),
                "bssrdf_error": round(error_b, 4),
                "medium_64spp_error": round(_error((medium_64, medium_64b), (ref[0], ref[1]), inside), 4),
                "medium_64spp_noise": round(noise_64, 4),
                "reference_noise": round(
                    math.sqrt(float(np.mean((_blocks(ref[0])[inside] - _blocks(ref[1])[inside]) ** 2)) / 4)
                    / float(_blocks((ref[0] + ref[1]) / 2)[inside].mean()),
                    4,
                ),
                "medium_s_to_bssrdf_error": round(medium_s * (noise_64 / max(error_b, 1e-6)) ** 2, 2),
                "albedo_s_64spp": round(albedo_s, 3),
                "bssrdf_s_16spp": round(bssrdf_s, 3),
                "medium_s_64spp": round(medium_s, 3),
            }
        )
    return rows, footprint, thickness


def bench_translucency(repeats: int) -> StageResult:
    """Body albedo, BSSRDF and medium renders against a converged medium, for ell* from a third of
    a pixel to the tile's thickness (``repeats`` is unused: single timed renders)."""
    from render.translucency import BSSRDF_MAX_MFP_OVER_THICKNESS, MEDIUM_THRESHOLD

    load = os.getloadavg()[0]
    rows, footprint, thickness = _renders()
    notes = [
        f"12 x 12 x {thickness:g} mm relief tile, {WIDTH} x {HEIGHT} px "
        f"(pixel footprint {footprint:.3f} mm), "
        "a resin that absorbs nothing (sigma_s' = 1 / ell*, g = 0.5, index 1.49), studio light",
        f"reference: the medium (volpath) at 2 x {REFERENCE_SPP} spp; errors: relative RMS luminance over "
        "4 x 4 px blocks inside the tile, both images' noise taken off (two seeds each)",
        f"chooser: body albedo up to ell* = {MEDIUM_THRESHOLD:g} footprint, the BSSRDF up to ell* = "
        f"{BSSRDF_MAX_MFP_OVER_THICKNESS:g} x thickness (tiles whose diffusion grid resolves ell*), "
        "the medium beyond",
        f"load average when the stage started: {load:.2f} on {os.cpu_count()} cores; "
        "times are single renders",
    ]

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        x = [r["mfp_over_footprint"] for r in rows]
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.6), constrained_layout=True)
        for key, label, style in (
            ("albedo_error", "body albedo (64 spp)", "o-"),
            ("bssrdf_error", "BSSRDF (16 spp)", "s-"),
            ("medium_64spp_noise", "medium, 64 spp: its noise (its bias: 0-3 %)", "^-"),
            ("reference_noise", "reference's own noise", "k:"),
        ):
            ax.plot(x, [100 * r[key] for r in rows], style, label=label)
        ax.axvline(MEDIUM_THRESHOLD, color="grey", lw=0.8)
        limit = BSSRDF_MAX_MFP_OVER_THICKNESS * thickness / footprint
        ax.axvline(limit, color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_xlabel("transport mean free path / pixel footprint")
        ax.set_ylabel("error against the converged medium (%)")
        top = ax.secondary_xaxis(
            "top", functions=(lambda v: v * footprint / thickness, lambda v: v * thickness / footprint)
        )
        top.set_xlabel("transport mean free path / thickness")
        ax.legend(fontsize=8)
        for key, label, style in (
            ("albedo_s_64spp", "body albedo (64 spp)", "o-"),
            ("bssrdf_s_16spp", "BSSRDF (16 spp, diffusion included)", "s-"),
            ("medium_s_64spp", "medium (64 spp)", "^-"),
            ("medium_s_to_bssrdf_error", "medium, to the BSSRDF's error (extrapolated)", "^:"),
        ):
            bx.plot(x, [r[key] for r in rows], style, label=label)
        bx.set_xscale("log")
        bx.set_yscale("log")
        bx.set_xlabel("transport mean free path / pixel footprint")
        bx.set_ylabel("render time (s)")
        bx.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "translucency",
        "body albedo, BSSRDF and medium against a converged medium, ell* from 0.3 pixel to the thickness",
        rows,
        chart,
        notes,
    )
