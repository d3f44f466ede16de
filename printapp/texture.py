"""Evaluate a design's texture at points in millimetres and turn it into relief."""

from __future__ import annotations

import math

import numpy as np

import noise
from printapp.design import Design, Texture, TileBase
from printapp.heightfield import HeightField


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
    return noise.turbulence(pts, low=texture.low, high=texture.high, min_pitch=pitch, **common)


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
        return noise.turbulence_grid(xs, ys, low=texture.low, high=texture.high, min_pitch=pitch, **common)
    xx, yy = np.meshgrid(x_mm, y_mm)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    return evaluate_texture(pts, texture, pitch_mm=pitch_mm).reshape(len(y_mm), len(x_mm))


def relief_heightfield(design: Design) -> HeightField:
    """The relief of a tile design: texture on the tile's grid, scaled to the amplitude (mm)."""
    if not isinstance(design.base, TileBase):
        raise TypeError("relief_heightfield needs a tile design")
    ny, nx, dy, dx = tile_grid_shape(design.base, design.pitch_mm)
    values = evaluate_texture_grid(np.arange(nx) * dx, np.arange(ny) * dy, design.texture, max(dx, dy))
    return HeightField(normalise_peak_to_valley(values, design.relief.amplitude_mm), dx, dy)
