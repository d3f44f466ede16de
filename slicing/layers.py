"""Layer images on a printer's display: a mesh or a height field sliced into :class:`Slices`.

Conventions (PrusaSlicer 2.5, checked against its output):

* The part is dropped to z = 0 and its bounding box centred on the display, which
  covers bed X in [0, display_width] and Y in [0, display_height].
* A top view T has columns X / pitch and rows (H - Y) / pitch; a portrait display shows
  ``rot90(T, 1)``; ``mirror_x`` then flips left-right and ``mirror_y`` up-down.
* Slice heights: see :func:`slicing.raster.slice_heights`.
* Pixels are 8-bit grey, 0 dark and 255 cured; with anti-aliasing (PrusaSlicer's
  ``gamma_correction = 1``) edge pixels carry their exact area coverage.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from noise.heightfield import HeightField
from slicing.deflate import _deflate_layer, deflate_bound
from slicing.printers import PrinterProfile
from slicing.raster import (
    _layer_box,
    _max_winding,
    _rasterise_layer_grey,
    heightfield_segments,
    mark_blocks,
    rasterise_sections,
    section_areas,
    section_segments,
    slice_heights,
)


@dataclass
class Slices:
    """A sliced part: its layers' coverage on a window of the display, and where the window sits.

    ``coverage(k)`` is the (rows, cols) fraction of each pixel cured in layer k, in bed
    coordinates (row 0 at the smallest Y, column 0 at the smallest X) for the window whose
    lower-left pixel is ``(col0, row0)`` of the top view's bed-aligned pixel grid.
    """

    profile: PrinterProfile
    heights_mm: np.ndarray
    layer_height_mm: float
    shift_mm: np.ndarray
    """Translation from the input mesh's coordinates to bed coordinates (mm)."""
    col0: int
    row0: int
    cols: int
    rows: int
    antialias: bool
    _layer: np.ndarray
    _segments: np.ndarray

    @property
    def n_layers(self) -> int:
        return int(self.heights_mm.size)

    def coverages(self) -> Iterator[tuple[int, np.ndarray]]:
        """(k, coverage) for every layer, in order; the array is reused between layers."""
        p = self.profile
        origin = (self.col0 * p.pitch_x_mm, self.row0 * p.pitch_y_mm)
        yield from rasterise_sections(
            self._layer,
            self._segments,
            self.n_layers,
            origin,
            (p.pitch_x_mm, p.pitch_y_mm),
            (self.rows, self.cols),
        )

    def grey(self, coverage: np.ndarray) -> np.ndarray:
        """Coverage to 8-bit grey: exact coverage with anti-aliasing, else cured where over half covered."""
        if self.antialias:
            return np.round(coverage * 255.0).astype(np.uint8)
        return np.where(coverage >= 0.5, 255, 0).astype(np.uint8)

    def layer_grey(self, k: int, scratch: dict | None = None) -> tuple[np.ndarray, int, int]:
        """Layer k as 8-bit grey on the part of the window it touches, and that part's (row, column).

        Releases the GIL, so layers can be made on threads.
        """
        p = self.profile
        ox, oy, r0, r1, c0, c1 = self._layer_window(k)
        bounds = self._bounds
        scratch = {} if scratch is None else scratch
        acc = scratch.get("acc")
        if acc is None or acc.shape != (self.rows, self.cols + 2):
            acc = scratch["acc"] = np.zeros((self.rows, self.cols + 2))
        out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
        _rasterise_layer_grey(
            self._segments,
            bounds[k],
            bounds[k + 1],
            ox + c0 * p.pitch_x_mm,
            oy + r0 * p.pitch_y_mm,
            1.0 / p.pitch_x_mm,
            1.0 / p.pitch_y_mm,
            self.antialias,
            acc,
            out,
        )
        return out, r0, c0

    def _layer_window(self, k: int) -> tuple[float, float, int, int, int, int]:
        """The window's origin (mm) and the rows [r0, r1) and columns [c0, c1) layer k touches."""
        p = self.profile
        ox, oy = self.col0 * p.pitch_x_mm, self.row0 * p.pitch_y_mm
        bounds = self._bounds
        r0, r1, c0, c1 = _layer_box(
            self._segments,
            bounds[k],
            bounds[k + 1],
            ox,
            oy,
            1.0 / p.pitch_x_mm,
            1.0 / p.pitch_y_mm,
            self.rows,
            self.cols,
        )
        return ox, oy, r0, r1, c0, c1

    @property
    def _bounds(self) -> np.ndarray:
        cached = getattr(self, "_bounds_cache", None)
        if cached is None:
            cached = np.searchsorted(self._layer, np.arange(self.n_layers + 1), side="left")
            self._bounds_cache = cached
        return cached

    def max_winding(self) -> float:
        """Largest winding number (pixel-averaged) over all layers: 1 for a solid that does not
        overlap itself, 2 or more where its surface passes through itself (as the printer sees it).
        """
        p = self.profile
        acc = np.zeros((self.rows, self.cols + 2))
        marks = np.zeros((self.rows, mark_blocks(self.cols)), dtype=np.uint8)
        bounds = self._bounds
        worst = 0.0
        for k in range(self.n_layers):
            ox, oy, r0, r1, c0, c1 = self._layer_window(k)
            worst = max(
                worst,
                _max_winding(
                    self._segments,
                    bounds[k],
                    bounds[k + 1],
                    ox + c0 * p.pitch_x_mm,
                    oy + r0 * p.pitch_y_mm,
                    1.0 / p.pitch_x_mm,
                    1.0 / p.pitch_y_mm,
                    acc,
                    marks,
                    r1 - r0,
                    c1 - c0,
                ),
            )
        return worst

    def section_areas_mm2(self) -> np.ndarray:
        """Exact area of each layer's cross-section (mm^2)."""
        return section_areas(self._layer, self._segments, self.n_layers)

    def display_place(
        self, height: int, width: int, row: int = 0, col: int = 0
    ) -> tuple[int, int, bool, bool, bool]:
        """Where a ``height`` x ``width`` block of the window at its (``row``, ``col``) lands on the display.

        Returns ``(display_row, display_col, transposed, reverse_rows, reverse_cols)``: the
        block's top-left on the display, and how the display shows it: transposed (on a
        portrait display), then with its rows and its columns reversed as flagged.
        """
        p = self.profile
        # In the top view T (H_px x W_px, row 0 at the largest Y) the block occupies
        # rows [a0, a0 + height) and columns [b0, b0 + width): T shows the window upside down.
        a0 = p.display_pixels_y - (self.row0 + row) - height
        b0 = self.col0 + col
        display_height, display_width = p.display_pixels_y, p.display_pixels_x
        transposed = p.orientation == "portrait"
        if transposed:
            # rot90(T, 1): T[a, b] -> P[W - 1 - b, a]; P is the window transposed, both axes reversed.
            a0, b0 = display_width - (b0 + width), a0
            display_height, display_width = display_width, display_height
            height, width = width, height
        if p.mirror_x:
            b0 = display_width - (b0 + width)
        if p.mirror_y:
            a0 = display_height - (a0 + height)
        return a0, b0, transposed, not p.mirror_y, transposed != p.mirror_x

    def display_block(self, grey: np.ndarray, row: int = 0, col: int = 0) -> tuple[np.ndarray, int, int]:
        """Grey pixels (at ``row``, ``col`` of the window) as they appear on the display.

        Returns a view (not a copy) and its top-left (row, column) on the display.
        """
        a0, b0, transposed, reverse_rows, reverse_cols = self.display_place(*grey.shape, row, col)
        block = grey.T if transposed else grey
        if reverse_rows:
            block = block[::-1]
        if reverse_cols:
            block = block[:, ::-1]
        return block, a0, b0

    def deflate_display_rows(self, k: int, scratch: dict | None = None) -> tuple[bytes, int, int, int]:
        """Layer k's display rows that hold the part, as PNG scanlines deflated while they are rasterised.

        Returns ``(stream, adler, display_row, n_rows)``: a raw deflate stream of the
        scanlines (filter byte 0, then the display row's pixels) of display rows
        ``[display_row, display_row + n_rows)``, ending on a full flush; and their adler-32
        (started from 1). See :mod:`slicing.deflate`. The pixels are :meth:`layer_grey`'s as
        :meth:`display_block` places them, except that a portrait display's window is
        rasterised with x and y swapped (in the display's orientation), which can round
        the other way a pixel whose coverage lies within rounding error of half a grey level.
        Releases the GIL, so layers can be made on threads.
        """
        p = self.profile
        ox, oy, r0, r1, c0, c1 = self._layer_window(k)
        placed = self.display_place(r1 - r0, c1 - c0, r0, c0)
        display_row, lead, transposed, reverse_rows, reverse_cols = placed
        row_bytes = self.display_shape()[1] + 1
        x0, y0 = ox + c0 * p.pitch_x_mm, oy + r0 * p.pitch_y_mm
        if transposed:
            seg = self._swapped_segments
            window = (y0, x0, 1.0 / p.pitch_y_mm, 1.0 / p.pitch_x_mm, c1 - c0, r1 - r0)
            whole_shape = (self.cols, self.rows + 2)
        else:
            seg = self._segments
            window = (x0, y0, 1.0 / p.pitch_x_mm, 1.0 / p.pitch_y_mm, r1 - r0, c1 - c0)
            whole_shape = (self.rows, self.cols + 2)
        n_rows, n_cols = window[4], window[5]
        if n_rows == 0 or n_cols == 0:
            return b"", 1, 0, 0
        scratch = {} if scratch is None else scratch
        whole = scratch.get("acc_display")
        if whole is None or whole.shape != whole_shape:
            whole = scratch["acc_display"] = np.zeros(whole_shape)
            scratch["marks_display"] = np.zeros((whole_shape[0], mark_blocks(whole_shape[1])), dtype=np.uint8)
        bound = deflate_bound(n_rows, row_bytes)
        out = scratch.get("deflate")
        if out is None or out.size < bound:
            out = scratch["deflate"] = np.empty(bound, dtype=np.uint8)
            scratch["items"] = np.empty(n_rows * row_bytes, dtype=np.int16)
        bounds = self._bounds
        n_bytes, adler = _deflate_layer(
            seg,
            bounds[k],
            bounds[k + 1],
            *window[:4],
            self.antialias,
            whole,
            scratch["marks_display"],
            n_rows,
            n_cols,
            reverse_rows,
            reverse_cols,
            lead,
            row_bytes,
            scratch["items"],
            out,
        )
        return out[:n_bytes].tobytes(), adler, display_row, n_rows

    @property
    def _swapped_segments(self) -> np.ndarray:
        """The sections' segments with x and y swapped (for rasterising in a portrait display's rows)."""
        cached = getattr(self, "_swapped_cache", None)
        if cached is None:
            cached = np.ascontiguousarray(self._segments[:, [1, 0, 3, 2]])
            self._swapped_cache = cached
        return cached

    def display_shape(self) -> tuple[int, int]:
        p = self.profile
        if p.orientation == "portrait":
            return p.display_pixels_x, p.display_pixels_y
        return p.display_pixels_y, p.display_pixels_x

    def display_image(self, grey_window: np.ndarray) -> np.ndarray:
        """The whole display's image for one layer, oriented and mirrored like PrusaSlicer's."""
        block, r0, c0 = self.display_block(grey_window)
        image = np.zeros(self.display_shape(), dtype=np.uint8)
        image[r0 : r0 + block.shape[0], c0 : c0 + block.shape[1]] = block
        return image


