"""Closed meshes to layer images: sections at the slice heights, rasterised with exact area coverage.

Each layer is the cross-section of the mesh at its slice height. Every triangle that
straddles a slice plane contributes one directed segment, oriented so that the solid is
on its left (the direction is the triangle's outward normal turned by +90 degrees in the
plane). The segments are rasterised with the signed-area accumulation scheme of font
rasterisers (as in font-rs and FreeType's "cell" rasteriser): each segment adds the area
it sweeps to the cells it crosses, and a prefix sum along each row turns that into the
exact fraction of each pixel covered by the polygon (nonzero rule, so holes, with their
opposite orientation, come out empty). That is the "area coverage" PrusaSlicer writes as
grey levels when its gamma correction is 1.

Vertices lying exactly on a slice plane count as above it (a symbolic perturbation), so
every section is a set of closed loops.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


def layer_count(height_mm: float, layer_height_mm: float, initial_layer_height_mm: float) -> int:
    """How many of PrusaSlicer's slice planes cut a part ``height_mm`` tall standing on z = 0.

    Layer 0 is sliced at ``ilh / 2``, layer ``i >= 1`` at ``ilh + (i - 1/2) lh``; a layer
    exists when its plane lies below the top, so there are ``ceil((height - ilh) / lh +
    1/2)`` layers above the first. (Counting ``1 + ceil((height - ilh) / lh)`` instead
    adds an empty layer whenever the top lies in the lower half of a layer, as a float32
    top of 1.70000005 mm does; PrusaSlicer 2.5 slices that model into 34 layers.) A top
    within a millionth of a layer of a plane counts as on it. Returns 0 for a part below
    the first plane.
    """
    if not (height_mm > 0 and layer_height_mm > 0 and initial_layer_height_mm > 0):
        raise ValueError("height, layer heights: expected positive values")
    if height_mm <= initial_layer_height_mm / 2.0:
        return 0
    above = max(0, math.ceil((height_mm - initial_layer_height_mm) / layer_height_mm + 0.5 - 1e-6) - 1)
    return 1 + above


def slice_heights(height_mm: float, layer_height_mm: float, initial_layer_height_mm: float) -> np.ndarray:
    """PrusaSlicer's slice heights for a part ``height_mm`` tall standing on z = 0 (see :func:`layer_count`).

    Raises
    ------
    ValueError
        If the part lies wholly below the first slice plane (``ilh / 2``): no layer would cut it.
    """
    n = layer_count(height_mm, layer_height_mm, initial_layer_height_mm)
    if n == 0:
        raise ValueError(
            f"the part is {height_mm:g} mm tall, below the first slice plane at "
            f"{initial_layer_height_mm / 2:g} mm; expected a part at least half a layer tall"
        )
    k = np.arange(n, dtype=np.float64)
    z = initial_layer_height_mm + (k - 0.5) * layer_height_mm
    z[0] = initial_layer_height_mm / 2.0
    return z


@njit(cache=True)
def _first_at_least(sorted_values: np.ndarray, value: float) -> np.int64:
    """``np.searchsorted(sorted_values, value, side="left")``, NaN sorting last as there.

    By hand: numba's ``np.searchsorted`` compiles its generic comparison (complex numbers
    included), about a second of the warm-up for every kernel that slices."""
    lo = np.int64(0)
    hi = np.int64(sorted_values.shape[0])
    nan = value != value
    while lo < hi:
        mid = (lo + hi) >> 1
        v = sorted_values[mid]
        if v < value or (nan and v == v):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def _count_segments(tri_z_min, tri_z_max, heights) -> np.ndarray:
    counts = np.zeros(tri_z_min.shape[0] + 1, dtype=np.int64)
    for t in range(tri_z_min.shape[0]):
        # planes with z_min <= z < z_max: the triangle has vertices on both sides
        lo = _first_at_least(heights, tri_z_min[t])
        hi = _first_at_least(heights, tri_z_max[t])
        counts[t + 1] = max(hi - lo, 0)
    for t in range(tri_z_min.shape[0]):
        counts[t + 1] += counts[t]
    return counts


@njit(cache=True, parallel=True)
def _segments(V, F, N, heights, tri_z_min, tri_z_max, offsets, layer, seg) -> None:
    for t in prange(F.shape[0]):
        lo = _first_at_least(heights, tri_z_min[t])
        hi = _first_at_least(heights, tri_z_max[t])
        out = offsets[t]
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        for k in range(lo, hi):
            z = heights[k]
            # Collect the two points where the triangle's edges cross the plane.
            px = np.empty(2)
            py = np.empty(2)
            n = 0
            for i0, i1 in ((a, b), (b, c), (c, a)):
                z0, z1 = V[i0, 2], V[i1, 2]
                above0 = z0 >= z
                above1 = z1 >= z
                if above0 != above1 and n < 2:
                    s = (z - z0) / (z1 - z0)
                    px[n] = V[i0, 0] + s * (V[i1, 0] - V[i0, 0])
                    py[n] = V[i0, 1] + s * (V[i1, 1] - V[i0, 1])
                    n += 1
            layer[out] = k
            if n < 2:
                seg[out, 0] = seg[out, 1] = seg[out, 2] = seg[out, 3] = 0.0
            else:
                # Solid on the left: the direction is the outward normal turned by +90 degrees.
                tx, ty = -N[t, 1], N[t, 0]
                if (px[1] - px[0]) * tx + (py[1] - py[0]) * ty >= 0:
                    seg[out, 0], seg[out, 1], seg[out, 2], seg[out, 3] = px[0], py[0], px[1], py[1]
                else:
                    seg[out, 0], seg[out, 1], seg[out, 2], seg[out, 3] = px[1], py[1], px[0], py[0]
            out += 1


@njit(cache=True, inline="always")
def _straddle(z0: float, z1: float, z2: float, heights):
    """Slice planes [lo, hi) that a triangle with these vertex heights straddles."""
    zmin = min(z0, min(z1, z2))
    zmax = max(z0, max(z1, z2))
    return _first_at_least(heights, zmin), _first_at_least(heights, zmax)


@njit(cache=True, inline="always")
def _emit(tri, heights, lo, hi, layer, seg, out) -> np.int64:
    """Write the sections of one triangle (3 x 3 vertex array) at planes lo..hi-1 from index ``out``."""
    nx_ = (tri[1, 1] - tri[0, 1]) * (tri[2, 2] - tri[0, 2]) - (tri[1, 2] - tri[0, 2]) * (
        tri[2, 1] - tri[0, 1]
    )
    ny_ = (tri[1, 2] - tri[0, 2]) * (tri[2, 0] - tri[0, 0]) - (tri[1, 0] - tri[0, 0]) * (
        tri[2, 2] - tri[0, 2]
    )
    for k in range(lo, hi):
        z = heights[k]
        px0 = py0 = px1 = py1 = 0.0
        n = 0
        for i0, i1 in ((0, 1), (1, 2), (2, 0)):
            z0, z1 = tri[i0, 2], tri[i1, 2]
            if (z0 >= z) != (z1 >= z) and n < 2:
                s = (z - z0) / (z1 - z0)
                x = tri[i0, 0] + s * (tri[i1, 0] - tri[i0, 0])
                y = tri[i0, 1] + s * (tri[i1, 1] - tri[i0, 1])
                if n == 0:
                    px0, py0 = x, y
                else:
                    px1, py1 = x, y
                n += 1
        layer[out] = k
        if (px1 - px0) * -ny_ + (py1 - py0) * nx_ >= 0:
            seg[out, 0], seg[out, 1], seg[out, 2], seg[out, 3] = px0, py0, px1, py1
        else:
            seg[out, 0], seg[out, 1], seg[out, 2], seg[out, 3] = px1, py1, px0, py0
        out += 1
    return out


@njit(cache=True, inline="always")
def _ring_vertex(idx: int, nx: int, ny: int) -> tuple[int, int]:
    """(row, column) of border vertex ``idx``, counter-clockwise from (0, 0), as the slab's walls use."""
    if idx < nx:
        return 0, idx
    if idx < nx + ny - 1:
        return idx - nx + 1, nx - 1
    if idx < 2 * nx + ny - 2:
        return ny - 1, nx - 1 - (idx - (nx + ny - 2))
    return ny - 1 - (idx - (2 * nx + ny - 3)), 0


