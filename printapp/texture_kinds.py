"""The texture kinds a design, ``printapp texture``, ``printapp fit`` and the report know: one registry.

Each kind says once what it is, which ``[texture]`` keys it reads, and how it is
evaluated at scattered points and on grids (lengths in mm, converted here to noise
units: one unit per ``feature_size_mm``). The design schema takes its ``kind`` values
from :data:`TEXTURE_KINDS`, the CLI its choices and help, the fit its fragment's keys.

The kinds read their parameters through :class:`TextureParams`, the attributes they
need; the design schema's ``Texture`` has them all, and imports this registry for its
``kind`` values (so this module never imports the schema).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class TextureParams(Protocol):
    """What the texture kinds read of a ``[texture]`` table (lengths in mm, angles in radians)."""

    kind: str
    feature_size_mm: float
    seed: int
    impulses: int
    cell_seed: str
    octaves: int
    lacunarity: float
    H: float
    low: int
    high: int
    stretch: float
    angle_rad: float
    field: str | None
    frame_blend_mm: float | None
    onb: str
    length_mm: float
    vein_angle_rad: float
    vein_period_mm: float
    turbulence_strength: float
    vein_sharpness: float
    veins: str
    vein_network: str
    vein_scale_mm: float
    vein_octaves: int
    vein_gain: float
    vein_H: float  # noqa: N815 - Musgrave's H, as fBm's
    vein_width: float
    vein_warp: float
    vein_layers: int
    vein_layer_turn_rad: float
    vein_layer_scale: float
    vein_layer_weight: float
    vein_fade: float
    ground_weight: float
    ground_H: float  # noqa: N815 - fBm's H


PointsFn = Callable[[np.ndarray, TextureParams, float | None], np.ndarray]
GridFn = Callable[[np.ndarray, np.ndarray, TextureParams, float | None], np.ndarray]
FramedFn = Callable[[np.ndarray, object, TextureParams, float | None], np.ndarray]


@dataclass(frozen=True)
class TextureKind:
    """One kind of texture.

    Attributes
    ----------
    name : str
        The ``[texture] kind`` value.
    summary : str
        One line for help texts and the report.
    parameters : tuple of str
        The ``[texture]`` keys (internal names) this kind reads beyond the common ones
        (``feature_size_mm``, ``seed``, ``impulses``, ``cell_seed``, ``stretch``, ``angle_rad``).
    points : callable or None
        ``points(pts, texture, min_pitch)``: values at scattered points in noise units;
        None where the kind needs a grid or a mesh (LIC).
    grid : callable
        ``grid(x_mm, y_mm, texture, pitch_mm)``: values on the grid x by y (mm), shaped
        (len(y), len(x)); ``pitch_mm`` None keeps every octave.
    unit_range : bool
        Values lie in [0, 1] (greys and palettes map 0..1); else they are stretched from
        their minimum to their maximum.
    framed : callable or None
        ``framed(pts, frames, texture, min_pitch)``: values at points in noise units,
        stretched by ``texture.stretch`` along each point's tangent in ``frames`` (a
        :class:`noise.frames.SurfaceFrames`, blended to isotropic around its singular
        points); None where a kind does not follow tangent frames (marble keeps its veins'
        world direction; lic follows its field by itself).
    """

    name: str
    summary: str
    parameters: tuple[str, ...]
    points: PointsFn | None
    grid: GridFn
    unit_range: bool = False
    framed: FramedFn | None = None


def _noise():  # noqa: ANN202
    # The kernels pull in numba; the CLI imports this registry for its help texts only.
    import noise

    return noise


def _common(texture: TextureParams) -> dict[str, object]:
    return {"seed": texture.seed, "impulses": texture.impulses, "cell_seed": texture.cell_seed}


def _noise_pitch(texture: TextureParams, pitch_mm: float | None) -> float | None:
    """The sampling pitch in noise units: octaves finer than two samples are dropped by the kernels."""
    return None if pitch_mm is None else pitch_mm / texture.feature_size_mm


VEINED_KINDS = ("marble", "veined")
"""Kinds whose ``veins`` key raises or sinks the veins."""
GROUND_STREAM = 5
"""The noise stream (:func:`noise.tables.stream_seed`) of a veined texture's fBm ground."""
FADE_STREAM = 6
"""The noise stream of the field that fades a veined texture's veins in and out."""


