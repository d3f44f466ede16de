"""Evaluate a design's texture at points in millimetres and turn it into relief."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from noise.heightfield import HeightField
from printapp.design import Design, Texture, TileBase
from printapp.errors import DesignError
from printapp.texture_kinds import stretch_field, stretch_to_noise_units, texture_kind, vein_sign

# The design key behind each name the noise kernels complain about.
_DESIGN_KEY_OF_KERNEL_NAME = {
    "x": "texture.feature_size_mm",
    "y": "texture.feature_size_mm",
    "z": "texture.feature_size_mm",
    "points": "texture.feature_size_mm",
    "period": "texture.vein_period_mm",
    "strength": "texture.turbulence_strength",
    "sharpness": "texture.vein_sharpness",
    "angle": "texture.vein_angle_deg",
    "length": "texture.length_mm",
}


@contextlib.contextmanager
def _kernel_errors_as_design_keys() -> Iterator[None]:
    """A kernel's ValueError ("name: expected ...") as its design key: exit 2, not a traceback."""
    try:
        yield
    except ValueError as exc:
        name, _, rest = str(exc).partition(":")
        key = _DESIGN_KEY_OF_KERNEL_NAME.get(name.strip(), f"texture.{name.strip()}")
        raise DesignError(f"{key}:{rest}") from None


def evaluate_texture(points_mm: np.ndarray, texture: Texture, pitch_mm: float | None = None) -> np.ndarray:
    """Raw texture values at ``points_mm`` ((n, 2) or (n, 3), mm).

    ``pitch_mm`` (the sampling pitch) drops fBm/turbulence octaves finer than two
    samples: a printer cannot reproduce them, and sampling them would alias.
    """
    kind = texture_kind(texture.kind)
    if kind.points is None:
        raise ValueError(f"{kind.name} textures are evaluated on grids or meshes, not at scattered points")
    pitch = None if pitch_mm is None else pitch_mm / texture.feature_size_mm
    with _kernel_errors_as_design_keys():
        return kind.points(stretch_to_noise_units(points_mm, texture), texture, pitch)


@dataclass(frozen=True)
class FrameSummary:
    """The tangent frames a stretched noise followed on a mesh, for the manifest and the CLI."""

    field: str
    """The field spec the stretch followed (the design's, or ``constant:ANGLE`` from angle_deg)."""
    onb: str
    """The orthonormal basis used where the field gives no direction."""
    blend_radius_mm: float
    """Radius over which the stretch fades to isotropic around singular vertices (mm)."""
    singular_vertices: int
    """Vertices where the field vanishes or turns about a triangle: isotropic noise there."""
    blended_vertices: int
    """Vertices within the blend radius of a singular one (the singular ones included)."""
    vertices: int

    def as_dict(self) -> dict[str, Any]:
        return {
            "field": self.field,
            "onb": self.onb,
            "blend_radius_mm": round(self.blend_radius_mm, 6),
            "singular_vertices": self.singular_vertices,
            "blended_vertices": self.blended_vertices,
            "vertices": self.vertices,
        }


def texture_frames(mesh, texture: Texture, base=None):
    """The tangent frames a stretched texture follows on ``mesh`` (mm), and their summary.

    Each vertex's frame is its angle-weighted normal and the field
    (:func:`printapp.texture_kinds.stretch_field`) projected into its tangent plane,
    isotropic around the field's singular points over ``frame_blend_mm`` (default
    ``stretch * feature_size_mm / 2``), with the ONB ``texture.onb`` there
    (:func:`noise.frames.surface_frames`). ``base``: the mesh ``mesh`` was refined from
    (image fields are laid on it).

    Returns
    -------
    (noise.frames.SurfaceFrames, FrameSummary)
    """
    from noise.frames import angle_weighted_normals, surface_frames
    from printapp.fields import field_on_mesh

    spec = stretch_field(texture)
    radius = texture.frame_blend_mm
    if radius is None:
        radius = 0.5 * texture.stretch * texture.feature_size_mm
    vertices = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    normals = angle_weighted_normals(vertices, faces)
    frames = surface_frames(
        vertices,
        faces,
        field_on_mesh(spec, mesh, base, normals),
        blend_radius=radius,
        method=texture.onb,
        normals=normals,
    )
    summary = FrameSummary(
        field=spec,
        onb=texture.onb,
        blend_radius_mm=float(radius),
        singular_vertices=frames.singular_count,
        blended_vertices=int(np.count_nonzero(frames.blend < 1.0)),
        vertices=len(vertices),
    )
    return frames, summary


def evaluate_texture_in_frames(
    points_mm: np.ndarray, frames, texture: Texture, pitch_mm: float
) -> np.ndarray:
    """Raw values of a stretched scn, fbm or turbulence at ``points_mm``, along ``frames``' tangents.

    The framed counterpart of :func:`evaluate_texture` (:mod:`noise.framed`): the noise is
    ``texture.stretch`` times longer along each point's tangent than across it, blended
    to isotropic where ``frames.blend`` falls to 0.
    """
    kind = texture_kind(texture.kind)
    if kind.framed is None:
        raise ValueError(f"{kind.name} textures do not follow tangent frames")
    return kind.framed(
        np.asarray(points_mm) / texture.feature_size_mm, frames, texture, pitch_mm / texture.feature_size_mm
    )


