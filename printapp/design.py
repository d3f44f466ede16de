"""The design file: TOML, validated by pydantic at the boundary, in internal units.

Inside printapp every length is in millimetres and every angle in radians. A design
file may give a length in micrometres (``amplitude_um = 300``) or an angle in degrees
(``angle_deg = 30``); such keys are converted once, here, to the ``_mm`` / ``_rad``
field that the model declares. ``design.resolved.toml`` is written back in mm and
degrees with every default filled in, and loads to the same design.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import annotated_types as at
import numpy as np
from pydantic import Field, ValidationError, field_validator, model_validator

from printapp.design_solve import TARGET_LIMITS, Solve, target_range
from printapp.errors import DesignError
from printapp.schema_base import UNIT_ALIASES, Section
from printapp.schema_errors import SchemaExplainer
from printapp.texture_kinds import TEXTURE_KIND_NAMES
from slicing import PrinterProfile, find_printer

_MAX_GRID_SIDE = 100_000
"""Samples along a tile's side beyond which a design is refused outright (the memory budget refuses far
fewer on most machines; see :mod:`printapp.memory`)."""
_UNIT_ALIASES = UNIT_ALIASES
_Section = Section


PositiveMM = Annotated[float, at.Gt(0.0)]


class TileBase(_Section):
    """A rectangular slab: the relief is on top, sides and bottom are flat."""

    shape: Literal["tile"] = "tile"
    width_mm: Annotated[float, at.Gt(0.0), at.Le(1000.0)] = 20.0
    depth_mm: Annotated[float, at.Gt(0.0), at.Le(1000.0)] = 20.0
    thickness_mm: Annotated[float, at.Gt(0.0), at.Le(500.0)] = 2.0


class MeshBase(_Section):
    """A closed input mesh whose surface receives the relief along its normals."""

    shape: Literal["mesh"] = "mesh"
    path: str = Field(min_length=1)
    scale: Annotated[float, at.Gt(0.0), at.Le(1e6)] = 1.0
    """Millimetres per unit of the mesh file (25.4 for a model in inches)."""


class Texture(_Section):
    """The texture field: which noise, at which scale, with which seed."""

    kind: Literal[TEXTURE_KIND_NAMES] = "fbm"  # type: ignore[valid-type]
    """One of :data:`printapp.texture_kinds.TEXTURE_KINDS`."""
    feature_size_mm: Annotated[float, at.Ge(1e-3), at.Le(1000.0)] = 2.0
    """Size of one noise lattice cell (mm): the base octave's features are about this big."""
    seed: Annotated[int, at.Ge(0), at.Lt(2**63)] = 0
    impulses: Annotated[int, at.Ge(1), at.Le(256)] = 30
    cell_seed: Literal["hash", "frisvad"] = "hash"
    octaves: Annotated[int, at.Ge(1), at.Le(16)] = 4
    lacunarity: Annotated[float, at.Gt(1.0), at.Le(8.0)] = 2.0
    H: Annotated[float, at.Gt(0.0), at.Le(1.0)] = 1.0
    low: Annotated[int, at.Ge(0), at.Le(16)] = 0
    high: Annotated[int, at.Ge(0), at.Le(16)] = 4
    stretch: Annotated[float, at.Ge(1.0), at.Le(100.0)] = 1.0
    """Elongation of the features along ``angle`` (tiles) or ``field`` (meshes): 1 is isotropic, 8 looks
    brushed."""
    angle_rad: Annotated[float, at.Ge(-2 * math.pi), at.Le(2 * math.pi)] = 0.0
    """Direction of elongation in the xy plane, from +x towards +y; on a mesh without ``field``, that
    world direction projected into each tangent plane (``field = "constant:ANGLE"``)."""
    field: str | None = None
    """The direction field: where lic's streamlines run ('constant:ANGLE' in degrees, 'swirl',
    'image:FILE'; on meshes also 'direction:X,Y,Z', 'axis:X,Y,Z', 'curvature:max|min') [lic:
    'constant:0']; on meshes also the direction scn, fbm and turbulence are stretched along, in
    each vertex's tangent frame [default: 'constant:' with ``angle``]."""
    frame_blend_mm: Annotated[float, at.Gt(0.0), at.Le(1000.0)] | None = None
    """Meshes: the radius around the field's singular points (where it vanishes or turns) over which
    the stretch fades to isotropic [default: stretch * feature_size_mm / 2, a kernel's reach]."""
    onb: Literal["duff", "frisvad"] = "duff"
    """Meshes: the orthonormal basis of the normal that gives the frame where the field gives no
    direction (Duff et al. 2017; Frisvad 2012 fails near n = (0, 0, -1))."""
    length_mm: Annotated[float, at.Ge(1e-3), at.Le(1000.0)] = 2.0
    """lic: half-length of the streamlines the noise is averaged along (mm)."""
    vein_angle_rad: Annotated[float, at.Ge(-2 * math.pi), at.Le(2 * math.pi)] = 0.0
    """marble: direction the veins run along, from +x towards +y."""
    vein_period_mm: Annotated[float, at.Ge(1e-3), at.Le(10000.0)] = 5.0
    """marble: distance between veins across their direction (mm); 1 / vein frequency."""
    turbulence_strength: Annotated[float, at.Ge(0.0), at.Le(1000.0)] = 5.0
    """marble: radians of the sine's phase per unit of turbulence (low..high octaves)."""
    vein_sharpness: Annotated[float, at.Ge(1.0), at.Le(1000.0)] = 1.0
    """marble: exponent on the [0, 1] value; large values make thin veins. veined: the ridges' profile."""
    veins: Literal["raised", "sunk"] = "raised"
    """marble, veined: whether the veins (value 1) stand up from the relief or are cut into it."""
    vein_network: Literal["ridged", "cellular"] = "ridged"
    """veined: ridges along the zero crossings of noise, or along cellular edges (F2 - F1, cracks)."""
    vein_scale_mm: Annotated[float, at.Gt(0.0), at.Le(10000.0)] = 5.0
    """veined: cell size of the vein network's first octave (mm)."""
    vein_octaves: Annotated[int, at.Ge(1), at.Le(12)] = 4
    """veined: octaves of the ridged multifractal (finer ones are dropped below two samples)."""
    vein_gain: Annotated[float, at.Ge(0.0), at.Le(16.0)] = 2.0
    """veined: how strongly a vein lets finer veins branch off it (Musgrave's gain)."""
    vein_H: Annotated[float, at.Ge(0.0), at.Le(2.0)] = 1.0  # noqa: N815 - Musgrave's H
    """veined: octave weights lacunarity^(-H i) of the finer veins."""
    vein_width: Annotated[float, at.Gt(0.0), at.Le(10.0)] = 0.5
    """veined: half-width of a vein in the basis's units (noise standard deviations, or F2 - F1 in cells)."""
    vein_warp: Annotated[float, at.Ge(0.0), at.Le(10.0)] = 0.5
    """veined: domain warp, the displacement's standard deviation in vein cells (noise of noise)."""
    vein_layers: Annotated[int, at.Ge(1), at.Le(4)] = 1
    """veined: layers of veins, each turned, scaled and weighted by the three keys below."""
    vein_layer_turn_rad: Annotated[float, at.Ge(-2 * math.pi), at.Le(2 * math.pi)] = math.pi / 3
    vein_layer_scale: Annotated[float, at.Gt(0.0), at.Le(10.0)] = 0.5
    vein_layer_weight: Annotated[float, at.Gt(0.0), at.Le(1.0)] = 0.6
    vein_fade: Annotated[float, at.Ge(0.0), at.Le(4.0)] = 0.0
    """veined: how much the veins' strength wanders over the surface (0: evenly strong everywhere)."""
    ground_weight: Annotated[float, at.Ge(0.0), at.Le(100.0)] = 0.0
    """veined: weight of the unit-variance fBm ground (octaves, lacunarity, ground_H, feature_size_mm)."""
    ground_H: Annotated[float, at.Ge(-1.0), at.Le(1.0)] = 0.5  # noqa: N815 - fBm's H
    """veined: the ground's octave weights lacunarity^(-ground_H i); at 0 or below, grain as strong."""
    palette: tuple[str, ...] | None = Field(default=None, strict=False)
    """Colours '#rrggbb' spaced evenly over palette_range, for colour previews; not the relief."""
    palette_range: tuple[float, float] | None = Field(default=None, strict=False)
    """Texture values given the first and last palette colour [default: 0..1 for marble, else min..max]."""
    palette_values: tuple[float, ...] | None = Field(default=None, strict=False)
    """Texture value of each palette colour, monotone (instead of spacing them evenly over palette_range)."""

    @field_validator("field")
    @classmethod
    def _field_spec(cls, spec: str | None) -> str | None:
        from printapp.fields import check_field_spec

        return None if spec is None else check_field_spec(spec)

    @field_validator("palette")
    @classmethod
    def _palette_colours(cls, palette: tuple[str, ...] | None) -> tuple[str, ...] | None:
        if palette is None:
            return None
        if not 2 <= len(palette) <= 256:
            raise ValueError(f"expected 2 to 256 colours, got {len(palette)}")
        hex_digits = set("0123456789abcdefABCDEF")
        for colour in palette:
            if not (len(colour) == 7 and colour[0] == "#" and set(colour[1:]) <= hex_digits):
                raise ValueError(f"expected colours written '#rrggbb', got {colour!r}")
        return tuple(c.lower() for c in palette)

    @field_validator("palette_range")
    @classmethod
    def _palette_range(cls, pair: tuple[float, float] | None) -> tuple[float, float] | None:
        if pair is not None and pair[0] == pair[1]:
            raise ValueError(f"expected two different values, got [{pair[0]:g}, {pair[1]:g}]")
        return pair

    @model_validator(mode="after")
    def _octave_range(self) -> Texture:
        if self.high < self.low:
            raise ValueError(f"'high' ({self.high}) must be at least 'low' ({self.low})")
        if self.palette_values is not None:
            values = self.palette_values
            if self.palette is None or len(values) != len(self.palette):
                raise ValueError(
                    f"'palette_values' needs one value per 'palette' colour, got {len(values)} values for "
                    f"{len(self.palette or ())} colours"
                )
            steps = np.diff(values)
            if not (np.all(steps > 0) or np.all(steps < 0)):
                raise ValueError("'palette_values' must run strictly upwards or strictly downwards")
        return self