def vein_sign(texture: TextureParams) -> float:
    """Relief sign of veins: up when raised, down when sunk (marble and veined); 1 for other kinds."""
    return -1.0 if texture.kind in VEINED_KINDS and texture.veins == "sunk" else 1.0


def _vein_options(texture: TextureParams) -> dict[str, float | int]:
    """The marble's parameters in noise units (one turbulence cell per unit)."""
    return {
        "angle": texture.vein_angle_rad,
        "period": texture.vein_period_mm / texture.feature_size_mm,
        "strength": texture.turbulence_strength,
        "sharpness": texture.vein_sharpness,
        "low": texture.low,
        "high": texture.high,
    }


def _grid_axes(x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams) -> tuple[np.ndarray, np.ndarray]:
    """Noise-unit axes of a grid whose stretch (if any) runs along x."""
    return x_mm / (texture.feature_size_mm * texture.stretch), y_mm / texture.feature_size_mm


def _scn_points(pts: np.ndarray, texture: TextureParams, min_pitch: float | None) -> np.ndarray:
    return _noise().sparse_convolution(pts, **_common(texture))


def _scn_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    return _noise().sparse_convolution_grid(*_grid_axes(x_mm, y_mm, texture), **_common(texture))


def _scn_framed(pts: np.ndarray, frames, texture: TextureParams, min_pitch: float | None) -> np.ndarray:  # noqa: ANN001
    from noise.framed import sparse_convolution_framed

    return sparse_convolution_framed(
        pts, frames.tangent, frames.normal, stretch=texture.stretch, blend=frames.blend, **_common(texture)
    )


def _fbm_points(pts: np.ndarray, texture: TextureParams, min_pitch: float | None) -> np.ndarray:
    return _noise().fbm(
        pts,
        octaves=texture.octaves,
        lacunarity=texture.lacunarity,
        H=texture.H,
        min_pitch=min_pitch,
        **_common(texture),
    )


def _fbm_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    return _noise().fbm_grid(
        *_grid_axes(x_mm, y_mm, texture),
        octaves=texture.octaves,
        lacunarity=texture.lacunarity,
        H=texture.H,
        min_pitch=_noise_pitch(texture, pitch_mm),
        **_common(texture),
    )


def _fbm_framed(pts: np.ndarray, frames, texture: TextureParams, min_pitch: float | None) -> np.ndarray:  # noqa: ANN001
    from noise.framed import fbm_framed

    return fbm_framed(
        pts,
        frames.tangent,
        frames.normal,
        stretch=texture.stretch,
        blend=frames.blend,
        octaves=texture.octaves,
        lacunarity=texture.lacunarity,
        H=texture.H,
        min_pitch=min_pitch,
        **_common(texture),
    )


def _turbulence_points(pts: np.ndarray, texture: TextureParams, min_pitch: float | None) -> np.ndarray:
    return _noise().turbulence(
        pts, low=texture.low, high=texture.high, min_pitch=min_pitch, **_common(texture)
    )


def _turbulence_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    return _noise().turbulence_grid(
        *_grid_axes(x_mm, y_mm, texture),
        low=texture.low,
        high=texture.high,
        min_pitch=_noise_pitch(texture, pitch_mm),
        **_common(texture),
    )


def _turbulence_framed(
    pts: np.ndarray, frames, texture: TextureParams, min_pitch: float | None
) -> np.ndarray:  # noqa: ANN001
    from noise.framed import turbulence_framed

    return turbulence_framed(
        pts,
        frames.tangent,
        frames.normal,
        stretch=texture.stretch,
        blend=frames.blend,
        low=texture.low,
        high=texture.high,
        min_pitch=min_pitch,
        **_common(texture),
    )


def _marble_points(pts: np.ndarray, texture: TextureParams, min_pitch: float | None) -> np.ndarray:
    return vein_sign(texture) * _noise().veins(
        pts, **_vein_options(texture), min_pitch=min_pitch, **_common(texture)
    )


