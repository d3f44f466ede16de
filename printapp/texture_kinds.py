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


def vein_sign(texture: TextureParams) -> float:
    """Relief sign of a marble: veins (value 1) up when raised, down when sunk; 1 for other kinds."""
    return -1.0 if texture.kind == "marble" and texture.veins == "sunk" else 1.0


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


def _lic_grid(
    x_mm: np.ndarray, y_mm: np.ndarray, texture: TextureParams, pitch_mm: float | None
) -> np.ndarray:
    from noise.lic import lic2d
    from printapp.fields import LIC_MAX_TAPS, field_on_grid, lic_field

    values = _noise().sparse_convolution_grid(
        x_mm / texture.feature_size_mm, y_mm / texture.feature_size_mm, **_common(texture)
    )
    step = float(x_mm[1] - x_mm[0]) if pitch_mm is None else pitch_mm
    length_px = max(texture.length_mm / step, 1.0)
    taps = 2.0 * len(x_mm) * len(y_mm) * (length_px + 1.0)
    if taps > LIC_MAX_TAPS:
        fitting = texture.length_mm * LIC_MAX_TAPS / taps
        raise ValueError(
            f"length: {length_px:.6g}-pixel streamlines over {len(x_mm)} x {len(y_mm)} pixels are {taps:.3g} "
            f"noise samples, more than {LIC_MAX_TAPS:.0e} (about a minute); at most {fitting:.3g} fits"
        )
    u, v = field_on_grid(lic_field(texture), x_mm, y_mm)
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
