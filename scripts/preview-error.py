"""Where a geometry preview's noise comes from, and what the denoiser does with it.

    .venv/bin/python scripts/preview-error.py MODEL.stl [SAMPLES_PER_HALF]

MODEL.stl is a mesh to light, e.g. the ``model.stl`` that ``printapp design
examples/part_relief.toml`` writes. Its preview scene (1024 x 768, the coated blue resin under
printapp's studio light) is rendered in two independent halves of SAMPLES_PER_HALF (default 16)
samples a pixel over the object's pixels, as variants of the scene:

- ``full``: the preview as ``printapp design`` renders it;
- ``no spot`` / ``no soft box``: one lamp taken away;
- ``direct light``: ``max_depth`` 2 (no interreflection, no caustics);
- ``diffuse body``: the coat taken off (a Lambertian of the same albedo).

For each: the object's mean luminance, the relative noise (:func:`render.convergence.relative_noise`),
the share of the variance in the noisiest 1 % of pixels, and in the pixels brighter than the
display's white (``preview.png`` clips them, so their noise cannot be seen). Then the ``full``
halves are denoised with Open Image Denoise at three settings (``high``, what printapp uses;
``fast``; ``fast`` with the guides declared noise-free), each with its time (median of three)
and its error against the converged image, estimated from the halves
(:func:`render.convergence.denoised_error`).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from preview_scene import BODY, HEIGHT, WIDTH, preview_scene  # (scripts/, beside this file)

from render.convergence import _denoise_half, _dilate, _lum, denoised_error, relative_noise
from render.mitsuba_adapter import mesh_object
from render.progressive import SampleRenderer, passes_of


def halves(renderer: SampleRenderer, active: np.ndarray, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """Two independent renders of ``spp`` samples a pixel over ``active`` (the rest black)."""
    out = []
    for which in (0, 1):
        image = np.zeros((HEIGHT * WIDTH, 3))
        total = np.zeros((active.size, 3))
        for k, count in enumerate(passes_of(spp)):  # powers of four, as render.convergence takes them
            total += count * renderer.render(count, 1000 * which + k, active)
        image[active] = total / spp
        out.append(image.reshape(HEIGHT, WIDTH, 3))
    return out[0], out[1]


def main(path: str, spp: int) -> None:
    import mitsuba as mi

    vertices, faces, scene, _ = preview_scene(path)
    diffuse = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": list(BODY)}})
    variants = {
        "full": scene,
        "no spot": {k: v for k, v in scene.items() if k != "spot"},
        "no soft box": {k: v for k, v in scene.items() if k != "softbox"},
        "direct light": dict(scene, integrator={"type": "path", "max_depth": 2}),
        "diffuse body": dict(scene, relief=mesh_object(vertices, faces, diffuse)),
    }
    first = SampleRenderer(scene, WIDTH, HEIGHT)
    guides = first.aovs(4, 0)
    mask = guides["coverage"] >= 0.5
    active = np.flatnonzero(_dilate(mask, 2))
    print(f"{mask.sum()} object pixels, {2 * spp} samples a pixel (two halves of {spp})")
    print(f"{'scene':14s} {'mean lum':>9s} {'noise':>7s} {'top 1 %':>8s} {'> white':>8s} {'seconds':>8s}")
    full = None
    for name, scene_dict in variants.items():
        renderer = first if name == "full" else SampleRenderer(scene_dict, WIDTH, HEIGHT)
        renderer.render(1, 0, active[:256])  # compile before the clock starts
        start = time.perf_counter()
        a, b = halves(renderer, active, spp)
        seconds = time.perf_counter() - start
        variance = ((_lum(a) - _lum(b)) ** 2 / 4.0)[mask]
        ranked = np.sort(variance)[::-1]
        top = float(ranked[: max(1, ranked.size // 100)].sum() / ranked.sum())
        white = float(variance[(0.5 * (a + b)).max(axis=-1)[mask] >= 1.0].sum() / variance.sum())
        mean = float(np.mean(0.5 * (_lum(a) + _lum(b))[mask]))
        noise = relative_noise(a, b, mask)
        print(f"{name:14s} {mean:9.4f} {noise:7.2%} {top:8.1%} {white:8.1%} {seconds:8.2f}")
        if name == "full":
            full = (a, b)
    assert full is not None
    import pyoidn

    a, b = full
    print(f"\nOpen Image Denoise on the full preview's halves (raw noise {relative_noise(a, b, mask):.2%})")
    for quality, clean in (("high", False), ("fast", False), ("fast", True)):

        def denoise(colour, albedo, normal, quality=quality, clean=clean):
            return np.asarray(
                pyoidn.denoise(
                    np.ascontiguousarray(np.clip(colour, 0.0, None), dtype=np.float32),
                    np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), dtype=np.float32),
                    np.ascontiguousarray(np.clip(normal, -1.0, 1.0), dtype=np.float32),
                    hdr=True,
                    quality=quality,
                    clean_aux=clean,
                ),
                dtype=np.float64,
            )

        times = []
        for _ in range(3):
            start = time.perf_counter()
            den_a = _denoise_half(denoise, (guides["albedo"], guides["normal"]), a, mask)
            den_b = _denoise_half(denoise, (guides["albedo"], guides["normal"]), b, mask)
            times.append(time.perf_counter() - start)
        error = denoised_error(den_a, den_b, a, b, mask)
        label = f"{quality}{', clean guides' if clean else ''}"
        print(f"  {label:20s} error {error:6.2%}  {sorted(times)[1]:.2f} s (two halves)")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 16)
