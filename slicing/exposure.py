"""Exposure from heights: every pixel of a relief tile lit with the grey level its height asks for.

The slicer of :mod:`slicing.layers` lights a pixel by how much of it the part's section
covers (PrusaSlicer's anti-aliasing): a layer's pixels are all or nothing inside the part
and grey only along its outline, so the layer tops of a relief come out flat. Here the
pixels wholly inside the tile are instead lit from the relief's height at their centres:
in each layer, a pixel is asked to cure ``d = clip(H - z_bottom, 0, t)`` of resin, where
``H`` is the height wanted at the pixel and ``t`` the layer's thickness, and gets

* with ``grey_levels``, the grey level whose dose cures ``d`` by the cure model
  (:meth:`slicing.printed.CureModel.grey_for_thickness`): sub-layer relief, as far as 8-bit
  grey levels and the resin's threshold allow;
* without, 255 where ``d`` is at least half the layer and 0 elsewhere (a binary pixel
  printed where the relief reaches the layer's middle, as PrusaSlicer's slice plane does).

A pixel-scale texture of depth ``a`` lowers each pixel's ``H`` by ``a u``, ``u`` in [0, 1)
drawn from a hash of the pixel's place on the display and a seed: texture at the printer's
finest lateral scale, cut into the layer tops so that none is a flat mirror. Pixels on the
tile's outline keep the slicer's anti-aliased coverage. The light a pixel spills into its
neighbours (the display's blur) is not modelled: it would soften this texture.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from noise.heightfield import HeightField
from slicing.layers import Slices, slice_heightfield
from slicing.printed import CureModel
from slicing.printers import PrinterProfile

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def pixel_hash_unit(cols: np.ndarray, rows: np.ndarray, seed: int) -> np.ndarray:
    """A number in [0, 1) per display pixel (column, row): a 64-bit mix (splitmix64) of both and the seed."""
    with np.errstate(over="ignore"):
        key = (
            np.asarray(cols, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
            ^ np.asarray(rows, dtype=np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)
            ^ np.uint64(seed & 0xFFFFFFFFFFFFFFFF)
        )
        key = (key ^ (key >> np.uint64(30))) * _M1
        key = (key ^ (key >> np.uint64(27))) * _M2
        key = key ^ (key >> np.uint64(31))
    return (key >> np.uint64(11)).astype(np.float64) / float(1 << 53)


def triangulated_heights(field: HeightField, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
    """Heights of the field's triangulated surface (two triangles per cell, diagonal v00-v11) at (x, y).

    ``x_mm`` and ``y_mm`` are in the field's frame (its origin at sample (0, 0)) and are
    clamped to it; the same surface :func:`slicing.layers.slice_heightfield` slices.
    """
    h = field.heights_mm
    ny, nx = h.shape
    fx = np.clip((np.asarray(x_mm) - field.origin_x_mm) / field.pitch_x_mm, 0.0, nx - 1 - 1e-9)
    fy = np.clip((np.asarray(y_mm) - field.origin_y_mm) / field.pitch_y_mm, 0.0, ny - 1 - 1e-9)
    c = np.floor(fx).astype(np.int64)
    r = np.floor(fy).astype(np.int64)
    u, v = fx - c, fy - r
    h00, h10, h01, h11 = h[r, c], h[r, c + 1], h[r + 1, c], h[r + 1, c + 1]
    lower = h00 + u * (h10 - h00) + v * (h11 - h10)
    upper = h00 + v * (h01 - h00) + u * (h11 - h01)
    return np.where(u >= v, lower, upper)


@dataclass
class ExposedSlices(Slices):
    """Slices whose pixels inside the tile are lit from the relief's heights (see the module).

    ``coverage(k)`` of a layer is its pixels' grey level over 255 (the share of a fully lit
    pixel's dose), and :meth:`grey` gives the grey levels back exactly.
    """

    target_top_mm: np.ndarray | None = None
    """(rows, cols) height above the bed each pixel inside the tile is to reach; NaN on the outline."""
    cure: CureModel | None = None
    grey_levels: bool = True
    sliced_layers: int = 0
    """Layers of the slicer's own; those above (the top of a relief that ends in a layer's upper
    half, which PrusaSlicer's slice planes leave out) are lit from the heights alone."""

    def _exposed(self, k: int, geometric: np.ndarray) -> np.ndarray:
        """Layer k's grey levels: ``geometric`` (the slicer's, whole window) with the tile's inside relit."""
        assert self.target_top_mm is not None and self.cure is not None
        thickness = self.profile.initial_layer_height_mm if k == 0 else self.layer_height_mm
        bottom = float(self.heights_mm[k]) - 0.5 * thickness
        inside, lowest, highest = self._inside()
        if bottom + thickness <= lowest or bottom >= highest:  # wholly below or above the relief
            return np.where(inside, np.uint8(255 if bottom < lowest else 0), geometric).astype(np.uint8)
        wanted = np.clip(np.where(inside, self.target_top_mm, 0.0) - bottom, 0.0, thickness)
        if self.grey_levels:
            lit = self.cure.grey_for_thickness(wanted, thickness)
        else:
            lit = np.where(wanted >= 0.5 * thickness, 255, 0).astype(np.uint8)
        return np.where(inside, lit, geometric).astype(np.uint8)

    def _inside(self) -> tuple[np.ndarray, float, float]:
        """The pixels lit from heights, and the lowest and highest height asked of them (cached)."""
        cached = getattr(self, "_inside_cache", None)
        if cached is None:
            assert self.target_top_mm is not None
            inside = np.isfinite(self.target_top_mm)
            tops = self.target_top_mm[inside]
            cached = (inside, float(tops.min()), float(tops.max())) if tops.size else (inside, 0.0, 0.0)
            self._inside_cache = cached
        return cached

    def coverages(self) -> Any:
        for k, cov in super().coverages():
            if k >= self.sliced_layers:
                break
            yield k, self._exposed(k, Slices.grey(self, cov)) / 255.0
        for k in range(self.sliced_layers, self.n_layers):
            yield k, self._exposed(k, np.zeros((self.rows, self.cols), dtype=np.uint8)) / 255.0

    def grey(self, coverage: np.ndarray) -> np.ndarray:
        return np.round(coverage * 255.0).astype(np.uint8)

    def layer_grey(self, k: int, scratch: dict | None = None) -> tuple[np.ndarray, int, int]:
        window = np.zeros((self.rows, self.cols), dtype=np.uint8)
        if k < self.sliced_layers:
            part, r0, c0 = super().layer_grey(k, scratch)
            window[r0 : r0 + part.shape[0], c0 : c0 + part.shape[1]] = part
        return self._exposed(k, window), 0, 0

    def max_winding(self) -> float:
        """The slicer's check (:meth:`slicing.layers.Slices.max_winding`) over the layers it sliced."""
        fields = {name: getattr(self, name) for name in Slices.__dataclass_fields__}
        fields["heights_mm"] = self.heights_mm[: self.sliced_layers]
        return Slices(**fields).max_winding()

    def section_areas_mm2(self) -> np.ndarray:
        """Area each layer lights (mm^2): its grey levels' share of a full pixel, summed."""
        pixel = self.profile.pitch_x_mm * self.profile.pitch_y_mm
        return np.array([float(cov.sum()) * pixel for _, cov in self.coverages()])