class Relief(_Section):
    """How high the texture stands and how finely it is sampled."""

    amplitude_mm: Annotated[float, at.Gt(0.0), at.Le(50.0)] = 0.3
    """Peak-to-valley height of the relief (mm): the texture is scaled to span exactly this."""
    pitch_mm: Annotated[float, at.Gt(0.0), at.Le(10.0)] | None = None
    """Sampling pitch of the height field (mm); default: the printer's pixel pitch."""
    grey_levels: bool = False
    """Tiles: expose every pixel with the grey level that, by the material's cure model, cures the relief's
    height there (sub-layer relief, carried by ``slices.sl1``); false: PrusaSlicer's anti-aliased coverage."""
    pixel_texture_mm: Annotated[float, at.Ge(0.0), at.Le(1.0)] = 0.0
    """Tiles: depth of a texture at the printer's pixel scale cut into the layer tops (each pixel's top
    lowered by a hashed share of it, through its exposure), so that no layer top is a flat mirror."""


class Printer(_Section):
    """Which printer, and optionally which layer height."""

    name: str = "prusa-sl1"
    layer_height_mm: Annotated[float, at.Gt(0.0), at.Le(1.0)] | None = None
    cure_spread_mm: Annotated[float, at.Ge(0.0), at.Le(1.0)] | None = None
    """Lateral cure spread: the standard deviation of the Gaussian spot a pixel's light makes in
    the resin (``cure_spread_um = 20``). Unset, none: no printer's spot has been measured
    (:func:`printapp.relief.cure_spread`; 20 um is the nominal one-pixel spot of the SL1)."""

    @field_validator("name")
    @classmethod
    def _known_printer(cls, name: str) -> str:
        find_printer(name)  # its UnknownPrinterError is a ValueError with the sentence
        return name

    @property
    def profile(self) -> PrinterProfile:
        return find_printer(self.name)

    @model_validator(mode="after")
    def _layer_in_range(self) -> Printer:
        lh = self.layer_height_mm
        prof = self.profile
        if lh is not None and not prof.min_layer_height_mm <= lh <= prof.max_layer_height_mm:
            raise ValueError(
                f"layer_height_mm {lh:g} is outside what {prof.label} can print "
                f"([{prof.min_layer_height_mm:g}, {prof.max_layer_height_mm:g}] mm)"
            )
        return self