def evaluate_texture_on_mesh(
    mesh, texture: Texture, pitch_mm: float, base=None
) -> tuple[np.ndarray, FrameSummary | None]:
    """Raw texture values at the vertices of ``mesh`` (a trimesh.Trimesh, mm), and the frames followed.

    A stretched scn, fbm or turbulence follows the surface (:func:`texture_frames`,
    :func:`evaluate_texture_in_frames`). Without a stretch, and for marble, the noise is
    evaluated at the vertices as on a tile, and no frame is returned.
    """
    vertices = np.asarray(mesh.vertices)
    if texture_kind(texture.kind).framed is None or texture.stretch == 1.0:
        return evaluate_texture(vertices, texture, pitch_mm=pitch_mm), None
    frames, summary = texture_frames(mesh, texture, base)
    return evaluate_texture_in_frames(vertices, frames, texture, pitch_mm), summary


def normalise_peak_to_valley(values: np.ndarray, amplitude_mm: float) -> np.ndarray:
    """Scale values affinely so that they span exactly [0, amplitude_mm]."""
    lo, hi = float(values.min()), float(values.max())
    if hi - lo <= 0.0:
        return np.zeros_like(values)
    return (values - lo) * (amplitude_mm / (hi - lo))


def tile_grid_shape(base: TileBase, pitch_mm: float) -> tuple[int, int, float, float]:
    """Samples (ny, nx) and exact pitches (dy, dx) that cover the tile edge to edge at about ``pitch_mm``."""
    nx = max(2, round(base.width_mm / pitch_mm) + 1)
    ny = max(2, round(base.depth_mm / pitch_mm) + 1)
    return ny, nx, base.depth_mm / (ny - 1), base.width_mm / (nx - 1)


def evaluate_texture_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: Texture, pitch_mm: float | None
) -> np.ndarray:
    """Raw texture values on the grid ``x_mm`` by ``y_mm`` (z = 0), shaped (len(y), len(x)).

    Uses the kind's grid fast path when the texture's axes line up with the grid (no
    stretch, or a stretch along x, or LIC); otherwise evaluates the points one by one.
    ``pitch_mm`` None keeps every octave (``printapp texture``); a design passes its pitch.
    """
    kind = texture_kind(texture.kind)
    if kind.points is None or texture.stretch == 1.0 or texture.angle_rad == 0.0:
        with _kernel_errors_as_design_keys():
            return kind.grid(x_mm, y_mm, texture, pitch_mm)
    xx, yy = np.meshgrid(x_mm, y_mm)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    return evaluate_texture(pts, texture, pitch_mm=pitch_mm).reshape(len(y_mm), len(x_mm))