def _marble_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    return vein_sign(texture) * _noise().veins_grid(
        *_grid_axes(x_mm, y_mm, texture),
        **_vein_options(texture),
        min_pitch=_noise_pitch(texture, pitch_mm),
        **_common(texture),
    )


def veined_values(
    pts: np.ndarray, texture: TextureParams, min_pitch: float | None, sampler=None
) -> np.ndarray:
    """A veined texture's value (before :func:`vein_sign`) at points in units of ``feature_size_mm``.

    ``veins * exp(vein_fade * g - vein_fade^2 / 2) + ground_weight * ground``: the vein network
    (:func:`noise.ridged.vein_network`, cells of ``vein_scale_mm``), faded in and out by
    ``g``, unit-variance fBm (three octaves, H = 1) with cells four times the veins', over a
    unit-variance fBm ground (cells of ``feature_size_mm``). ``sampler`` replaces the exact
    noise (``printapp fit`` reads it from tables, :class:`noise.tables.NoiseTable`).
    """
    from noise.ridged import fbm_sampled, vein_network
    from noise.tables import exact_sampler

    if sampler is None:
        sampler = exact_sampler(texture.seed, texture.impulses, texture.cell_seed)
    ratio = texture.feature_size_mm / texture.vein_scale_mm
    values = vein_network(
        pts * ratio,
        basis="noise" if texture.vein_network == "ridged" else "cells",
        octaves=texture.vein_octaves,
        lacunarity=2.0,
        H=texture.vein_H,
        gain=texture.vein_gain,
        width=texture.vein_width,
        sharpness=texture.vein_sharpness,
        warp=texture.vein_warp,
        layers=texture.vein_layers,
        layer_turn=texture.vein_layer_turn_rad,
        layer_scale=texture.vein_layer_scale,
        layer_weight=texture.vein_layer_weight,
        seed=texture.seed,
        min_pitch=None if min_pitch is None else min_pitch * ratio,
        sampler=sampler,
    )
    if texture.vein_fade > 0:
        fade = texture.vein_fade
        g = fbm_sampled(pts * (ratio / 4.0), octaves=3, H=1.0, stream=FADE_STREAM, sampler=sampler)
        values = values * np.exp(fade * g - 0.5 * fade * fade)
    if texture.ground_weight > 0:
        values = values + texture.ground_weight * fbm_sampled(
            pts,
            octaves=texture.octaves,
            lacunarity=texture.lacunarity,
            H=texture.ground_H,
            stream=GROUND_STREAM,
            min_pitch=min_pitch,
            sampler=sampler,
        )
    return values


def _veined_points(pts: np.ndarray, texture: TextureParams, min_pitch: float | None) -> np.ndarray:
    return vein_sign(texture) * veined_values(pts, texture, min_pitch)


def _veined_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    xs, ys = _grid_axes(x_mm, y_mm, texture)
    xx, yy = np.meshgrid(xs, ys)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    values = vein_sign(texture) * veined_values(pts, texture, _noise_pitch(texture, pitch_mm))
    return values.reshape(len(y_mm), len(x_mm))


def _lic_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    from noise.lic import lic2d
    from printapp.fields import LIC_MAX_TAPS, field_on_grid, lic_field

    # The field and the length are checked before any noise is made: a bad one fails at once.
    field = lic_field(texture)
    step = float(x_mm[1] - x_mm[0]) if pitch_mm is None else pitch_mm
    length_px = max(texture.length_mm / step, 1.0)
    taps = 2.0 * len(x_mm) * len(y_mm) * (length_px + 1.0)
    if taps > LIC_MAX_TAPS:
        fitting = texture.length_mm * LIC_MAX_TAPS / taps
        raise ValueError(
            f"length: {length_px:.6g}-pixel streamlines over {len(x_mm)} x {len(y_mm)} pixels are {taps:.3g} "
            f"noise samples, more than {LIC_MAX_TAPS:.0e} (about a minute); at most {fitting:.3g} fits"
        )
    u, v = field_on_grid(field, x_mm, y_mm)
    values = _noise().sparse_convolution_grid(
        x_mm / texture.feature_size_mm, y_mm / texture.feature_size_mm, **_common(texture)
    )
    return lic2d(u, v, values, length=length_px)


