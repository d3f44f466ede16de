"""The preview scene the developer scripts light a ``model.stl`` in, as ``printapp design`` builds it:
1024 x 768, a blue coated resin under printapp's studio light (imported by the ``preview-*.py`` scripts)."""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing, StudioLight, choose_variant, resin_scene_dict

WIDTH, HEIGHT = 1024, 768
BODY = (0.25, 0.45, 0.75)


def preview_scene(path: str) -> tuple[np.ndarray, np.ndarray, dict[str, Any], Framing]:
    """The mesh at ``path`` (vertices, faces) and its preview scene with its framing (variant chosen here)."""
    choose_variant()
    mesh = trimesh.load(path)
    vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    scene, frame = resin_scene_dict(
        vertices,
        faces,
        body_albedo=BODY,
        refractive_index=1.5,
        width_px=WIDTH,
        height_px=HEIGHT,
        fov_deg=PREVIEW_FOV_DEG,
        light=StudioLight(),
    )
    return vertices, faces, scene, frame
