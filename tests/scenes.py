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


def v_grooves(depth_mm: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A 20 mm tile of V-grooves along y (right-angled: each face mirrors the lamps onto its
    neighbour), or a flat tile for ``depth_mm = 0``: vertices and upward-facing triangles."""
    xs = np.linspace(-10.0, 10.0, 11)  # ridges and valleys, 2 mm apart: every face planar
    ys = np.linspace(-10.0, 10.0, 3)
    x, y = np.meshgrid(xs, ys)
    z = np.where(np.arange(xs.size) % 2 == 0, depth_mm, 0.0)[None, :] * np.ones_like(x)
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    faces = []
    n = xs.size
    for r in range(ys.size - 1):
        for c in range(n - 1):
            a, b, d, e = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
            faces += [(a, b, e), (a, e, d)]
    return vertices, np.asarray(faces)


def coated_grooves_renderer(mirror_probability: float, width_px: int, height_px: int):
    """The V-groove tile in the preview's scene (variant already chosen), its blue coated resin
    drawing the mirror with this probability: a sampling parameter, on which the image's
    expectation does not depend (render.progressive's sampler is checked against it)."""
    from render.fresnel import diffuse_fresnel_reflectance
    from render.mitsuba_adapter import resin_scene_dict
    from render.progressive import SampleRenderer

    vertices, faces = v_grooves(2.0)
    coat = {
        "type": "printapp_coated",
        "ior": 1.5,
        "f_dr_int": float(diffuse_fresnel_reflectance(1.0 / 1.5)),
        "mirror_probability": float(mirror_probability),
        "body": {"type": "rgb", "value": [0.25, 0.45, 0.75]},
    }
    scene_dict, _ = resin_scene_dict(
        vertices, faces, body_albedo=(0.25, 0.45, 0.75), refractive_index=1.5, width_px=width_px,
        height_px=height_px, surface=coat,
    )  # fmt: skip
    return SampleRenderer(scene_dict, width_px, height_px)