_OCTAVES = ("octaves", "lacunarity", "H")
_BAND = ("low", "high")

TEXTURE_KINDS: dict[str, TextureKind] = {
    kind.name: kind
    for kind in (
        TextureKind(
            "scn",
            "sparse convolution noise: random impulses convolved with a cubic kernel (the talk's noise)",
            (),
            _scn_points,
            _scn_grid,
            framed=_scn_framed,
        ),
        TextureKind(
            "fbm",
            "fractional Brownian motion: octaves of noise, each lacunarity^-H as strong",
            _OCTAVES,
            _fbm_points,
            _fbm_grid,
            framed=_fbm_framed,
        ),
        TextureKind(
            "turbulence",
            "turbulence: octaves low..high of |noise|, each half as strong (sharp creases)",
            _BAND,
            _turbulence_points,
            _turbulence_grid,
            framed=_turbulence_framed,
        ),
        TextureKind(
            "lic",
            "line integral convolution: fine noise smeared along the streamlines of a field",
            ("field", "length_mm"),
            None,
            _lic_grid,
        ),
        TextureKind(
            "marble",
            "veined marble: ((1 + sin(2 pi n.p / period + k turbulence(p))) / 2)^sharpness",
            ("vein_angle_rad", "vein_period_mm", "turbulence_strength", "vein_sharpness", *_BAND, "veins"),
            _marble_points,
            _marble_grid,
            unit_range=True,
        ),
        TextureKind(
            "veined",
            "branching veins: domain-warped ridged multifractal (noise or cellular cracks) over fBm",
            (
                "vein_network",
                "vein_scale_mm",
                "vein_octaves",
                "vein_gain",
                "vein_H",
                "vein_width",
                "vein_sharpness",
                "vein_warp",
                "vein_layers",
                "vein_layer_turn_rad",
                "vein_layer_scale",
                "vein_layer_weight",
                "vein_fade",
                "ground_weight",
                "ground_H",
                "octaves",
                "lacunarity",
                "veins",
            ),
            _veined_points,
            _veined_grid,
        ),
    )
}
"""Every texture kind, by name, in the order help texts list them."""

TEXTURE_KIND_NAMES: tuple[str, ...] = tuple(TEXTURE_KINDS)


def texture_kind(name: str) -> TextureKind:
    """The registered kind ``name``.

    Raises
    ------
    ValueError
        Naming the known kinds.
    """
    if name not in TEXTURE_KINDS:
        raise ValueError(f"expected a texture kind, one of {', '.join(TEXTURE_KIND_NAMES)}, got {name!r}")
    return TEXTURE_KINDS[name]


def stretch_field(texture: TextureParams) -> str:
    """The field a stretched scn, fbm or turbulence follows on a mesh: the design's, else ``angle``'s.

    Without a field, ``angle_deg`` keeps its tile meaning on a mesh: the world direction at
    that angle in the x-y plane, projected into each tangent plane (``constant:ANGLE``,
    as for lic), so a stretch never goes without a direction.
    """
    if texture.field is not None:
        return texture.field
    return f"constant:{math.degrees(texture.angle_rad):.12g}"


def stretch_to_noise_units(points_mm: np.ndarray, texture: TextureParams) -> np.ndarray:
    """Map points (mm) to noise coordinates: shrink by ``stretch`` along ``angle``, one cell per feature."""
    pts = np.array(points_mm, dtype=np.float64, copy=True)
    if texture.stretch != 1.0:
        c, s = math.cos(texture.angle_rad), math.sin(texture.angle_rad)
        u = c * pts[:, 0] + s * pts[:, 1]
        v = -s * pts[:, 0] + c * pts[:, 1]
        u /= texture.stretch
        pts[:, 0] = c * u - s * v
        pts[:, 1] = s * u + c * v
    return pts / texture.feature_size_mm