Unit = Annotated[float, at.Ge(0.0), at.Le(1.0)]


class Material(_Section):
    """The resin: its refractive index and the colour its pigments give the body.

    Or, with ``name``, a material of the catalogue (``printapp material``) whose index, body
    albedo and translucency are computed from its particles (Lorenz–Mie), with ``parameters``
    such as ``tio2_volume_fraction``; ``refractive_index`` and ``body_albedo`` are then derived
    and may not be given. ``translucency`` picks the rendering: ``"auto"`` renders the light
    under the surface only where it wanders farther than the pixels can show, as a BSSRDF
    (tiles) or a homogeneous medium (render.translucency); ``"bssrdf"``, ``"medium"`` and
    ``"albedo"`` force one.
    """

    refractive_index: Annotated[float, at.Ge(1.0), at.Le(3.0)] = 1.5
    body_albedo: tuple[Unit, Unit, Unit] = Field(default=(0.8, 0.8, 0.8), strict=False)
    """Linear-RGB albedo of light that enters the resin and comes back out diffusely."""
    name: str | None = Field(default=None, min_length=1, max_length=200)
    parameters: dict[str, float] = Field(default_factory=dict)
    translucency: Literal["auto", "bssrdf", "medium", "albedo"] = "auto"
    cure: Literal["working-curve", "linear"] = "working-curve"
    """How thick a grey pixel cures (:mod:`slicing.printed`): Jacobs' working curve with the resin's
    constants, or a share of the layer linear in the grey level (printapp's first model)."""
    penetration_depth_mm: Annotated[float, at.Gt(0.0), at.Le(10.0)] | None = None
    """Working curve: ``Dp`` (default: the catalogue's ``[cure.NAME]`` of this material, else acrylate's)."""
    critical_dose_mj_cm2: Annotated[float, at.Gt(0.0), at.Le(1e5)] | None = None
    """Working curve: ``Ec``, the dose at which the resin gels (mJ/cm^2; default: the catalogue's)."""
    dose_mj_cm2: Annotated[float, at.Gt(0.0), at.Le(1e5)] | None = None
    """Working curve: the dose a fully lit pixel receives (mJ/cm^2; default: the catalogue's)."""

    @model_validator(mode="after")
    def _cure_constants(self) -> Material:
        from printapp.cure import build_cure_model

        build_cure_model(
            self.cure, self.name, self.penetration_depth_mm, self.critical_dose_mj_cm2, self.dose_mj_cm2
        )
        return self

    @model_validator(mode="after")
    def _named_material(self) -> Material:
        if self.name is None:
            if self.parameters:
                raise ValueError("'parameters' needs a material 'name'")
            return self
        given = sorted({"refractive_index", "body_albedo"} & self.model_fields_set)
        if given:
            raise ValueError(
                f"give either 'name' or '{given[0]}': a named material's index and albedo are derived"
            )
        from printapp.materials import check_design_material

        check_design_material(self.name, self.parameters)
        return self


