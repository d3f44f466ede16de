"""Mitsuba's samplers as render.progressive drives them: bias against a sampling parameter, and noise.

    .venv/bin/python scripts/preview-sampler.py [MODEL.stl ...]

1. On the tests' tile of right-angled V-grooves (96 x 72, 64 samples a pixel, 128 seeds), for
   each sampler and for the coat's mirror probability at 0.7 and at 0.4 (a sampling parameter:
   the image's expectation does not depend on it): the object's mean luminance with its
   standard error, for Mitsuba's ``path`` and for the camera's estimate of the lamps' caustics
   alone (``CoatedPath(caustics="only")``), and a pixel's variance times its samples.
   Every row averages over the same pixels (the mask is taken once, before the sampler changes:
   a mask taken with each sampler moves the means by more than the bias looked for). A
   reference that shares no code with ``render.progressive``: Mitsuba's own film loop
   (``mi.render``, box filter) with its ``independent`` sampler, on the vectorised variant and on
   the scalar one (Mitsuba's C++ ``plastic`` in place of printapp's coat).
2. For each MODEL.stl (e.g. the ``model.stl`` of ``printapp design examples/part_relief.toml``),
   in its preview scene (1024 x 768): a sample's relative noise and the seconds a pass takes, at
   passes of 4, 16 and 64, for printapp's own (:mod:`render.sampler`), ``multijitter``, ``ldsampler``
   and ``independent``.

About a minute for step 1 and two a model.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the tests' scenes
from preview_scene import HEIGHT, WIDTH, preview_scene  # noqa: E402  (scripts/, beside this file)

import render.progressive as progressive  # noqa: E402
from render.caustics import coat_of  # noqa: E402
from render.coated_path import CoatedPath  # noqa: E402
from render.convergence import LUMINANCE  # noqa: E402
from render.mitsuba_adapter import choose_variant, resin_scene_dict  # noqa: E402
from render.progressive import SampleRenderer  # noqa: E402
from tests.scenes import coated_grooves_renderer, v_grooves  # noqa: E402

OURS = progressive.SAMPLER
SAMPLERS = (OURS, "multijitter", "ldsampler", "stratified", "independent")
TILE_W, TILE_H, TILE_SPP, TILE_SEEDS = 96, 72, 64, 128


def _tile(p_mirror: float) -> SampleRenderer:
    return coated_grooves_renderer(p_mirror, TILE_W, TILE_H)


def _row(label: str, images: np.ndarray, mask: np.ndarray, spp: int) -> None:
    means = images[:, mask].mean(1)
    pixel_var = images[:, mask].var(0, ddof=1).mean() * spp
    se = means.std(ddof=1) / np.sqrt(means.size)
    print(f"  {label:44s} {means.mean():.6f} +- {se:.6f}   var x spp {pixel_var:.4e}", flush=True)


def _film_loop(scene_dict: dict, first_seed: int) -> np.ndarray:
    """The tile's luminance from Mitsuba's own film loop (box filter) with independent samples."""
    import mitsuba as mi

    sensor = dict(scene_dict["sensor"])
    sensor["film"] = dict(sensor["film"], rfilter={"type": "box"})
    sensor["sampler"] = {"type": "independent", "sample_count": TILE_SPP}
    scene = mi.load_dict(dict(scene_dict, sensor=sensor))
    return np.stack(
        [
            np.asarray(mi.render(scene, seed=first_seed + 131 * s), dtype=np.float64)[..., :3] @ LUMINANCE
            for s in range(TILE_SEEDS)
        ]
    )


def bias_table() -> None:
    mask = _tile(0.7).aovs(16, 0)["coverage"] >= 0.5
    print(f"V-groove tile, {mask.sum()} object pixels, {TILE_SPP} spp, {TILE_SEEDS} seeds: mean luminance")
    for p_mirror in (0.7, 0.4):
        renderer = _tile(p_mirror)
        caustics = CoatedPath(coat_of(renderer.scene_dict), caustics="only")
        for sampler in SAMPLERS:
            progressive.SAMPLER = sampler
            for name, integrator in (("path", None), ("caustics (camera)", caustics)):
                images = np.stack(
                    [
                        renderer.render(TILE_SPP, 1000 + s, integrator=integrator) @ LUMINANCE
                        for s in range(TILE_SEEDS)
                    ]
                )
                _row(f"p = {p_mirror}, {sampler}, {name}", images, mask, TILE_SPP)
        images = _film_loop(renderer.scene_dict, 7)
        _row(f"p = {p_mirror}, mi.render + independent, path", images, mask, TILE_SPP)
    progressive.SAMPLER = OURS
    scalar_reference(mask)


def scalar_reference(mask: np.ndarray) -> None:
    """The tile on Mitsuba's scalar variant: its C++ ``plastic`` (the coat printapp's BSDF copies),
    its film loop and its ``independent`` sampler; no code shared with render.progressive."""
    import mitsuba as mi

    vectorised = mi.variant()
    mi.set_variant("scalar_rgb")
    try:
        vertices, faces = v_grooves(2.0)
        scene_dict, _ = resin_scene_dict(
            vertices, faces, body_albedo=(0.25, 0.45, 0.75), refractive_index=1.5, width_px=TILE_W,
            height_px=TILE_H,
        )  # fmt: skip
        images = _film_loop(scene_dict, 9000)
        _row("scalar_rgb, plastic, mi.render + independent, path", images, mask, TILE_SPP)
    finally:
        mi.set_variant(vectorised)


def noise_table(path: str) -> None:
    _, _, scene, _ = preview_scene(path)
    renderer = SampleRenderer(scene, WIDTH, HEIGHT)
    mask = renderer.aovs(4, 0)["coverage"] >= 0.5
    print(f"{path}: {mask.sum()} object pixels; a sample's relative noise, seconds a pass")
    for spp, reps in ((4, 16), (16, 8), (64, 4)):
        for sampler in (OURS, "multijitter", "ldsampler", "independent"):
            progressive.SAMPLER = sampler
            renderer.render(spp, 0)  # (compiles)
            start = time.perf_counter()
            images = np.stack([renderer.render(spp, 100 + s) @ LUMINANCE for s in range(reps)])
            seconds = (time.perf_counter() - start) / reps
            obj = images[:, mask]
            noise = np.sqrt(obj.var(0, ddof=1).mean() * spp) / obj.mean()
            print(
                f"  passes of {spp:2d}, {sampler:12s} mean {obj.mean():.5f} noise {noise:.3f} {seconds:.2f} s"
            )
    progressive.SAMPLER = OURS


if __name__ == "__main__":
    if choose_variant().variant.startswith("scalar"):
        sys.exit("this script needs one of Mitsuba's vectorised variants (libLLVM >= 16)")
    bias_table()
    for model in sys.argv[1:]:
        noise_table(model)
