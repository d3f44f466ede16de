"""A design's relief: the printable model, a flat patch of its texture, and what the printer makes of it.

Each stage is a pure function of the design and its seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from noise.heightfield import HeightField
from printapp.design import Design, MeshBase, TileBase
from printapp.errors import DesignError
from printapp.fields import is_tile_field, surface_lic_values
from printapp.mesh import (
    displace_along_normals,
    load_closed_mesh,
    refine_to_edge_length,
    slab_from_heightfield,
)
from printapp.solid import SolidCheck
from printapp.texture import (
    FrameSummary,
    evaluate_texture_grid,
    evaluate_texture_on_mesh,
    normalise_peak_to_valley,
    relief_heightfield,
)
from slicing import Slices, slice_heightfield
from slicing.exposure import expose_heightfield
from slicing.printed import CureModel, pixel_centres_mm, printed_heights

_PATCH_FEATURES = 12.0  # side of the flat patch used for appearance statistics, in base-octave features


@dataclass
class Relief:
    """The printable model and what was measured on it."""

    mesh: trimesh.Trimesh
    patch: HeightField
    """A flat patch of the relief, at the design's pitch and amplitude scale, for appearance."""
    undisplaced: trimesh.Trimesh | None = None
    """For mesh bases: the refined mesh before displacement (same faces as ``mesh``)."""
    base: trimesh.Trimesh | None = None
    """For mesh bases: the closed mesh that was refined, the same surface as ``undisplaced``
    (the refinement splits triangles in their planes) in a few of its triangles."""
    softened_vertices: int = 0
    """For mesh bases: vertices whose relief was lowered so that no triangle folds."""
    frame: FrameSummary | None = None
    """For a stretched scn, fbm or turbulence on a mesh: the tangent frames it followed."""


def check_tile_memory(design: Design) -> None:
    """Refuse a tile whose relief would not fit the memory budget, naming a pitch that would."""
    from printapp.memory import BASE_BYTES, TILE_BYTES_PER_SAMPLE, fits, require
    from printapp.texture import tile_grid_shape

    assert isinstance(design.base, TileBase)
    ny, nx, _, _ = tile_grid_shape(design.base, design.pitch_mm)
    area = design.base.width_mm * design.base.depth_mm
    finest = math.sqrt(area / max(fits(TILE_BYTES_PER_SAMPLE), 1.0))
    setting = "relief.pitch_mm" if design.relief.pitch_mm is not None else "base.width_mm, base.depth_mm"
    require(
        BASE_BYTES + float(nx) * ny * TILE_BYTES_PER_SAMPLE,
        what=f"a relief of {nx} x {ny} samples",
        setting=setting,
        fitting=f"relief.pitch_mm = {finest:.4g} fits",
    )


def _edge_setting(feature_edge_mm: float, pitch_mm: float, per_feature: float) -> tuple[str, float]:
    """The key that sets a mesh's edge length, and its value per millimetre of edge."""
    if feature_edge_mm >= pitch_mm:
        return "texture.feature_size_mm", per_feature
    return "relief.pitch_mm", 1.0


