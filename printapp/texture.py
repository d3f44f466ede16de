"""Evaluate a design's texture at points in millimetres and turn it into relief."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

import noise
from noise.heightfield import HeightField
from printapp.design import Design, Texture, TileBase


def to_noise_units(points_mm: np.ndarray, texture: Texture) -> np.ndarray:
    """Map points (mm) to noise coordinates: stretch along ``angle``, then one cell per feature size."""
    pts = np.array(points_mm, dtype=np.float64, copy=True)
    if texture.stretch != 1.0:
        c, s = math.cos(texture.angle_rad), math.sin(texture.angle_rad)
        u = c * pts[:, 0] + s * pts[:, 1]
        v = -s * pts[:, 0] + c * pts[:, 1]
        u /= texture.stretch
        pts[:, 0] = c * u - s * v
        pts[:, 1] = s * u + c * v
    return pts / texture.feature_size_mm


def evaluate_texture(points_mm: np.ndarray, texture: Texture, pitch_mm: float | None = None) -> np.ndarray:
    """Raw texture values at ``points_mm`` ((n, 2) or (n, 3), mm).

    ``pitch_mm`` (the sampling pitch) drops fBm/turbulence octaves finer than two
    samples: a printer cannot reproduce them, and sampling them would alias.
    """
    if texture.kind == "lic":
        raise ValueError("lic textures are evaluated on grids or meshes, not at scattered points")
    pts = to_noise_units(points_mm, texture)
    pitch = None if pitch_mm is None else pitch_mm / texture.feature_size_mm
    common = {"seed": texture.seed, "impulses": texture.impulses, "cell_seed": texture.cell_seed}
    if texture.kind == "scn":
        return noise.sparse_convolution(pts, **common)
    if texture.kind == "fbm":
        return noise.fbm(
            pts,
            octaves=texture.octaves,
            lacunarity=texture.lacunarity,
            H=texture.H,
            min_pitch=pitch,
            **common,
        )
    if texture.kind == "marble":
        return _vein_sign(texture) * noise.veins(pts, **_vein_options(texture), min_pitch=pitch, **common)
    return noise.turbulence(pts, low=texture.low, high=texture.high, min_pitch=pitch, **common)


def _vein_options(texture: Texture) -> dict[str, float | int]:
    """The marble's parameters in noise units (one turbulence cell per unit)."""
    return {
        "angle": texture.vein_angle_rad,
        "period": texture.vein_period_mm / texture.feature_size_mm,
        "strength": texture.turbulence_strength,
        "sharpness": texture.vein_sharpness,
        "low": texture.low,
        "high": texture.high,
    }


def _vein_sign(texture: Texture) -> float:
    """Relief sign of a marble: veins (value 1) up when raised, down when sunk."""
    return -1.0 if texture.veins == "sunk" else 1.0


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
    x_mm: np.ndarray, y_mm: np.ndarray, texture: Texture, pitch_mm: float
) -> np.ndarray:
    """Raw texture values on the grid ``x_mm`` by ``y_mm`` (z = 0), shaped (len(y), len(x)).

    Uses the noise package's grid fast path when the texture's axes line up with the
    grid (no stretch, or a stretch along x); otherwise evaluates the points one by one.
    """
    if texture.kind == "lic":
        from noise.lic import lic2d
        from printapp.fields import field_on_grid

        noise_values = noise.sparse_convolution_grid(
            x_mm / texture.feature_size_mm,
            y_mm / texture.feature_size_mm,
            seed=texture.seed,
            impulses=texture.impulses,
            cell_seed=texture.cell_seed,
        )
        u, v = field_on_grid(texture.field, x_mm, y_mm)
        return lic2d(u, v, noise_values, length=max(texture.length_mm / pitch_mm, 1.0))
    if texture.stretch == 1.0 or texture.angle_rad == 0.0:
        xs = x_mm / (texture.feature_size_mm * texture.stretch)
        ys = y_mm / texture.feature_size_mm
        pitch = pitch_mm / texture.feature_size_mm
        common = {"seed": texture.seed, "impulses": texture.impulses, "cell_seed": texture.cell_seed}
        if texture.kind == "scn":
            return noise.sparse_convolution_grid(xs, ys, **common)
        if texture.kind == "fbm":
            return noise.fbm_grid(
                xs,
                ys,
                octaves=texture.octaves,
                lacunarity=texture.lacunarity,
                H=texture.H,
                min_pitch=pitch,
                **common,
            )
        if texture.kind == "marble":
            return _vein_sign(texture) * noise.veins_grid(
                xs, ys, **_vein_options(texture), min_pitch=pitch, **common
            )
        return noise.turbulence_grid(xs, ys, low=texture.low, high=texture.high, min_pitch=pitch, **common)
    xx, yy = np.meshgrid(x_mm, y_mm)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    return evaluate_texture(pts, texture, pitch_mm=pitch_mm).reshape(len(y_mm), len(x_mm))