@njit(cache=True)
def _heightfield_triangles(h, dx, dy, base, ox, oy, shift, heights, layer, seg, count_only: bool) -> np.int64:
    """Visit the slab's triangles (top, then walls) straight from the grid; count or emit their sections."""
    ny, nx = h.shape
    tri = np.empty((3, 3))
    out = 0

    def vertex(i, r, c, z):
        tri[i, 0] = (ox + c * dx) + shift[0]
        tri[i, 1] = (oy + r * dy) + shift[1]
        tri[i, 2] = z + shift[2]

    for r in range(ny - 1):
        for c in range(nx - 1):
            for upper in range(2):
                if upper == 0:  # v00, v10, v11
                    vertex(0, r, c, base + h[r, c])
                    vertex(1, r, c + 1, base + h[r, c + 1])
                    vertex(2, r + 1, c + 1, base + h[r + 1, c + 1])
                else:  # v00, v11, v01
                    vertex(0, r, c, base + h[r, c])
                    vertex(1, r + 1, c + 1, base + h[r + 1, c + 1])
                    vertex(2, r + 1, c, base + h[r + 1, c])
                lo, hi = _straddle(tri[0, 2], tri[1, 2], tri[2, 2], heights)
                if count_only:
                    out += max(hi - lo, 0)
                else:
                    out = _emit(tri, heights, lo, hi, layer, seg, out)
    # Walls along the border, counter-clockwise seen from above: (a_low, b_low, b), (a_low, b, a).
    n_ring = 2 * (nx - 1) + 2 * (ny - 1)
    for k in range(n_ring):
        ar, ac = _ring_vertex(k, nx, ny)
        br, bc = _ring_vertex((k + 1) % n_ring, nx, ny)
        for part in range(2):
            if part == 0:
                vertex(0, ar, ac, 0.0)
                vertex(1, br, bc, 0.0)
                vertex(2, br, bc, base + h[br, bc])
            else:
                vertex(0, ar, ac, 0.0)
                vertex(1, br, bc, base + h[br, bc])
                vertex(2, ar, ac, base + h[ar, ac])
            lo, hi = _straddle(tri[0, 2], tri[1, 2], tri[2, 2], heights)
            if count_only:
                out += max(hi - lo, 0)
            else:
                out = _emit(tri, heights, lo, hi, layer, seg, out)
    return out