def build_relief(design: Design, base: trimesh.Trimesh | None = None) -> Relief:
    """The displaced, closed model of a design (mm) and a flat patch of its relief.

    ``base`` replaces loading the design's mesh file (e.g. a repaired mesh).
    """
    texture = design.texture
    pitch = design.pitch_mm
    if isinstance(design.base, TileBase):
        check_tile_memory(design)
        field_ = relief_heightfield(design)
        return Relief(mesh=slab_from_heightfield(field_, design.base.thickness_mm), patch=field_)
    assert isinstance(design.base, MeshBase)
    if base is None:
        base = load_closed_mesh(design.base.path, design.base.scale)
    frame = None
    if texture.kind == "lic":
        # The smeared noise varies on the scale of its features across the streamlines:
        # two vertices per feature resolve it.
        edge = max(texture.feature_size_mm / 2.0, pitch)
        refined = refine_to_edge_length(base, edge, _edge_setting(texture.feature_size_mm / 2.0, pitch, 2.0))
        # Streamline samples a quarter of a feature apart: with the trapezoidal rule the box
        # integral is then within 2 % of a 1/32-feature walk on a plane (tests/test_surface.py);
        # the printer's pitch, finer still, only cost time.
        step = max(pitch, texture.feature_size_mm / 4.0)
        raw = surface_lic_values(refined, texture, step_mm=step, base=base)
    else:
        # Four vertices per base-octave feature along an edge resolve the relief's shape;
        # finer than the printer's pixel is wasted.
        edge = max(texture.feature_size_mm / 4.0, pitch)
        refined = refine_to_edge_length(base, edge, _edge_setting(texture.feature_size_mm / 4.0, pitch, 4.0))
        raw, frame = evaluate_texture_on_mesh(refined, texture, pitch_mm=edge, base=base)
    lo, hi = float(raw.min()), float(raw.max())
    mesh, softened = displace_along_normals(
        refined, normalise_peak_to_valley(raw, design.relief.amplitude_mm)
    )
    # A flat patch of the same texture on the mesh's value-to-height scale, so that its
    # slopes are the mesh's (for a mesh-only lic field, a constant field: the same slope
    # statistics up to a rotation; a framed noise is stretched along angle_deg there, the
    # same random field in law, up to a rotation, as it is on the surface).
    side = _PATCH_FEATURES * max(texture.feature_size_mm, texture.length_mm if texture.kind == "lic" else 0.0)
    n = max(3, min(1024, round(side / pitch) + 1))
    step = side / (n - 1)
    patch_texture = texture
    if texture.kind == "lic" and texture.field is not None and not is_tile_field(texture.field):
        patch_texture = texture.model_copy(update={"field": "constant:0"})
    values = evaluate_texture_grid(np.arange(n) * step, np.arange(n) * step, patch_texture, step)
    scale = design.relief.amplitude_mm / (hi - lo) if hi > lo else 0.0
    return Relief(
        mesh=mesh,
        patch=HeightField((values - lo) * scale, step, step),
        undisplaced=refined,
        base=base,
        softened_vertices=softened,
        frame=frame,
    )


@dataclass
class AsPrinted:
    """The printed relief of a tile (as a height field at the printer's pixels) and its error."""

    field: HeightField
    rms_error_mm: float
    max_error_mm: float


def cure_model(design: Design) -> CureModel:
    """The design's cure model (``[material] cure`` with the catalogue's constants, overridden)."""
    from printapp.cure import build_cure_model

    m = design.material
    return build_cure_model(m.cure, m.name, m.penetration_depth_mm, m.critical_dose_mj_cm2, m.dose_mj_cm2)


FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))
"""Full width at half maximum of a Gaussian, in standard deviations (2.355)."""


def nominal_cure_spread_mm(design: Design) -> float:
    """The nominal lateral cure spread (mm): a spot whose full width at half maximum is one pixel.

    ``pitch / 2.355``: the narrowest spot that draws a lit pixel no sharper than the pixel
    itself; nominal, not measured (Reid et al. 2024 calibrate a printer's spot from a
    single-layer print, which has not been done for these printers).
    """
    return design.printer.profile.pitch_mm / FWHM_PER_SIGMA


def cure_spread(design: Design) -> tuple[float, str]:
    """The design's lateral cure spread (mm, the Gaussian spot's standard deviation) and where it came from.

    ``[printer] cure_spread_um`` where given, else none. Not the nominal spread
    (:func:`nominal_cure_spread_mm`) by default: it is not measured, and it moves verdicts
    (it smooths pixel-scale textures: ``docs/benchmarks.md``, brdf section).
    """
    given = design.printer.cure_spread_mm
    if given is not None:
        return given, f"{given * 1000:.4g} um ([printer] cure_spread_um)"
    nominal = nominal_cure_spread_mm(design) * 1000.0
    return 0.0, (
        f"none (default: no measured spread for this printer; cure_spread_um = {nominal:.3g} is the "
        "nominal one-pixel spot)"
    )