def palette_colours(values: np.ndarray, texture: Texture) -> np.ndarray:
    """Colours (sRGB in [0, 1], shape ``values.shape + (3,)``) of texture values through its palette.

    The palette's colours are spaced evenly from ``palette_range[0]`` to
    ``palette_range[1]`` (which may run downwards) and interpolated linearly; values
    beyond the range take the end colours. Without a palette, a grey ramp from black to
    white; without a range, 0..1 for marble and the values' own minimum..maximum otherwise.
    """
    palette = texture.palette or ("#000000", "#ffffff")
    colours = np.array([[int(c[i : i + 2], 16) / 255.0 for i in (1, 3, 5)] for c in palette])
    if texture.palette_range is not None:
        lo, hi = texture.palette_range
    elif texture.kind == "marble":
        lo, hi = 0.0, 1.0
    else:
        lo, hi = float(values.min()), float(values.max())
    if hi == lo:
        t = np.zeros_like(values, dtype=np.float64)
    else:
        t = np.clip((np.asarray(values, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
    knots = np.linspace(0.0, 1.0, len(colours))
    return np.stack([np.interp(t, knots, colours[:, c]) for c in range(3)], axis=-1)


def texture_colour_grid(x_mm: np.ndarray, y_mm: np.ndarray, texture: Texture, pitch_mm: float) -> np.ndarray:
    """The texture on the grid ``x_mm`` by ``y_mm`` coloured by its palette: (len(y), len(x), 3) sRGB.

    Marble is coloured by its [0, 1] value whether its veins are raised or sunk.
    """
    values = evaluate_texture_grid(x_mm, y_mm, texture, pitch_mm)
    if texture.kind == "marble":
        values = _vein_sign(texture) * values
    return palette_colours(values, texture)


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
    texture's values (marble: its [0, 1] value). The square starts at the origin, with
    pixel centres at ``(i + 1/2) width / size``, as ``printapp fit`` synthesised it; the
    width defaults to the design's tile width (20 mm for a fragment). Returns a one-line
    summary.

    Raises
    ------
    PrintappError
        If the file does not load as a design, or the width or output is unusable.
    """
    import io

    from printapp.design import load_design
    from printapp.errors import PrintappError
    from printapp.exporters import atomic_write_bytes

    design = load_design(path)
    if width_mm is None:
        width_mm = design.base.width_mm if isinstance(design.base, TileBase) else 20.0
    if not (math.isfinite(width_mm) and width_mm > 0):
        raise PrintappError(f"--width-mm: expected a positive width in mm, got {width_mm}")
    pitch = width_mm / size
    axis = (np.arange(size) + 0.5) * pitch
    texture = design.texture
    values = evaluate_texture_grid(axis, axis, texture, pitch)
    if texture.kind == "marble":
        values = _vein_sign(texture) * values
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
