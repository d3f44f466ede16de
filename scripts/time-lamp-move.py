"""Time the first render after a lamp move (the light sweep's frames), as this checkout renders it.

    PYTHONPATH=TREE .venv/bin/python scripts/time-lamp-move.py MODEL.stl

TREE is the checkout whose ``render`` package is timed (this one, or a worktree of an earlier
commit); MODEL.stl a mesh to light, e.g. the ``model.stl`` that ``printapp design
examples/part_relief.toml`` writes. The preview's scene (1024 x 768, the object as an instance)
is loaded, then the lamps are moved three times to positions never rendered before (random
azimuths: no kernel cached on disk can serve them), and each time a 4-sample pass over the
object's pixels is timed right after the move and once more unmoved. Where each move compiles
a kernel, "after move" exceeds "again" by the compilation (about 0.55 s on 2 cores).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import replace

import numpy as np
import trimesh

from render.mitsuba_adapter import (
    PREVIEW_FOV_DEG,
    StudioLight,
    choose_variant,
    lamp_transforms,
    resin_scene_dict,
    studio_places,
)
from render.progressive import SampleRenderer


def main(path: str) -> None:
    choose_variant()
    mesh = trimesh.load(path)
    vertices = np.asarray(mesh.vertices)
    light = StudioLight()
    scene, frame = resin_scene_dict(
        vertices,
        np.asarray(mesh.faces),
        body_albedo=(0.25, 0.45, 0.75),
        refractive_index=1.5,
        width_px=1024,
        height_px=768,
        fov_deg=PREVIEW_FOV_DEG,
        light=light,
    )
    scene["relief_group"] = {"type": "shapegroup", "relief": scene.pop("relief")}
    scene["relief"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "relief_group"}}
    renderer = SampleRenderer(scene, 1024, 768)
    pixels = np.flatnonzero(renderer.aovs(4, 0)["coverage"].ravel() >= 0.5)

    def timed() -> float:
        start = time.perf_counter()
        renderer.render(4, 3, pixels=pixels)
        return time.perf_counter() - start

    timed()
    rng = np.random.default_rng()  # unseeded on purpose: positions no earlier run has compiled
    for k in range(3):
        moved = replace(light, azimuth_rad=light.azimuth_rad + 0.5 * (k + 1) + float(rng.uniform(0.0, 1.0)))
        places = studio_places(frame, math.radians(40.0), math.radians(-60.0), moved, 1.0)
        lamps = lamp_transforms(frame, places, moved, 1.0)
        start = time.perf_counter()
        renderer.move_shapes({name: lamps[name] for name in ("softbox", "spot") if renderer.has(name)})
        move_s = time.perf_counter() - start
        print(f"move {move_s:.3f} s, after move {timed():.3f} s, again {timed():.3f} s")


if __name__ == "__main__":
    main(sys.argv[1])