def as_printed(
    design_field: HeightField,
    slices: Slices,
    base_thickness_mm: float,
    cure: CureModel | None = None,
    spread_mm: float = 0.0,
) -> AsPrinted:
    """What the printer makes of a tile: printed heights at pixel centres, against the design.

    ``cure`` is the cure model (:mod:`slicing.printed`; default: the linear one), and
    ``spread_mm`` the lateral cure spread (:func:`slicing.printed.spread_dose`; 0: none).
    The comparison uses pixels at least one pixel inside the tile's edges (the walls' grey
    pixels are not relief), the design interpolated bilinearly at the pixel centres.
    """
    from scipy.interpolate import RegularGridInterpolator

    heights = printed_heights(slices, cure, spread_mm)
    x, y = pixel_centres_mm(slices)
    xd = x - slices.shift_mm[0] - design_field.origin_x_mm
    yd = y - slices.shift_mm[1] - design_field.origin_y_mm
    px, py = slices.profile.pitch_x_mm, slices.profile.pitch_y_mm
    cols = np.nonzero((xd > px) & (xd < design_field.width_mm - px))[0]
    rows = np.nonzero((yd > py) & (yd < design_field.depth_mm - py))[0]
    if cols.size == 0 or rows.size == 0:
        raise DesignError(
            f"base: the tile is {design_field.width_mm:.4g} x {design_field.depth_mm:.4g} mm, too small "
            f"to print a relief: expected at least four of the {slices.profile.label}'s {px:.3g} mm "
            "pixels a side"
        )
    window = heights[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    ny, nx = design_field.shape
    interpolate = RegularGridInterpolator(
        (np.arange(ny) * design_field.pitch_y_mm, np.arange(nx) * design_field.pitch_x_mm),
        design_field.heights_mm,
    )
    yy, xx = np.meshgrid(yd[rows], xd[cols], indexing="ij")
    designed = (
        interpolate(np.column_stack([yy.ravel(), xx.ravel()])).reshape(window.shape) + base_thickness_mm
    )
    error = window - designed
    return AsPrinted(
        field=HeightField(window - base_thickness_mm, px, py, float(xd[cols[0]]), float(yd[rows[0]])),
        rms_error_mm=float(np.sqrt(np.mean(error**2))),
        max_error_mm=float(np.max(np.abs(error))),
    )


def appearance_field(design: Design, relief: Relief | None = None) -> tuple[HeightField, str]:
    """The relief whose appearance a design predicts, and what it is.

    For a tile, what the printer makes of it (sliced and read back); for a mesh or a
    tile with booleans, a flat patch of the designed relief.
    """
    relief = relief or build_relief(design)
    if isinstance(design.base, TileBase) and not design.combine:
        slices = slice_tile(design, relief.patch)
        printed = as_printed(
            relief.patch, slices, design.base.thickness_mm, cure_model(design), cure_spread(design)[0]
        )
        return printed.field, "as-printed relief"
    return relief.patch, "designed relief"


def slice_tile(design: Design, patch: HeightField) -> Slices:
    """A tile's layers straight from its height field: the same layers as slicing the slab, no mesh.

    With ``[relief] grey_levels`` or a ``pixel_texture``, the pixels inside the tile are lit
    from the relief's heights instead (:func:`slicing.exposure.expose_heightfield`).
    """
    assert isinstance(design.base, TileBase)
    if design.relief.grey_levels or design.relief.pixel_texture_mm > 0.0:
        return expose_heightfield(
            patch,
            design.base.thickness_mm,
            design.printer.profile,
            cure=cure_model(design),
            grey_levels=design.relief.grey_levels,
            pixel_texture_mm=design.relief.pixel_texture_mm,
            seed=design.texture.seed,
            layer_height_mm=design.layer_height_mm,
        )
    return slice_heightfield(
        patch,
        design.base.thickness_mm,
        design.printer.profile,
        layer_height_mm=design.layer_height_mm,
    )


def fits_printer(design: Design, solid: SolidCheck) -> bool:
    """Whether the model fits the printer's display and height, in either orientation."""
    return fits_printer_size(design, solid.size_mm)


def fits_printer_size(design: Design, size_mm: tuple[float, float, float]) -> bool:
    """Whether a model of this bounding box (mm) fits the printer, in either orientation."""
    profile = design.printer.profile
    sx, sy, sz = size_mm
    w, d = profile.display_width_mm, profile.display_height_mm
    return ((sx <= w and sy <= d) or (sx <= d and sy <= w)) and sz <= profile.max_print_height_mm