def expose_heightfield(
    field: HeightField,
    base_thickness_mm: float,
    profile: PrinterProfile,
    *,
    cure: CureModel,
    grey_levels: bool,
    pixel_texture_mm: float = 0.0,
    seed: int = 0,
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
) -> ExposedSlices:
    """Slice a relief tile with its pixels lit from its heights (see the module).

    The layers, their count and the tile's outline are those of
    :func:`slicing.layers.slice_heightfield`; the pixels wholly inside the tile get the grey
    levels of the relief's height at their centres, less the pixel-scale texture.

    Raises
    ------
    ValueError
        As :func:`slicing.layers.slice_heightfield`, or for a negative texture depth.
    """
    if not (pixel_texture_mm >= 0.0 and np.isfinite(pixel_texture_mm)):
        raise ValueError(f"pixel texture: expected a depth >= 0 mm, got {pixel_texture_mm!r}")
    geometric = slice_heightfield(
        field, base_thickness_mm, profile, layer_height_mm=layer_height_mm, antialias=antialias
    )
    px, py = profile.pitch_x_mm, profile.pitch_y_mm
    cols = geometric.col0 + np.arange(geometric.cols)
    rows = geometric.row0 + np.arange(geometric.rows)
    # Pixel centres in the field's frame.
    xd = (cols + 0.5) * px - geometric.shift_mm[0]
    yd = (rows + 0.5) * py - geometric.shift_mm[1]
    x0, y0 = field.origin_x_mm, field.origin_y_mm
    inside_x = (xd - 0.5 * px >= x0) & (xd + 0.5 * px <= x0 + field.width_mm)
    inside_y = (yd - 0.5 * py >= y0) & (yd + 0.5 * py <= y0 + field.depth_mm)
    yy, xx = np.meshgrid(yd, xd, indexing="ij")
    top = base_thickness_mm + triangulated_heights(field, xx, yy)
    if pixel_texture_mm > 0.0:
        cc, rr = np.meshgrid(cols, rows)
        top = top - pixel_texture_mm * pixel_hash_unit(cc, rr, seed)
    top = np.where(inside_y[:, None] & inside_x[None, :], top, np.nan)
    fields = {name: getattr(geometric, name) for name in Slices.__dataclass_fields__}
    # Layers up to the highest height asked: slab k >= 1 ends at ilh + k lh.
    ilh, lh = profile.initial_layer_height_mm, geometric.layer_height_mm
    highest = float(np.nanmax(top)) if np.any(np.isfinite(top)) else 0.0
    needed = 1 + max(0, math.ceil((highest - ilh) / lh - 1e-9))
    if needed > geometric.n_layers:
        k = np.arange(geometric.n_layers, needed, dtype=np.float64)
        fields["heights_mm"] = np.concatenate([geometric.heights_mm, ilh + (k - 0.5) * lh])
    return ExposedSlices(
        **fields, target_top_mm=top, cure=cure, grey_levels=grey_levels, sliced_layers=geometric.n_layers
    )
