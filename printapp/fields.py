"""Direction fields for line integral convolution, from a short spec.

On tiles and images: ``constant:ANGLE`` (degrees from +x towards +y), ``swirl``
(circles about the centre), ``image:FILE`` (an angle map: grey 0..255 is 0..180
degrees, an orientation field).

On meshes: ``constant:ANGLE`` (that horizontal world direction), ``swirl`` (circles
about the vertical axis through the mesh's centre), ``direction:X,Y,Z`` (a world
direction), ``axis:X,Y,Z`` (circles about that axis through the centre),
``curvature:max`` or ``curvature:min`` (principal curvature directions). Each is
projected into the surface's tangent planes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from printapp.errors import DesignError

_EXPECTED = (
    "expected 'constant:ANGLE', 'swirl' or 'image:FILE' (tiles and meshes), "
    "or 'direction:X,Y,Z', 'axis:X,Y,Z', 'curvature:max|min' (meshes)"
)


LIC_MAX_TAPS = 2e10
"""Most noise samples one LIC may take (pixels or vertices times taps per streamline): about a
minute on two cores; longer streamlines are refused rather than left to run for hours."""


def _vector(arg: str, spec: str) -> np.ndarray:
    try:
        values = np.array([float(x) for x in arg.split(",")])
    except ValueError:
        raise ValueError(f"expected three comma-separated numbers in {spec!r}") from None
    if values.shape != (3,) or not np.all(np.isfinite(values)) or not np.any(values):
        raise ValueError(f"expected a finite, non-zero X,Y,Z in {spec!r}")
    return values


def lic_field(texture) -> str:  # noqa: ANN001
    """The field lic's streamlines follow: the design's ``[texture] field``, else 'constant:0' (along +x)."""
    return texture.field if texture.field is not None else "constant:0"


def is_tile_field(spec: str) -> bool:
    """Whether the spec also works on a flat tile (constant, swirl, image)."""
    return spec.partition(":")[0] in ("constant", "swirl", "image")


def check_field_spec(spec: str) -> str:
    """Validate a field spec's form (not the file's content); return it unchanged."""
    kind, _, arg = spec.partition(":")
    if kind == "swirl" and not arg:
        return spec
    if kind in ("direction", "axis"):
        _vector(arg, spec)
        return spec
    if kind == "curvature" and arg in ("max", "min"):
        return spec
    if kind == "constant":
        try:
            angle = float(arg)
        except ValueError:
            raise ValueError(f"expected 'constant:ANGLE' with ANGLE in degrees, got {spec!r}") from None
        if not math.isfinite(angle):
            raise ValueError(f"expected a finite angle, got {spec!r}")
        return spec
    if kind == "image" and arg:
        return spec
    raise ValueError(f"{_EXPECTED}, got {spec!r}")


def field_on_grid(
    spec: str, x: np.ndarray, y: np.ndarray, base_dir: Path | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Components (u along x, v along y) of the field ``spec`` on the grid x by y.

    Raises
    ------
    DesignError
        If an image field's file is missing or unreadable.
    """
    check_field_spec(spec)
    if not is_tile_field(spec):
        raise DesignError(
            f"field {spec!r} needs a mesh base; on tiles use 'constant:ANGLE', 'swirl' or 'image:FILE'"
        )
    kind, _, arg = spec.partition(":")
    xx, yy = np.meshgrid(x, y)
    if kind == "constant":
        a = math.radians(float(arg))
        return np.full_like(xx, math.cos(a)), np.full_like(xx, math.sin(a))
    if kind == "swirl":
        cx = 0.5 * (x[0] + x[-1])
        cy = 0.5 * (y[0] + y[-1])
        return -(yy - cy), xx - cx
    from PIL import Image

    from printapp.inputs import open_image

    path = Path(arg)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    with open_image(path, "field image") as image:
        grey = np.asarray(image.convert("L").resize((len(x), len(y)), Image.Resampling.BILINEAR), dtype=float)
    # Image rows run downwards; our y runs upwards.
    angle = grey[::-1] / 255.0 * math.pi
    return np.cos(angle), np.sin(angle)


def _angle_map(path: Path, size: int = 1024) -> np.ndarray:
    """An angle map file as radians (grey 0..255 -> 0..pi), row 0 at the bottom (v = 0)."""
    from PIL import Image

    from printapp.inputs import open_image

    with open_image(path, "field image") as image:
        grey = image.convert("L")
        if max(grey.size) > size:
            grey = grey.resize((size, size), Image.Resampling.BILINEAR)
        values = np.asarray(grey, dtype=float)
    return values[::-1] / 255.0 * math.pi


def field_on_mesh(spec: str, mesh, base=None, normals: np.ndarray | None = None) -> np.ndarray:
    """Tangent vectors per vertex of ``mesh`` (zero where the field vanishes) for ``spec``.

    ``base`` is the unrefined mesh that ``mesh`` was refined from (its faces' parents in
    ``mesh.metadata["parent_face"]``): image fields are laid on it through an xatlas UV
    layout, computed on the small base mesh rather than the refined one. ``normals``: the
    vertices' angle-weighted normals, when the caller has them already.
    """
    from noise.surface import field_constant, field_from_angle_map, field_principal_curvature, field_rotation

    vertices = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    check_field_spec(spec)
    kind, _, arg = spec.partition(":")
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    if kind == "constant":
        a = math.radians(float(arg))
        return field_constant(vertices, faces, [math.cos(a), math.sin(a), 0.0], normals)
    if kind == "direction":
        return field_constant(vertices, faces, _vector(arg, spec), normals)
    if kind == "swirl":
        return field_rotation(vertices, faces, [0.0, 0.0, 1.0], centre, normals)
    if kind == "axis":
        return field_rotation(vertices, faces, _vector(arg, spec), centre, normals)
    if kind == "curvature":
        return field_principal_curvature(vertices, faces, arg)
    import xatlas

    if base is None or "parent_face" not in mesh.metadata:
        base, parents = mesh, np.arange(len(faces))
    else:
        parents = mesh.metadata["parent_face"]
    base_vertices, base_faces = np.asarray(base.vertices), np.asarray(base.faces)
    _, uv_faces, uvs = xatlas.parametrize(base_vertices.astype(np.float32), base_faces.astype(np.uint32))
    return field_from_angle_map(
        vertices, faces, parents, base_vertices, base_faces, uvs[uv_faces], _angle_map(Path(arg))
    )


def surface_lic_values(mesh, texture, step_mm: float, base=None) -> np.ndarray:
    """The design texture's surface LIC at each vertex of ``mesh`` (a trimesh.Trimesh)."""
    from noise.surface import lic_surface

    vertices = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    taps = 2.0 * len(vertices) * (texture.length_mm / step_mm + 1.0)
    if taps > LIC_MAX_TAPS:
        raise DesignError(
            f"texture.length_mm: {texture.length_mm:g} mm streamlines at {step_mm:g} mm steps from "
            f"{len(vertices):,} vertices are {taps:.3g} noise samples, more than {LIC_MAX_TAPS:.0e} "
            f"(about a minute); texture.length_mm = {texture.length_mm * LIC_MAX_TAPS / taps:.3g} fits"
        )
    field = field_on_mesh(lic_field(texture), mesh, base)
    return lic_surface(
        vertices,
        faces,
        field,
        length=texture.length_mm,
        step=step_mm,
        noise_scale=texture.feature_size_mm,
        seed=texture.seed,
        impulses=texture.impulses,
        cell_seed=texture.cell_seed,
    )
