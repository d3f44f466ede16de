"""The lamps' caustics on a coated relief: what they cost a geometry preview, and the split that
light-traces them (render.caustics), measured.

    .venv/bin/python scripts/preview-caustics.py MODEL.stl [MODEL.stl ...]

Each MODEL.stl is a mesh to light, e.g. the ``model.stl`` that ``printapp design
examples/part_relief.toml`` writes; its preview scene is built as ``printapp design`` builds it
(1024 x 768, a blue coated resin under printapp's studio light). For each model:

1. the share of the object's light and of the camera's variance (``path``, 2 x 16 samples a
   pixel) that the lamps' ``E D S L`` paths carry, from the camera's own estimate of them
   (``CoatedPath(caustics="only")``), and the variance left without them;
2. the two parts at equal samples (2 x 16 a pixel, uniform): means (they must agree with
   ``path``'s), noise and seconds, and the light tracer's variance and seconds, with or
   without its learned guide;
3. the preview's whole progressive render to 2 % noise (``render.convergence.converge``, adaptive
   sampling, first passes of 4 samples) with ``path``, and with the split where
   ``caustic_split`` takes it: seconds, samples a pixel and light paths.

About a minute a model, and three for step 3 on the CAD examples.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from preview_scene import HEIGHT, WIDTH, preview_scene  # (scripts/, beside this file)

from render.caustics import caustic_image, caustic_split, coat_of, lamps_of
from render.coated_path import CoatedPath
from render.convergence import LUMINANCE, ConvergenceSettings, converge
from render.progressive import SampleRenderer


def _halves(renderer: SampleRenderer, pixels: np.ndarray, integrator, spp: int = 16) -> tuple:
    start = time.perf_counter()
    a = renderer.render(spp, 1, pixels, integrator=integrator) @ LUMINANCE
    b = renderer.render(spp, 2, pixels, integrator=integrator) @ LUMINANCE
    return a, b, time.perf_counter() - start


def main(paths: list[str]) -> None:
    for path in paths:
        _, _, scene, frame = preview_scene(path)
        renderer = SampleRenderer(scene, WIDTH, HEIGHT)
        mask = renderer.aovs(4, 0)["coverage"] >= 0.5
        pixels = np.flatnonzero(mask.ravel())
        coat, lamps = coat_of(scene), lamps_of(renderer.scene, scene)
        print(f"{path}: {pixels.size} object pixels")
        parts = {
            "path": renderer.scene.integrator(),
            "caustics, camera's estimate": CoatedPath(coat, caustics="only"),
            "caustic-free": CoatedPath(coat),
        }
        stats = {}
        for name, integrator in parts.items():
            renderer.render(1, 0, pixels[:256], integrator=integrator)  # (compiles)
            a, b, seconds = _halves(renderer, pixels, integrator)
            stats[name] = (float(np.mean(0.5 * (a + b))), float(np.mean((a - b) ** 2)) / 4.0, seconds)
        mean, variance, seconds = stats["path"]
        c_mean, c_var, _ = stats["caustics, camera's estimate"]
        f_mean, f_var, f_seconds = stats["caustic-free"]
        print(f"  caustics: {c_mean / mean:.2%} of the light, {c_var / variance:.1%} of path's variance")
        print(f"  path          mean {mean:.5f}  noise {np.sqrt(variance) / mean:6.2%}  {seconds:5.2f} s")
        print(f"  caustic-free  mean {f_mean:.5f}  noise {np.sqrt(f_var) / mean:6.2%}  {f_seconds:5.2f} s")
        frame_args = {
            "centre_mm": frame.centre,
            "radius_mm": frame.radius_mm,
            "width_px": WIDTH,
            "height_px": HEIGHT,
        }
        _, guide = caustic_image(renderer.scene, coat, lamps, 500_000, 12345, learn=True, **frame_args)
        for label, which in (("uniform", None), ("learned guide", guide)):
            start = time.perf_counter()
            a, _ = caustic_image(renderer.scene, coat, lamps, 2_000_000, 1, guide=which, **frame_args)
            b, _ = caustic_image(renderer.scene, coat, lamps, 2_000_000, 2, guide=which, **frame_args)
            seconds = time.perf_counter() - start
            la, lb = (a @ LUMINANCE)[pixels], (b @ LUMINANCE)[pixels]
            print(
                f"  light tracer ({label}), 2 x 2 M paths: mean {np.mean(0.5 * (la + lb)):.5f} "
                f"variance {np.mean((la - lb) ** 2) / 4:.3e} {seconds:5.2f} s; "
                f"with the caustic-free part: mean {f_mean + np.mean(0.5 * (la + lb)):.5f}"
            )
        settings = ConvergenceSettings(target=0.02, first_spp=4, max_spp=4096, time_cap_s=1e9)
        whole = converge(renderer.render, mask, seed=7, settings=settings)
        print(
            f"  to 2 %, path:  {whole.seconds:5.1f} s, {whole.spp} samples a pixel, noise {whole.noise:.4f}"
        )
        start = time.perf_counter()
        split = caustic_split(renderer, mask, 7)
        if split is None:
            print("  to 2 %, split: declined (the caustics are under render.caustics.MIN_CAUSTIC_SHARE)")
            continue
        render, caustics = split
        result = converge(render, mask, seed=7, settings=settings, caustics=caustics)
        seconds = time.perf_counter() - start
        print(
            f"  to 2 %, split: {seconds:5.1f} s (its pilots included), {result.spp} samples a pixel, "
            f"{result.light_paths / 1e6:.1f} M light paths, noise {result.noise:.4f}"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
