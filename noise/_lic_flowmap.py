"""The flow-map LIC kernels (private; :func:`noise.lic.lic2d` with ``method="flowmap"`` runs them).

Each pixel's RK step forward and backward is integrated once into a float32 step map;
every pixel then traces its own streamline by bilinear blends of the map. See
:mod:`noise.lic` for the method and its accuracy.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# ---- flow map -------------------------------------------------------------------------
# Everything below runs in float32: the map is float32, and positions in pixels keep
# about 1e-4 px of rounding per step on a 2048-pixel image.

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
_FHALF = np.float32(0.5)
_U1 = np.uint64(1)
_U2 = np.uint64(2)
_U3 = np.uint64(3)


@njit(cache=True)
def _cell(x, y, row: np.uint64):
    """Cell index (row-major, ``row`` cells per row) and bilinear fractions of a point in
    padded coordinates (non-negative, so truncation is the floor)."""
    i0 = np.uint32(x)
    j0 = np.uint32(y)
    return np.uint64(j0) * row + np.uint64(i0), x - np.float32(i0), y - np.float32(j0)


@njit(cache=True, fastmath={"contract"})
def _blend2(a, c: np.uint64, row: np.uint64, fx, fy):
    """Bilinear blend of a two-channel, cell-interleaved flat array around cell ``c``."""
    c2 = c + c
    b2 = c2 + row + row
    top = a[c2] + fx * (a[c2 + _U2] - a[c2])
    first = top + fy * (a[b2] + fx * (a[b2 + _U2] - a[b2]) - top)
    top = a[c2 + _U1] + fx * (a[c2 + _U3] - a[c2 + _U1])
    second = top + fy * (a[b2 + _U1] + fx * (a[b2 + _U3] - a[b2 + _U1]) - top)
    return first, second


@njit(cache=True)
def _unit_padded(field, row: np.uint64, x, y, nx: int, ny: int):
    """``_field`` on an edge-padded, interleaved float32 copy of (u, v), flattened.

    ``field`` holds (ny + 2) rows of ``row`` = nx + 2 cells of (u, v), pixel (i, j) at
    cell (j + 1) * row + i + 1; the border rows and columns repeat the edge, which is
    the clamping of ``_bilinear``.
    """
    if not (x >= -_FHALF and x <= nx - _FHALF and y >= -_FHALF and y <= ny - _FHALF):
        return _F0, _F0, False
    c, fx, fy = _cell(x + _F1, y + _F1, row)
    du, dv = _blend2(field, c, row, fx, fy)
    norm = np.sqrt(du * du + dv * dv)
    if not norm > np.float32(1e-12):  # also catches NaN
        return _F0, _F0, False
    inverse = _F1 / norm
    return du * inverse, dv * inverse, True


@njit(cache=True, parallel=True)
def _scan_inputs(u, v, texture, rows) -> None:
    """Per row j: rows[j] = (largest finite |field component|, texture sum, 1 if the
    texture row is all finite else 0), in one parallel pass over the inputs."""
    for j in prange(u.shape[0]):
        largest = 0.0
        total = 0.0
        finite = 1.0
        for i in range(u.shape[1]):
            a = abs(u[j, i])
            b = abs(v[j, i])
            if a > largest and math.isfinite(a):
                largest = a
            if b > largest and math.isfinite(b):
                largest = b
            t = texture[j, i]
            if not math.isfinite(t):
                finite = 0.0
            total += t
        rows[j, 0] = largest
        rows[j, 1] = total
        rows[j, 2] = finite


@njit(cache=True, parallel=True)
def _pad_inputs(u, v, scale: float, texture, mean: float, field, padded_texture) -> None:
    """Edge-padded float32 copies: scale * (u, v) interleaved (Inf becomes NaN), texture less ``mean``."""
    ny, nx = u.shape
    for j in prange(ny + 2):
        jj = min(max(j - 1, 0), ny - 1)
        for i in range(nx + 2):
            ii = min(max(i - 1, 0), nx - 1)
            a = u[jj, ii] * scale
            b = v[jj, ii] * scale
            field[j, i, 0] = a if math.isfinite(a) else np.nan
            field[j, i, 1] = b if math.isfinite(b) else np.nan
            padded_texture[j, i] = texture[jj, ii] - mean


@njit(cache=True, parallel=True)
def _build_step_maps(field, h: float, rk4: bool, maps) -> None:
    """Fill ``maps`` (2, ny + 2, nx + 2, 2) float32 with the step (dx, dy) of signed
    length +h ([0]) and -h ([1]) from every pixel centre (padded indexing).

    A step is NaN where it cannot be taken (an evaluation point or its end point
    outside the image, or a zero or NaN field there) and in the border cells, so a
    streamline stops as soon as any of the four cells around it cannot step. Because
    a valid step ends inside the image, a bilinear blend of four valid steps ends
    inside it too (the convex combination of their end points), so the trace needs no
    bounds checks. The two directions share the first Runge-Kutta stage, and each
    stage runs over a whole row before the next, so that the evaluations of different
    pixels (independent) overlap instead of waiting on each other.
    """
    ny = maps.shape[1] - 2
    nx = maps.shape[2] - 2
    row = np.uint64(nx + 2)
    nan = np.float32(np.nan)
    hh = np.float32(h)
    half = np.float32(0.5 * h)
    sixth = np.float32(h / 6.0)
    two = np.float32(2.0)
    for j in prange(ny + 2):
        for d in range(2):
            maps[d, j, 0, 0] = nan
            maps[d, j, 0, 1] = nan
            maps[d, j, nx + 1, 0] = nan
            maps[d, j, nx + 1, 1] = nan
        if j == 0 or j > ny:
            for i in range(1, nx + 1):
                for d in range(2):
                    maps[d, j, i, 0] = nan
                    maps[d, j, i, 1] = nan
            continue
        y = np.float32(j - 1)
        # stage[s, q, i]: direction (x, y) of stage s of the forward (q = 0, 1) and
        # backward (q = 2, 3) step from pixel i; ok[s, d, i]: whether it exists.
        stage = np.empty((4, 4, nx), dtype=np.float32)
        ok = np.empty((4, 2, nx), dtype=np.bool_)
        for i in range(nx):
            kx, ky, good = _unit_padded(field, row, np.float32(i), y, nx, ny)
            stage[0, 0, i] = kx
            stage[0, 1, i] = ky
            ok[0, 0, i] = good
            ok[0, 1, i] = good
        n_stages = 4 if rk4 else 2
        for s in range(1, n_stages):
            reach = hh if s == 3 else half
            for i in range(nx):
                x = np.float32(i)
                for d in range(2):
                    signed = reach if d == 0 else -reach
                    q = 0 if s == 1 else 2 * d  # stage 1 starts from the shared first stage
                    at_x = x + signed * stage[s - 1, q, i]
                    at_y = y + signed * stage[s - 1, q + 1, i]
                    kx, ky, good = _unit_padded(field, row, at_x, at_y, nx, ny)
                    stage[s, 2 * d, i] = kx
                    stage[s, 2 * d + 1, i] = ky
                    ok[s, d, i] = good and ok[s - 1, d, i]
        for i in range(nx):
            x = np.float32(i)
            for d in range(2):
                qx = 2 * d
                qy = qx + 1
                if rk4:
                    signed = sixth if d == 0 else -sixth
                    dx = stage[0, 0, i] + two * (stage[1, qx, i] + stage[2, qx, i]) + stage[3, qx, i]
                    dy = stage[0, 1, i] + two * (stage[1, qy, i] + stage[2, qy, i]) + stage[3, qy, i]
                    dx *= signed
                    dy *= signed
                else:
                    signed = hh if d == 0 else -hh
                    dx = signed * stage[1, qx, i]
                    dy = signed * stage[1, qy, i]
                end_x = x + dx
                end_y = y + dy
                valid = ok[n_stages - 1, d, i] and -0.5 <= end_x <= nx - 0.5 and -0.5 <= end_y <= ny - 0.5
                maps[d, j, i + 1, 0] = dx if valid else nan
                maps[d, j, i + 1, 1] = dy if valid else nan


@njit(cache=True, fastmath={"contract"})
def _map_step(m, tex, row: np.uint64, shortest2, x, y, dx, dy, alive):
    """One step of a streamline through a flat step map ``m`` and texture ``tex``.

    (x, y) are padded coordinates (pixel centre i at x = i + 1); ``row`` is the padded
    width. Returns the new position, the next step, whether the streamline is still
    alive, and the texture value at the new position. A NaN step (a cell that cannot
    step) or one that turns back by more than 90 degrees ends the streamline; the
    sample at the point it reached still counts, as in the exact method.
    """
    x = x + dx
    y = y + dy
    c, fx, fy = _cell(x, y, row)
    ndx, ndy = _blend2(m, c, row, fx, fy)
    b = c + row
    top = tex[c] + fx * (tex[c + _U1] - tex[c])
    t = top + fy * (tex[b] + fx * (tex[b + _U1] - tex[b]) - top)
    # False for a NaN step too. A step that turns back has passed a sink or a source; a
    # blend of steps that mostly cancel (shorter than half a step) is within a pixel of
    # one: the exact method would overshoot and turn back there.
    ok = (dx * ndx + dy * ndy >= _F0) & (ndx * ndx + ndy * ndy >= shortest2)
    return x, y, (ndx if ok else _F0), (ndy if ok else _F0), (alive if ok else _F0), t


@njit(cache=True)
def _map_start(m, row: int, i: int, j: int):
    """First step and liveness of the streamline from padded cell (i, j)."""
    c = 2 * (j * row + i)
    dx = m[c]
    ok = dx == dx
    return (dx if ok else _F0), (m[c + 1] if ok else _F0), (_F1 if ok else _F0)


@njit(cache=True, parallel=True, fastmath={"contract"})
def _lic_flowmap(forward, backward, tex, nx: int, ny: int, h: float, mean: float, weights, out) -> None:
    """Per-pixel LIC through the step maps; ``weights[k]`` weighs the k-th step each way,
    ``mean`` is added back to the (centred) texture's averages.

    Four pixels, each traced forward and backward, advance together: eight
    independent dependency chains that the processor overlaps.
    """
    row = np.uint64(nx + 2)
    row_int = nx + 2
    n_steps = weights.shape[0]
    shortest2 = np.float32(0.25 * h * h)
    for j in prange(ny):
        y = np.float32(j + 1)
        for i in range(0, nx, 4):
            # The last group of a row repeats its last pixel when nx is not a multiple of 4.
            ia = i + 1
            ib = min(i + 1, nx - 1) + 1
            ic = min(i + 2, nx - 1) + 1
            id_ = min(i + 3, nx - 1) + 1
            xa, xb, xc, xd = np.float32(ia), np.float32(ib), np.float32(ic), np.float32(id_)
            x1, y1, x2, y2, x3, y3, x4, y4 = xa, y, xa, y, xb, y, xb, y
            x5, y5, x6, y6, x7, y7, x8, y8 = xc, y, xc, y, xd, y, xd, y
            d1x, d1y, a1 = _map_start(forward, row_int, ia, j + 1)
            d2x, d2y, a2 = _map_start(backward, row_int, ia, j + 1)
            d3x, d3y, a3 = _map_start(forward, row_int, ib, j + 1)
            d4x, d4y, a4 = _map_start(backward, row_int, ib, j + 1)
            d5x, d5y, a5 = _map_start(forward, row_int, ic, j + 1)
            d6x, d6y, a6 = _map_start(backward, row_int, ic, j + 1)
            d7x, d7y, a7 = _map_start(forward, row_int, id_, j + 1)
            d8x, d8y, a8 = _map_start(backward, row_int, id_, j + 1)
            sum_a = tex[(j + 1) * row_int + ia]
            sum_b = tex[(j + 1) * row_int + ib]
            sum_c = tex[(j + 1) * row_int + ic]
            sum_d = tex[(j + 1) * row_int + id_]
            weight_a = weight_b = weight_c = weight_d = _F1
            for k in range(n_steps):
                w = weights[k]
                c1, c2, c3, c4 = w * a1, w * a2, w * a3, w * a4
                c5, c6, c7, c8 = w * a5, w * a6, w * a7, w * a8
                x1, y1, d1x, d1y, a1, t1 = _map_step(forward, tex, row, shortest2, x1, y1, d1x, d1y, a1)
                x2, y2, d2x, d2y, a2, t2 = _map_step(backward, tex, row, shortest2, x2, y2, d2x, d2y, a2)
                x3, y3, d3x, d3y, a3, t3 = _map_step(forward, tex, row, shortest2, x3, y3, d3x, d3y, a3)
                x4, y4, d4x, d4y, a4, t4 = _map_step(backward, tex, row, shortest2, x4, y4, d4x, d4y, a4)
                x5, y5, d5x, d5y, a5, t5 = _map_step(forward, tex, row, shortest2, x5, y5, d5x, d5y, a5)
                x6, y6, d6x, d6y, a6, t6 = _map_step(backward, tex, row, shortest2, x6, y6, d6x, d6y, a6)
                x7, y7, d7x, d7y, a7, t7 = _map_step(forward, tex, row, shortest2, x7, y7, d7x, d7y, a7)
                x8, y8, d8x, d8y, a8, t8 = _map_step(backward, tex, row, shortest2, x8, y8, d8x, d8y, a8)
                sum_a += c1 * t1 + c2 * t2
                sum_b += c3 * t3 + c4 * t4
                sum_c += c5 * t5 + c6 * t6
                sum_d += c7 * t7 + c8 * t8
                weight_a += c1 + c2
                weight_b += c3 + c4
                weight_c += c5 + c6
                weight_d += c7 + c8
            out[j, ia - 1] = np.float64(sum_a / weight_a) + mean
            out[j, ib - 1] = np.float64(sum_b / weight_b) + mean
            out[j, ic - 1] = np.float64(sum_c / weight_c) + mean
            out[j, id_ - 1] = np.float64(sum_d / weight_d) + mean