def slice_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    profile: PrinterProfile,
    *,
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
) -> Slices:
    """Slice a closed, outward-oriented mesh (mm) for ``profile``, PrusaSlicer's way.

    Raises
    ------
    ValueError
        If the mesh is empty, or larger than the display or the printable height (the
        message says by how much), or the layer height is outside the profile's range.
    """
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    if verts.size == 0 or tris.size == 0:
        raise ValueError("model: expected a mesh with triangles, found none")
    lh = _check_layer_height(profile, layer_height_mm)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    shift = _placement(lo, hi, profile)
    heights = slice_heights(float(hi[2] - lo[2]), lh, profile.initial_layer_height_mm)
    layer, segments = section_segments(verts + shift, tris, heights)
    return _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments)


def slice_heightfield(
    field: HeightField,
    base_thickness_mm: float,
    profile: PrinterProfile,
    *,
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
) -> Slices:
    """Slice a relief tile straight from its height field, without building a mesh.

    The solid is the closed slab that :func:`printapp.mesh.slab_from_heightfield` would
    build (top triangulated along each cell's v00-v11 diagonal, vertical walls, floor at
    z = 0); its sections are computed triangle by triangle from the grid, so the layers
    are the same as slicing that mesh, at a fraction of the memory for large maps.
    The field's origin places it in x and y.
    """
    h = np.ascontiguousarray(field.heights_mm, dtype=np.float64)
    pitch_x_mm, pitch_y_mm = field.pitch_x_mm, field.pitch_y_mm
    origin_mm = (field.origin_x_mm, field.origin_y_mm)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise ValueError("heights: expected a finite 2-D array of at least 2 x 2 samples")
    if not (pitch_x_mm > 0 and pitch_y_mm > 0 and base_thickness_mm > 0):
        raise ValueError("pitch, base thickness: expected positive values")
    if float(h.min()) + base_thickness_mm <= 0:
        raise ValueError("heights: the tile's top must stay above z = 0")
    lh = _check_layer_height(profile, layer_height_mm)
    ny, nx = h.shape
    lo = np.array([origin_mm[0], origin_mm[1], 0.0])
    hi = np.array(
        [
            origin_mm[0] + (nx - 1) * pitch_x_mm,
            origin_mm[1] + (ny - 1) * pitch_y_mm,
            base_thickness_mm + h.max(),
        ]
    )
    shift = _placement(lo, hi, profile)
    heights = slice_heights(float(hi[2]), lh, profile.initial_layer_height_mm)
    layer, segments = heightfield_segments(
        h, pitch_x_mm, pitch_y_mm, base_thickness_mm, origin_mm[0], origin_mm[1], shift, heights
    )
    return _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments)