RangeBound = Annotated[float, at.Ge(0.0), at.Le(1000.0)]
GlossUnits = Annotated[float, at.Ge(0.0), at.Le(200.0)]
Degrees180 = Annotated[float, at.Ge(0.0), at.Le(180.0)]


def _check_range(name: str, pair: tuple[float, float] | None) -> None:
    if pair is not None and pair[0] > pair[1]:
        raise ValueError(f"'{name}' must be [min, max] with min <= max, got [{pair[0]:g}, {pair[1]:g}]")


class Appearance(_Section):
    """Optional targets the design must meet, each as ``[min, max]``.

    A target may also be written ``{ value = 30, tolerance = 5 }`` (the range 25..35, clipped
    to the measure's range), ``{ max = 10 }`` or ``{ min = 4 }`` (one-sided); it is kept as
    ``[min, max]``.

    ``roughness`` is the Beckmann roughness of the relief's slopes (the root mean
    square slope times sqrt 2, geometric mean of the two principal directions);
    ``anisotropy`` is the ratio of the larger to the smaller principal roughness.
    ``gloss_20``, ``gloss_60``, ``gloss_85`` and ``haze`` are read off the BRDF that
    the gonioreflectometer traces through the (as-printed) relief, as a glossmeter
    would (plane of incidence along x).
    """

    roughness: tuple[RangeBound, RangeBound] | None = Field(default=None, strict=False)
    anisotropy: tuple[Annotated[float, at.Ge(1.0)], Annotated[float, at.Ge(1.0)]] | None = Field(
        default=None, strict=False
    )
    gloss_20: tuple[GlossUnits, GlossUnits] | None = Field(default=None, strict=False)
    """Specular gloss at 20 degrees (gloss units, ISO 2813), predicted from the traced BRDF."""
    gloss_60: tuple[GlossUnits, GlossUnits] | None = Field(default=None, strict=False)
    gloss_85: tuple[GlossUnits, GlossUnits] | None = Field(default=None, strict=False)
    haze: tuple[GlossUnits, GlossUnits] | None = Field(default=None, strict=False)
    """Haze index G60 - G20 (ASTM D4039)."""
    highlight_azimuth_deg: tuple[Degrees180, Degrees180] | None = Field(default=None, strict=False)
    """Direction of the highlight's long axis in [0, 180) degrees from +x, from the traced BRDF."""

    @model_validator(mode="before")
    @classmethod
    def _target_forms(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        return {k: target_range(k, v) if k in TARGET_LIMITS else v for k, v in data.items()}

    @model_validator(mode="after")
    def _ordered(self) -> Appearance:
        for name in (
            "roughness",
            "anisotropy",
            "gloss_20",
            "gloss_60",
            "gloss_85",
            "haze",
            "highlight_azimuth_deg",
        ):
            _check_range(name, getattr(self, name))
        return self


class Brdf(_Section):
    """The virtual gonioreflectometer that predicts the printed surface's BRDF."""

    rays: Annotated[int, at.Ge(1000), at.Le(100_000_000)] = 100_000
    """Primary rays per incident direction; the error falls as 1/sqrt(rays)."""
    distribution: Literal["auto", "ggx", "beckmann"] = "auto"
    """Microfacet distribution of the fitted compact model ('auto': the better fit)."""
    theta_bins: Annotated[int, at.Ge(4), at.Le(360)] = 45
    phi_bins: Annotated[int, at.Ge(4), at.Le(720)] = 90
    lobe_error: Annotated[float, at.Gt(0.0), at.Lt(1.0)] | None = None
    """When set (e.g. 0.01): trace each incident direction until its reflection lobe's
    relative standard error is this, starting from ``rays`` (at most 1e8 per direction)."""
    seed: Annotated[int, at.Ge(0), at.Lt(2**63)] = 0
    """Seed of the traced rays (independent of the texture's seed)."""


class Render(_Section):
    """The verification preview.

    It is rendered in passes until the relative noise of the object's pixels (estimated from
    two independent halves, :mod:`render.convergence`) is at most ``noise``, or until
    ``max_spp`` samples per pixel or ``time_cap_s`` seconds are spent (then verification
    fails and says so). ``spp`` is the first passes' samples (both halves together).
    ``denoise = "auto"`` writes a preview denoised by Open Image Denoise where that is
    trusted (the verdict still reads the raw noise); ``"off"`` never denoises.
    ``sampling = "adaptive"`` gives each pixel samples in proportion to its own noise after
    the first two rounds; ``"uniform"`` gives every object pixel the same.
    """

    width_px: Annotated[int, at.Ge(16), at.Le(4096)] = 1024
    height_px: Annotated[int, at.Ge(16), at.Le(4096)] = 768
    spp: Annotated[int, at.Ge(1), at.Le(65536)] = 8
    noise: Annotated[float, at.Gt(0.0), at.Le(1.0)] = 0.02
    """Relative noise a converged preview may have (RMS standard error over the object's mean)."""
    max_spp: Annotated[int, at.Ge(1), at.Le(1 << 20)] = 4096
    time_cap_s: Annotated[float, at.Gt(0.0), at.Le(86400.0)] = 60.0
    denoise: Literal["auto", "off"] = "auto"
    sampling: Literal["adaptive", "uniform"] = "adaptive"
    elevation_rad: Annotated[float, at.Gt(0.0), at.Lt(math.pi / 2)] = math.radians(40.0)
    azimuth_rad: Annotated[float, at.Ge(-2 * math.pi), at.Le(2 * math.pi)] = math.radians(-60.0)
    distance_scale: Annotated[float, at.Ge(0.2), at.Le(1000.0)] = 1.0
    """Camera distance relative to the one that frames the object (larger: farther away)."""
    seed: Annotated[int, at.Ge(0), at.Lt(2**32)] = 0
    """Seed of the path tracer's samples (independent of the texture's and the BRDF's)."""
    mode: Literal["auto", "model", "table", "geometry"] = "auto"
    """How the relief is rendered: its fitted BRDF ('model'), its traced BRDF table ('table') or
    its geometry; 'auto' takes the cheapest that shows what the camera can resolve."""

    @model_validator(mode="after")
    def _budget_holds_first_passes(self) -> Render:
        if self.max_spp < self.spp:
            raise ValueError(f"'max_spp' ({self.max_spp}) must be at least 'spp' ({self.spp})")
        return self


Vector3 = tuple[float, float, float]


class Combine(_Section):
    """A boolean with another solid, applied to the relief model (manifold3d).

    ``shape = "box"`` is a box of ``size_mm`` centred at ``translate_mm``;
    ``shape = "mesh"`` is a closed mesh file (``path``, relative to the design file),
    scaled by ``scale`` and moved by ``translate_mm``.
    """

    op: Literal["union", "difference", "intersection"]
    shape: Literal["box", "mesh"] = "box"
    size_mm: tuple[PositiveMM, PositiveMM, PositiveMM] = Field(default=(1.0, 1.0, 1.0), strict=False)
    path: str | None = None
    scale: Annotated[float, at.Gt(0.0), at.Le(1e6)] = 1.0
    translate_mm: tuple[float, float, float] = Field(default=(0.0, 0.0, 0.0), strict=False)

    @model_validator(mode="after")
    def _mesh_needs_path(self) -> Combine:
        if self.shape == "mesh" and not self.path:
            raise ValueError("a mesh combine needs 'path'")
        return self


class Design(_Section):
    """A whole design: base shape, texture, relief, printer, material, targets, preview."""

    name: str = Field(default="untitled", min_length=1, max_length=200)
    base: Annotated[TileBase | MeshBase, Field(discriminator="shape")] = TileBase()
    texture: Texture = Texture()
    relief: Relief = Relief()
    printer: Printer = Printer()
    material: Material = Material()
    appearance: Appearance = Appearance()
    brdf: Brdf = Brdf()
    render: Render = Render()
    combine: list[Combine] = Field(default_factory=list, strict=False)
    solve: Solve | None = None
    """``printapp solve``'s free parameters and bounds (ignored by ``printapp design``)."""

    @model_validator(mode="before")
    @classmethod
    def _default_base_shape(cls, data: Any) -> Any:
        # A [base] table without 'shape' is a tile unless it names a mesh path.
        if isinstance(data, dict) and isinstance(data.get("base"), dict) and "shape" not in data["base"]:
            base = dict(data["base"])
            base["shape"] = "mesh" if "path" in base else "tile"
            data = {**data, "base": base}
        return data

    @property
    def pitch_mm(self) -> float:
        """Sampling pitch of the relief (mm): the design's, else the printer's pixel pitch."""
        return self.relief.pitch_mm if self.relief.pitch_mm is not None else self.printer.profile.pitch_mm

    @property
    def layer_height_mm(self) -> float:
        """Layer height (mm): the design's, else the printer profile's."""
        lh = self.printer.layer_height_mm
        return lh if lh is not None else self.printer.profile.layer_height_mm

    @model_validator(mode="after")
    def _stretch_direction(self) -> Design:
        # A stretched noise has one direction: say which when two are given, never ignore one.
        texture = self.texture
        if (
            texture.kind not in ("scn", "fbm", "turbulence")
            or texture.stretch == 1.0
            or texture.field is None
        ):
            return self
        if isinstance(self.base, TileBase):
            raise ValueError(
                f"texture.field {texture.field!r}: on a tile, {texture.kind} is stretched along angle_deg in "
                "the tile's frame; field directs lic, and stretched noise on a mesh base"
            )
        if texture.angle_rad != 0.0:
            raise ValueError(
                f"texture: give either field ({texture.field!r}) or angle_deg "
                f"({math.degrees(texture.angle_rad):g}) for the stretch on a mesh, not both"
            )
        return self

    @model_validator(mode="after")
    def _bssrdf_needs_a_tile(self) -> Design:
        # Known from the file alone; whether the tile's grid resolves the light's path is known
        # only with the material's optics, at rendering (printapp.material_design.render_choice).
        if self.material.translucency == "bssrdf" and (not isinstance(self.base, TileBase) or self.combine):
            raise ValueError(
                'material.translucency = "bssrdf": the BSSRDF is rendered for tiles without booleans only; '
                'use "medium" or "auto"'
            )
        return self

    @model_validator(mode="after")
    def _solve_needs_a_tile(self) -> Design:
        if self.solve is not None and not isinstance(self.base, TileBase):
            raise ValueError(
                "a [solve] table needs a tile base: solve predicts the as-printed relief of tiles"
            )
        return self

    @model_validator(mode="after")
    def _grid_size(self) -> Design:
        if isinstance(self.base, TileBase):
            pitch = self.pitch_mm
            side = max(self.base.width_mm, self.base.depth_mm) / pitch
            if side > _MAX_GRID_SIDE:
                raise ValueError(
                    f"relief.pitch_mm {pitch:g} gives {side:.0f} samples along a "
                    f"{max(self.base.width_mm, self.base.depth_mm):g} mm side; "
                    f"expected at most {_MAX_GRID_SIDE}"
                )
        return self


# ---------------------------------------------------------------------------------------------
# Loading, with one clear sentence per problem

_EXPLAINER = SchemaExplainer(Design, "base", {"tile": TileBase, "mesh": MeshBase}, _UNIT_ALIASES)


def design_from_dict(data: Any, source: str = "design") -> Design:
    """Validate a parsed TOML document into a :class:`Design`.

    Raises
    ------
    DesignError
        With one sentence naming ``source``, the key and what was expected.
    """
    if not isinstance(data, dict):
        raise DesignError(f"{source}: expected a TOML table at the top level")
    try:
        return Design.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        # An unknown key explains the rest of a table's errors best; report it first.
        errors.sort(key=lambda e: (e["type"] != "extra_forbidden", len(e["loc"])))
        raise DesignError(_EXPLAINER.explain(errors[0], source, data)) from None
    except (TypeError, ValueError, OverflowError) as exc:
        raise DesignError(f"{source}: {exc}") from None
