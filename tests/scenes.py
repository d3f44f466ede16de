"""Small Mitsuba scenes the render tests share."""

import numpy as np
import trimesh


def box_scene(width_px: int = 64, height_px: int = 48, light=None):
    """A 10 x 10 x 2 mm resin box under the studio light: ``(scene_dict, framing)`` (variant chosen here)."""
    from render.mitsuba_adapter import choose_variant, resin_scene_dict

    choose_variant()
    box = trimesh.creation.box(extents=(10, 10, 2))
    return resin_scene_dict(
        np.asarray(box.vertices),
        np.asarray(box.faces),
        body_albedo=(0.8, 0.5, 0.2),
        refractive_index=1.5,
        width_px=width_px,
        height_px=height_px,
        light=light,
    )