def _check_layer_height(profile: PrinterProfile, layer_height_mm: float | None) -> float:
    lh = profile.layer_height_mm if layer_height_mm is None else float(layer_height_mm)
    if not profile.min_layer_height_mm - 1e-12 <= lh <= profile.max_layer_height_mm + 1e-12:
        raise ValueError(
            f"layer height: {lh:g} mm is outside what {profile.label} can print "
            f"([{profile.min_layer_height_mm:g}, {profile.max_layer_height_mm:g}] mm)"
        )
    return lh


def _placement(lo: np.ndarray, hi: np.ndarray, profile: PrinterProfile) -> np.ndarray:
    """The shift that drops the part to z = 0 and centres it on the display; refuses parts too large."""
    size = hi - lo
    w, d = profile.display_width_mm, profile.display_height_mm
    if size[0] > w or size[1] > d or size[2] > profile.max_print_height_mm:
        over = [
            f"{axis} by {s - limit:.2f} mm"
            for axis, s, limit in (
                ("x", size[0], w),
                ("y", size[1], d),
                ("z", size[2], profile.max_print_height_mm),
            )
            if s > limit
        ]
        raise ValueError(
            f"model: {size[0]:.2f} x {size[1]:.2f} x {size[2]:.2f} mm does not fit the {profile.label} "
            f"({w:g} x {d:g} x {profile.max_print_height_mm:g} mm): too large in {', '.join(over)}"
        )
    return -np.array([(lo[0] + hi[0]) / 2 - w / 2, (lo[1] + hi[1]) / 2 - d / 2, lo[2]])


def _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments) -> Slices:
    px, py = profile.pitch_x_mm, profile.pitch_y_mm
    placed_lo, placed_hi = lo + shift, hi + shift
    col0 = max(int(math.floor(placed_lo[0] / px)) - 1, 0)
    col1 = min(int(math.ceil(placed_hi[0] / px)) + 1, profile.display_pixels_x)
    row0 = max(int(math.floor(placed_lo[1] / py)) - 1, 0)
    row1 = min(int(math.ceil(placed_hi[1] / py)) + 1, profile.display_pixels_y)
    return Slices(
        profile=profile,
        heights_mm=heights,
        layer_height_mm=lh,
        shift_mm=shift,
        col0=col0,
        row0=row0,
        cols=col1 - col0,
        rows=row1 - row0,
        antialias=profile.antialiasing if antialias is None else antialias,
        _layer=layer,
        _segments=segments,
    )