def palette_colours(values: np.ndarray, texture: Texture) -> np.ndarray:
    """Colours (sRGB in [0, 1], shape ``values.shape + (3,)``) of texture values through its palette.

    The palette's colours are spaced evenly from ``palette_range[0]`` to
    ``palette_range[1]`` (which may run downwards) and interpolated linearly; values
    beyond the range take the end colours. Without a palette, a grey ramp from black to
    white; without a range, 0..1 for marble and the values' own minimum..maximum otherwise.
    With ``palette_values``, colour ``k`` sits at value ``palette_values[k]`` instead. The range
    and the values are given for veins raised (marble, veined): with ``veins = "sunk"`` the
    texture's values and they are both negated, so the colours stay with the veins.
    """
    palette = texture.palette or ("#000000", "#ffffff")
    colours = np.array([[int(c[i : i + 2], 16) / 255.0 for i in (1, 3, 5)] for c in palette])
    sign = vein_sign(texture)
    if texture.palette_values is not None:
        # Knots at given values; the values are the raised veins', like the range below.
        knots = sign * np.asarray(texture.palette_values, dtype=np.float64)
        if knots[-1] < knots[0]:
            knots, colours = knots[::-1], colours[::-1]
        v = np.asarray(values, dtype=np.float64)
        return np.stack([np.interp(v, knots, colours[:, c]) for c in range(3)], axis=-1)
    if texture.palette_range is not None:
        # The range is the raised veins' values: sinking them negates the values, and the range.
        lo, hi = (sign * v for v in texture.palette_range)
    elif texture_kind(texture.kind).unit_range:
        lo, hi = 0.0, sign
    else:
        lo, hi = float(values.min()), float(values.max())
    if hi == lo:
        t = np.zeros_like(values, dtype=np.float64)
    else:
        t = np.clip((np.asarray(values, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
    knots = np.linspace(0.0, 1.0, len(colours))
    return np.stack([np.interp(t, knots, colours[:, c]) for c in range(3)], axis=-1)


def relief_heightfield(design: Design) -> HeightField:
    """The relief of a tile design: texture on the tile's grid, scaled to the amplitude (mm)."""
    if not isinstance(design.base, TileBase):
        raise TypeError("relief_heightfield needs a tile design")
    ny, nx, dy, dx = tile_grid_shape(design.base, design.pitch_mm)
    values = evaluate_texture_grid(np.arange(nx) * dx, np.arange(ny) * dy, design.texture, max(dx, dy))
    return HeightField(normalise_peak_to_valley(values, design.relief.amplitude_mm), dx, dy)


def write_texture_from_file(path: Path, out: Path, size: int, width_mm: float | None = None) -> str:
    """Write the [texture] of a design or fragment file as an image of ``size`` px over ``width_mm``.

    ``.png`` gets the colours of its palette (8-bit sRGB, row 0 at the top), ``.npy`` the
    texture's values, as a design's relief takes them (sunk veins negative). The square starts at the
    origin, with
    pixel centres at ``(i + 1/2) width / size``, as ``printapp fit`` synthesised it; the
    width defaults to the design's tile width (20 mm for a fragment). Returns a one-line
    summary.

    Raises
    ------
    PrintappError
        If the file does not load as a design, or the width or output is unusable.
    """
    import io

    from printapp.design_io import load_design
    from printapp.errors import PrintappError
    from printapp.outputs import atomic_write_bytes

    design = load_design(path)
    if width_mm is None:
        width_mm = design.base.width_mm if isinstance(design.base, TileBase) else 20.0
    if not (math.isfinite(width_mm) and width_mm > 0):
        raise PrintappError(f"--width-mm: expected a positive width in mm, got {width_mm}")
    pitch = width_mm / size
    axis = (np.arange(size) + 0.5) * pitch
    texture = design.texture
    values = evaluate_texture_grid(axis, axis, texture, pitch)
    buffer = io.BytesIO()
    if out.suffix.lower() == ".npy":
        np.save(buffer, values)
    else:
        from PIL import Image

        rgb = palette_colours(values, texture)
        pixels = np.round(np.clip(rgb[::-1], 0.0, 1.0) * 255).astype(np.uint8)
        Image.fromarray(pixels, mode="RGB").save(buffer, format="PNG")
    atomic_write_bytes(out, buffer.getvalue())
    return (
        f"{texture.kind} from {path}: {size}x{size} px over {width_mm:g} mm, "
        f"values {values.min():.4g}..{values.max():.4g}; wrote {out}"
    )


# Flags of ``printapp texture`` named by the kernels' ValueErrors ("name: expected ...").
_FLAG_OF_KERNEL_NAME = {
    "x": "--cells",
    "y": "--cells",
    "points": "--cells",
    "angle": "--vein-angle-deg",
    "period": "--vein-period",
    "strength": "--turbulence-strength",
    "sharpness": "--sharpness",
}


def texture_image(kind: str, size: int, cells: float, options: dict[str, object]) -> np.ndarray:
    """Values of a texture KIND on a ``size`` x ``size`` image, ``cells`` noise cells across.

    The image is the kind's grid evaluation with one pixel per millimetre and a feature
    size of ``size / cells`` pixels, every octave kept. ``options`` are ``[texture]``
    fields (internal names, lengths in pixels: ``vein_period_mm``, ``length_mm``). The
    kernels check the values; their complaints come back naming the command's flags.

    Raises
    ------
    PrintappError
        Naming the flag that is out of range, or the field image that cannot be read.
    """
    from printapp.errors import PrintappError
    from printapp.memory import BASE_BYTES, budget_bytes, require

    spec = texture_kind(kind)
    per_pixel = 160 if spec.points is None else 48  # LIC keeps a field, step maps and noise
    largest = int(math.sqrt(max(0.0, (budget_bytes() - BASE_BYTES) / per_pixel)))
    require(
        BASE_BYTES + float(size) ** 2 * per_pixel,
        what=f"a {size} x {size}-pixel {kind} image",
        setting="--size",
        fitting=f"--size {largest} fits",
    )
    # No validation here on purpose: the command's ranges are wider than a design's (a
    # texture image may have 24 octaves), and the kernels check what they need.
    texture = Texture.model_construct(kind=kind, feature_size_mm=size / cells, **options)
    pixels = np.arange(size) + 0.5
    try:
        return spec.grid(pixels, pixels, texture, None if spec.points is not None else 1.0)
    except ValueError as exc:
        name, _, rest = str(exc).partition(":")
        if name.startswith("expected"):  # from the field spec parser
            raise PrintappError(f"--field: {exc}") from None
        flag = _FLAG_OF_KERNEL_NAME.get(name, f"--{name.replace('_', '-')}")
        raise PrintappError(f"{flag}:{rest}") from None


def grey_png_bytes(values: np.ndarray, unit_range: bool) -> bytes:
    """An 8-bit grey PNG of ``values`` (row 0 at the top): [0, 1] clipped, or stretched min..max."""
    import io

    from PIL import Image

    if unit_range:
        unit = np.clip(values, 0.0, 1.0)
    else:
        span = float(values.max() - values.min())
        unit = (values - values.min()) / span if span > 0 else np.zeros_like(values)
    buffer = io.BytesIO()
    Image.fromarray(np.round(unit[::-1] * 255).astype(np.uint8), mode="L").save(buffer, format="PNG")
    return buffer.getvalue()