def heightfield_segments(
    heights_mm: np.ndarray,
    pitch_x_mm: float,
    pitch_y_mm: float,
    base_thickness_mm: float,
    origin_x_mm: float,
    origin_y_mm: float,
    shift_mm: np.ndarray,
    slice_z: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Directed section segments of a height-field slab (see :func:`section_segments`), without a mesh."""
    h = np.ascontiguousarray(heights_mm, dtype=np.float64)
    z = np.ascontiguousarray(slice_z, dtype=np.float64)
    shift = np.ascontiguousarray(shift_mm, dtype=np.float64)
    dummy_layer = np.empty(0, dtype=np.int64)
    dummy_seg = np.empty((0, 4))
    args = (
        h,
        float(pitch_x_mm),
        float(pitch_y_mm),
        float(base_thickness_mm),
        float(origin_x_mm),
        float(origin_y_mm),
        shift,
        z,
    )
    count = _heightfield_triangles(*args, dummy_layer, dummy_seg, True)
    layer = np.empty(count, dtype=np.int64)
    seg = np.empty((count, 4))
    _heightfield_triangles(*args, layer, seg, False)
    order = np.argsort(layer, kind="stable")
    return layer[order], seg[order]


def section_segments(
    vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Directed cross-section segments of a closed, outward-oriented mesh at each height.

    Returns
    -------
    layer : (s,) int64 array
        The index into ``heights`` of each segment, sorted ascending.
    segments : (s, 4) float64 array
        (x0, y0, x1, y1), with the solid on the segment's left.
    """
    verts = np.ascontiguousarray(vertices, dtype=np.float64)
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    z = verts[:, 2][tris]
    zmin, zmax = z.min(axis=1), z.max(axis=1)
    normals = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    offsets = _count_segments(zmin, zmax, np.ascontiguousarray(heights, dtype=np.float64))
    layer = np.empty(offsets[-1], dtype=np.int64)
    seg = np.empty((offsets[-1], 4))
    _segments(
        verts, tris, normals, np.ascontiguousarray(heights, dtype=np.float64), zmin, zmax, offsets, layer, seg
    )
    order = np.argsort(layer, kind="stable")
    return layer[order], seg[order]


BLOCK_SHIFT = 6
"""Cells per block of :func:`_accumulate_line`'s marks: 2 ** 6 = 64."""


@njit(cache=True, nogil=True)
def _accumulate_line(acc, x0: float, y0: float, x1: float, y1: float, marks) -> None:
    """Add the signed area a directed segment sweeps to the cells it crosses (font-rs style).

    ``acc`` is (rows, cols + 2); coordinates are in pixels, with pixel (r, c) covering
    [c, c + 1) x [r, r + 1). A segment going up (increasing row) adds +area. Unless
    ``marks`` is empty, ``marks[r, c >> BLOCK_SHIFT]`` is set for every cell written, so
    that a scan may skip the blocks of a row that nothing touched.
    """
    if y0 == y1:
        return
    direction = 1.0
    if y0 > y1:
        direction = -1.0
        x0, y0, x1, y1 = x1, y1, x0, y0
    rows = acc.shape[0]
    cols = acc.shape[1] - 2
    marking = marks.shape[0] > 0
    dxdy = (x1 - x0) / (y1 - y0)
    x = x0
    if y0 < 0.0:
        x -= y0 * dxdy
    y_start = max(y0, 0.0)
    y_end = min(y1, float(rows))
    row = int(math.floor(y_start))
    while row < rows and row + 1 > y_start and float(row) < y_end:
        dy = min(float(row + 1), y_end) - max(float(row), y_start)
        if dy <= 0:
            row += 1
            continue
        xnext = x + dxdy * dy
        d = dy * direction
        xa, xb = (x, xnext) if x < xnext else (xnext, x)
        # Clamp to the raster; area left of column 0 accumulates into column 0.
        xa_c = min(max(xa, 0.0), float(cols))
        xb_c = min(max(xb, 0.0), float(cols))
        x0i = int(math.floor(xa_c))
        x0f = xa_c - x0i
        x1i = int(math.ceil(xb_c))
        if marking:
            for block in range(x0i >> BLOCK_SHIFT, (max(x1i, x0i + 1) >> BLOCK_SHIFT) + 1):
                marks[row, block] = 1
        if x1i <= x0i + 1:
            xmf = 0.5 * (xa_c + xb_c) - x0i
            acc[row, x0i] += d - d * xmf
            acc[row, x0i + 1] += d * xmf
        else:
            s = 1.0 / (xb_c - xa_c)
            x0f2 = 1.0 - x0f
            a0 = 0.5 * s * x0f2 * x0f2
            x1f = xb_c - x1i + 1.0
            am = 0.5 * s * x1f * x1f
            acc[row, x0i] += d * a0
            if x1i == x0i + 2:
                acc[row, x0i + 1] += d * (1.0 - a0 - am)
            else:
                a1 = s * (1.5 - x0f)
                acc[row, x0i + 1] += d * (a1 - a0)
                for xi in range(x0i + 2, x1i - 1):
                    acc[row, xi] += d * s
                a2 = a1 + (x1i - x0i - 3) * s
                acc[row, x1i - 1] += d * (1.0 - a2 - am)
            acc[row, x1i] += d * am
        x = xnext
        row += 1


@njit(cache=True, nogil=True)
def _add_segments(
    seg, start, end, ox: float, oy: float, inv_pitch_x: float, inv_pitch_y: float, acc, marks
) -> None:
    """Accumulate segments start..end-1, mapped from mm to the pixels of a window at (ox, oy);
    ``marks`` as :func:`_accumulate_line` (empty: none kept)."""
    for s in range(start, end):
        _accumulate_line(
            acc,
            (seg[s, 0] - ox) * inv_pitch_x,
            (seg[s, 1] - oy) * inv_pitch_y,
            (seg[s, 2] - ox) * inv_pitch_x,
            (seg[s, 3] - oy) * inv_pitch_y,
            marks,
        )


@njit(cache=True, nogil=True)
def _no_marks():
    return np.zeros((0, 0), dtype=np.uint8)


@njit(cache=True, nogil=True)
def mark_blocks(cols: int) -> int:
    """Blocks of marks a row of ``cols`` pixels needs (its accumulator is two cells wider)."""
    return ((cols + 1) >> BLOCK_SHIFT) + 1


@njit(cache=True, nogil=True)
def _accumulate_layer(
    seg, start, end, ox: float, oy: float, inv_pitch_x: float, inv_pitch_y: float, acc
) -> None:
    acc[:, :] = 0.0
    _add_segments(seg, start, end, ox, oy, inv_pitch_x, inv_pitch_y, acc, _no_marks())


@njit(cache=True, nogil=True)
def _rasterise_layer(
    seg, start, end, ox: float, oy: float, inv_pitch_x: float, inv_pitch_y: float, acc, out
) -> None:
    _accumulate_layer(seg, start, end, ox, oy, inv_pitch_x, inv_pitch_y, acc)
    rows, cols = out.shape
    for r in range(rows):
        total = 0.0
        for c in range(cols):
            total += acc[r, c]
            out[r, c] = min(abs(total), 1.0)


@njit(cache=True, nogil=True)
def _layer_box(
    seg, start, end, ox: float, oy: float, inv_pitch_x: float, inv_pitch_y: float, rows: int, cols: int
):
    """Pixel rows [r0, r1) and columns [c0, c1) of the window that a layer's segments touch."""
    if end <= start:
        return 0, 0, 0, 0
    xmin = ymin = np.inf
    xmax = ymax = -np.inf
    for s in range(start, end):
        for j in (0, 2):
            x = (seg[s, j] - ox) * inv_pitch_x
            y = (seg[s, j + 1] - oy) * inv_pitch_y
            xmin, xmax = min(xmin, x), max(xmax, x)
            ymin, ymax = min(ymin, y), max(ymax, y)
    c0 = max(int(math.floor(xmin)) - 1, 0)
    r0 = max(int(math.floor(ymin)) - 1, 0)
    c1 = min(int(math.ceil(xmax)) + 1, cols)
    r1 = min(int(math.ceil(ymax)) + 1, rows)
    return r0, max(r1, r0), c0, max(c1, c0)


@njit(cache=True, nogil=True)
def _grey_level(winding: float, antialias: bool) -> int:
    """A pixel's grey from its signed, pixel-averaged winding: round(255 coverage), or 255 from half on."""
    coverage = min(abs(winding), 1.0)
    if antialias:
        return int(math.floor(coverage * 255.0 + 0.5))
    return 255 if coverage >= 0.5 else 0


@njit(cache=True, nogil=True)
def _rasterise_layer_grey(
    seg, start, end, ox: float, oy: float, inv_pitch_x: float, inv_pitch_y: float, antialias: bool, whole, out
) -> None:
    """Straight to 8-bit grey: round(255 coverage), or 255 where coverage >= 1/2.

    The accumulator is the ``out``-sized corner of ``whole`` (two columns wider), which must
    be zero on entry and is left zero (cleared while it is summed), saving a pass over it per
    layer. The corner is cut here rather than by the caller: a view cut in Python is typed
    C-contiguous or not by where the layer falls, and each typing is a compilation.
    """
    rows, cols = out.shape
    acc = whole[:rows, : cols + 2]
    _add_segments(seg, start, end, ox, oy, inv_pitch_x, inv_pitch_y, acc, _no_marks())
    for r in range(rows):
        total = 0.0
        grey = np.uint8(0)
        for c in range(cols):
            step = acc[r, c]
            # Most pixels lie inside or outside the section, where nothing was added:
            # they repeat the last grey without a write to acc or a rounding.
            if step != 0.0:
                total += step
                acc[r, c] = 0.0
                grey = np.uint8(_grey_level(total, antialias))
            out[r, c] = grey
        acc[r, cols] = 0.0
        acc[r, cols + 1] = 0.0


@njit(cache=True, nogil=True)
def _max_winding(
    seg,
    start,
    end,
    ox: float,
    oy: float,
    inv_pitch_x: float,
    inv_pitch_y: float,
    whole,
    whole_marks,
    rows: int,
    cols: int,
) -> float:
    """Largest |winding number| (averaged over a pixel) of a layer's section over the ``rows``
    x ``cols`` corner of ``whole`` (the accumulator, two columns wider; left zero), with
    ``whole_marks`` its blocks' marks (:func:`_accumulate_line`; zero on entry, left zero).
    The corners are cut here for the reason :func:`_rasterise_layer_grey` gives.

    A closed, consistently oriented solid that does not overlap itself winds once around
    every point inside it: more than one means the surface passes through itself there.
    """
    acc = whole[:rows, : cols + 2]
    marks = whole_marks[:rows, : mark_blocks(cols)]
    _add_segments(seg, start, end, ox, oy, inv_pitch_x, inv_pitch_y, acc, marks)
    worst = 0.0
    for r in range(rows):
        total = 0.0
        # The winding changes only where a segment added something: only the blocks it
        # marked are read, and in them only the cells it wrote to are cleared and summed.
        for block in range(marks.shape[1]):
            if marks[r, block] == 0:
                continue
            marks[r, block] = 0
            for c in range(block << BLOCK_SHIFT, min((block + 1) << BLOCK_SHIFT, cols)):
                step = acc[r, c]
                if step != 0.0:
                    total += step
                    acc[r, c] = 0.0
                    worst = max(worst, abs(total))
        acc[r, cols] = 0.0
        acc[r, cols + 1] = 0.0
    return worst


@njit(cache=True)
def _section_areas(layer, seg, n_layers) -> np.ndarray:
    """Exact cross-section area of each layer (shoelace over its directed segments)."""
    areas = np.zeros(n_layers)
    for s in range(layer.shape[0]):
        areas[layer[s]] += 0.5 * (seg[s, 0] * seg[s, 3] - seg[s, 2] * seg[s, 1])
    return areas


def section_areas(layer: np.ndarray, segments: np.ndarray, n_layers: int) -> np.ndarray:
    """Exact area (in the segments' units squared) of each layer's cross-section."""
    return _section_areas(layer, segments, n_layers)


def rasterise_sections(
    layer: np.ndarray,
    segments: np.ndarray,
    n_layers: int,
    origin_mm: tuple[float, float],
    pitch_mm: tuple[float, float],
    shape: tuple[int, int],
):
    """Yield (k, coverage) for each layer k: the (rows, cols) fraction of each pixel inside the solid.

    Row r, column c is the pixel [x0 + c px, x0 + (c + 1) px) x [y0 + r py, y0 + (r + 1) py),
    i.e. row 0 at the smallest y (a top view with y up is ``coverage[::-1]``).
    """
    rows, cols = shape
    acc = np.zeros((rows, cols + 2))
    out = np.zeros((rows, cols))
    bounds = np.searchsorted(layer, np.arange(n_layers + 1), side="left")
    for k in range(n_layers):
        _rasterise_layer(
            segments,
            bounds[k],
            bounds[k + 1],
            origin_mm[0],
            origin_mm[1],
            1.0 / pitch_mm[0],
            1.0 / pitch_mm[1],
            acc,
            out,
        )
        yield k, out
