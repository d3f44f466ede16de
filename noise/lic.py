"""Line integral convolution in 2-D (Cabral & Leedom 1993; Stalling & Hege 1995).

Each output pixel is the average of the input texture along the streamline of the
vector field through it, ``length`` pixels forward and backward. Streamlines are
integrated on the *normalised* field (unit speed, so arc length is the parameter),
interpolated bilinearly, with second- or fourth-order Runge-Kutta steps, and the box
kernel is integrated with the trapezoidal rule over exactly [-length, length]. A
streamline stops at the image border, at a zero vector, where the field is NaN, and
where a step would turn back by more than 90 degrees (it has run into a sink or a
source: at unit speed it would otherwise oscillate about the critical point and
average the texture there); the average is then taken over what was traced, as in
Cabral & Leedom.

Three evaluation strategies:

* ``"flowmap"`` (the default): one streamline per pixel centre, but each step is read
  from a precomputed *step map* instead of being integrated again: the map holds, at
  every pixel centre, the Runge-Kutta step of length ``step`` forward and backward
  (one integration per pixel and direction, O(N)), and a streamline at any point steps
  by the bilinear interpolation of the map there, then samples the texture at the same
  four cells. A step costs one bilinear look-up of three float32 channels, about a
  third of an RK2 step on the field, and eight streamline halves run interleaved so
  that the processor overlaps their latencies. The interpolated map differs from
  integrating at the point itself by O(h dx^2) per step; the bench measures what that
  costs (the correlation with the reference). Within about a pixel of a critical
  point the four cells' steps point different ways and their blend shrinks; a blend
  shorter than half a step ends the streamline there, where the exact method would
  overshoot and turn back.
* ``"exact"``: one streamline per pixel centre, integrated on the field at every step
  (any kernel). Slow; the reference the others are measured against.
* ``"stalling-hege"``: the fast box-kernel method of Stalling & Hege: one long
  streamline serves many pixels, its box-filtered values computed by running sums in
  O(1) per sample; new streamlines start only in pixels that no earlier one has
  covered, and grow a kernel length at a time while they still cover new pixels. The
  image is split into a fixed number of row bands, each with its own coverage and
  accumulators, so the result does not depend on the number of threads. A sample
  stands for the pixels within ``max_offset`` of it, so the result is only as close to
  the per-pixel one as that offset allows.

All three are deterministic and independent of the thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from noise._lic_flowmap import _build_step_maps, _lic_flowmap, _pad_inputs, _scan_inputs

KERNELS = ("box", "hann")
INTEGRATORS = ("rk2", "rk4")
METHODS = ("flowmap", "exact", "stalling-hege")
_BANDS = 4  # fixed, so results do not depend on the thread count


@njit(cache=True, inline="always")
def _bilinear(a: np.ndarray, x: float, y: float) -> float:
    """Bilinear value of ``a`` at (x, y) in pixel units (centres at integers), clamped to the image."""
    ny, nx = a.shape
    xc = min(max(x, 0.0), nx - 1.0)
    yc = min(max(y, 0.0), ny - 1.0)
    i0 = min(int(xc), max(nx - 2, 0))
    j0 = min(int(yc), max(ny - 2, 0))
    i1 = min(i0 + 1, nx - 1)
    j1 = min(j0 + 1, ny - 1)
    fx = xc - i0
    fy = yc - j0
    top = a[j0, i0] * (1 - fx) + a[j0, i1] * fx
    bottom = a[j1, i0] * (1 - fx) + a[j1, i1] * fx
    return top * (1 - fy) + bottom * fy


@njit(cache=True, inline="always")
def _field(u: np.ndarray, v: np.ndarray, x: float, y: float) -> tuple[float, float, bool]:
    """Unit field direction at pixel coordinates (x, y); not ok outside the image or at a zero."""
    ny, nx = u.shape
    if not (x >= -0.5 and x <= nx - 0.5 and y >= -0.5 and y <= ny - 0.5):
        return 0.0, 0.0, False
    du = _bilinear(u, x, y)
    dv = _bilinear(v, x, y)
    norm = math.sqrt(du * du + dv * dv)
    if not norm > 1e-12:  # also catches NaN
        return 0.0, 0.0, False
    return du / norm, dv / norm, True


# Not inlined: at numba's IR level each call site of ``_step`` inlined twelve bilinear lookups
# (both integrators), and the exact and Stalling-Hege kernels took 7 and 9 s to compile; as a
# call they take 4 and 3 s and run as fast (a step is two or four field lookups).
@njit(cache=True)
def _step(u, v, x: float, y: float, h: float, rk4: bool) -> tuple[float, float, bool]:
    """One Runge-Kutta step of signed length h from (x, y) along the unit field."""
    k1x, k1y, ok = _field(u, v, x, y)
    if not ok:
        return x, y, False
    if not rk4:
        k2x, k2y, ok = _field(u, v, x + 0.5 * h * k1x, y + 0.5 * h * k1y)
        if not ok:
            return x, y, False
        return x + h * k2x, y + h * k2y, True
    k2x, k2y, ok = _field(u, v, x + 0.5 * h * k1x, y + 0.5 * h * k1y)
    if not ok:
        return x, y, False
    k3x, k3y, ok = _field(u, v, x + 0.5 * h * k2x, y + 0.5 * h * k2y)
    if not ok:
        return x, y, False
    k4x, k4y, ok = _field(u, v, x + h * k3x, y + h * k3y)
    if not ok:
        return x, y, False
    return x + h * (k1x + 2 * k2x + 2 * k3x + k4x) / 6.0, y + h * (k1y + 2 * k2y + 2 * k3y + k4y) / 6.0, True


@njit(cache=True, inline="always")
def _step_on(u, v, x: float, y: float, h: float, rk4: bool, px: float, py: float):
    """``_step``, refused where it would turn back (more than 90 degrees) from the previous
    step (px, py): the streamline has run into a sink or a source, where it ends."""
    x1, y1, ok = _step(u, v, x, y, h, rk4)
    if ok and (x1 - x) * px + (y1 - y) * py < 0.0:
        return x, y, False
    return x1, y1, ok


@njit(cache=True, inline="always")
def _sample(texture: np.ndarray, x: float, y: float) -> float:
    """Bilinear texture value at (x, y), clamped to the image."""
    return _bilinear(texture, x, y)


@njit(cache=True)
def _kernel_weight(k: int, n_steps: int, hann: bool) -> float:
    """Weight of the k-th sample (1..n_steps) each way; the centre sample weighs 1.

    Box: the trapezoidal rule, so that the sum is the integral over exactly
    [-length, length] (the end samples stand for half a step). Hann: the raised cosine.
    """
    if hann:
        return 0.5 * (1.0 + math.cos(math.pi * k / (n_steps + 1)))
    return 0.5 if k == n_steps else 1.0


@njit(cache=True, parallel=True)
def _lic_per_pixel(u, v, texture, n_steps: np.int64, h: float, rk4: bool, hann: bool, out) -> None:
    ny, nx = texture.shape
    for j in prange(ny):
        for i in range(nx):
            total = _sample(texture, float(i), float(j))
            weight = 1.0
            for direction in (1.0, -1.0):
                x, y = float(i), float(j)
                px, py = 0.0, 0.0
                for k in range(1, n_steps + 1):
                    x1, y1, ok = _step_on(u, v, x, y, direction * h, rk4, px, py)
                    if not ok:
                        break
                    px, py = x1 - x, y1 - y
                    x, y = x1, y1
                    w = _kernel_weight(k, n_steps, hann)
                    total += w * _sample(texture, x, y)
                    weight += w
            out[j, i] = total / weight


@njit(cache=True)
def _extend(
    u, v, texture, xs, ys, ts, run, mid, end: np.int64, steps: np.int64, sign: int, h: float, rk4: bool
):
    """Trace up to ``steps`` more steps from buffer index ``end`` in direction ``sign``.

    Keeps the running sums ``run`` such that the sum of ts over [a, b] is
    run[b] - run[a - 1]. Returns the new end index and whether the streamline ended.
    """
    x, y = xs[end], ys[end]
    for _ in range(steps):
        started = end != mid  # the streamline's first step each way has nothing to turn from
        px = x - xs[end - sign] if started else 0.0
        py = y - ys[end - sign] if started else 0.0
        x, y, ok = _step_on(u, v, x, y, sign * h, rk4, px, py)
        if not ok:
            return end, True
        end += sign
        xs[end] = x
        ys[end] = y
        ts[end] = _sample(texture, x, y)
        if sign > 0:
            run[end] = run[end - 1] + ts[end]
        else:
            run[end] = run[end + 1] - ts[end + 1]
    return end, False


@njit(cache=True)
def _deposit(xs, ys, ts, run, lo, hi, k0, k1, n_half, max_offset, s, c) -> np.int64:
    """Add the box-filtered values of samples k0..k1 to the pixels they stand for; count new pixels."""
    ny, nx = s.shape
    fresh = 0
    for k in range(k0, k1 + 1):
        a = max(k - n_half, lo)
        b = min(k + n_half, hi)
        before = run[a] - ts[a]  # run[a - 1], also where a is the buffer's first sample
        value = (run[b] - before) / (b - a + 1)
        pi = int(xs[k] + 0.5)
        pj = int(ys[k] + 0.5)
        # Only samples near a pixel's centre stand for it: the convolution of noise
        # changes quickly across streamlines.
        if abs(xs[k] - pi) <= max_offset and abs(ys[k] - pj) <= max_offset and 0 <= pi < nx and 0 <= pj < ny:
            if c[pj, pi] == 0:
                fresh += 1
            s[pj, pi] += value
            c[pj, pi] += 1
    return fresh


@njit(cache=True, parallel=True)
def _lic_fast_box(
    u, v, texture, n_half: np.int64, n_cap: np.int64, h: float, rk4: bool, max_offset: float, sums, hits
):
    """Stalling & Hege's fast LIC for the box kernel; per-band accumulators sums[b], hits[b].

    A streamline starts at an uncovered pixel centre and is extended, a kernel length
    at a time, for as long as its samples still reach pixels that nothing has covered.
    """
    ny, nx = texture.shape
    n_bands = sums.shape[0]
    mid = n_cap
    for band in prange(n_bands):
        j_begin = band * ny // n_bands
        j_end = (band + 1) * ny // n_bands
        xs = np.empty(2 * n_cap + 1)
        ys = np.empty(2 * n_cap + 1)
        ts = np.empty(2 * n_cap + 1)
        run = np.empty(2 * n_cap + 1)
        s = sums[band]
        c = hits[band]
        for j in range(j_begin, j_end):
            for i in range(nx):
                if c[j, i] > 0:
                    continue
                xs[mid] = float(i)
                ys[mid] = float(j)
                ts[mid] = texture[j, i]
                run[mid] = ts[mid]
                hi, hi_stop = _extend(u, v, texture, xs, ys, ts, run, mid, mid, n_half, 1, h, rk4)
                lo, lo_stop = _extend(u, v, texture, xs, ys, ts, run, mid, mid, n_half, -1, h, rk4)
                # Samples whose window reaches past where tracing was cut short (not
                # where the streamline ended) are not final yet.
                done_hi = hi if hi_stop else hi - n_half
                done_lo = lo if lo_stop else lo + n_half
                _deposit(xs, ys, ts, run, lo, hi, done_lo, done_hi, n_half, max_offset, s, c)
                while not hi_stop and hi - mid + n_half <= n_cap:
                    hi, hi_stop = _extend(u, v, texture, xs, ys, ts, run, mid, hi, n_half, 1, h, rk4)
                    new_hi = hi if hi_stop else hi - n_half
                    fresh = _deposit(xs, ys, ts, run, lo, hi, done_hi + 1, new_hi, n_half, max_offset, s, c)
                    done_hi = new_hi
                    if fresh == 0:
                        break
                while not lo_stop and mid - lo + n_half <= n_cap:
                    lo, lo_stop = _extend(u, v, texture, xs, ys, ts, run, mid, lo, n_half, -1, h, rk4)
                    new_lo = lo if lo_stop else lo + n_half
                    fresh = _deposit(xs, ys, ts, run, lo, hi, new_lo, done_lo - 1, n_half, max_offset, s, c)
                    done_lo = new_lo
                    if fresh == 0:
                        break


def _as_field(name: str, array: np.ndarray, shape: tuple[int, ...] | None) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(array, dtype=np.float64))
    if arr.ndim != 2 or min(arr.shape) < 1:
        raise ValueError(f"{name}: expected a 2-D array, got shape {arr.shape}")
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape} like the texture, got {arr.shape}")
    return arr


def lic2d(
    u: np.ndarray,
    v: np.ndarray,
    texture: np.ndarray,
    *,
    length: float,
    kernel: str = "box",
    method: str = "flowmap",
    integrator: str = "rk2",
    step: float = 1.0,
    max_offset: float = 0.25,
) -> np.ndarray:
    """Line integral convolution of ``texture`` along the field (u, v).

    Cabral & Leedom (1993), "Imaging vector fields using line integral convolution";
    the fast box-kernel method of Stalling & Hege (1995), "Fast and resolution
    independent line integral convolution".

    Parameters
    ----------
    u, v : (ny, nx) float arrays
        Field components along the image's columns (x) and rows (y), as in ``rlic``;
        only the direction matters. Zero vectors (shorter than 1e-12 of the largest
        component: critical points) and NaN or Inf stop streamlines.
    texture : (ny, nx) float array
        The input texture, typically white noise. Must be finite.
    length : float
        Half-length of the streamline (pixels): it extends this far each way.
    kernel : {"box", "hann"}
        Weights along the streamline.
    method : {"flowmap", "exact", "stalling-hege"}
        How streamlines are evaluated (see the module docstring). ``"flowmap"``
        (default) steps through a precomputed map of Runge-Kutta steps, any kernel;
        ``"exact"`` integrates the field at every step (the slow reference);
        ``"stalling-hege"`` reuses each streamline for many pixels (box kernel only).
    integrator : {"rk2", "rk4"}
        Runge-Kutta order of the streamline integration (for ``"flowmap"``, of the
        steps in its map, computed once per pixel).
    step : float
        Largest integration step (pixels), in (0, 2]; the step taken is
        ``length / ceil(length / step)``, so that whole steps span the half-length. With
        the defaults (RK2, 1 px) the flow map matches the exact method at 0.1-pixel RK4
        steps to a correlation of 0.99 or better on white noise for half-lengths 10 to
        50 (``printapp bench lic``); longer steps undersample the bilinear texture and
        lose accuracy quickly (0.986 at 1.25 px).
    max_offset : float
        ``"stalling-hege"`` only: how far (pixels, per axis) from a pixel's centre a
        streamline sample may be and still stand for that pixel. 0.5 (every sample
        counts, as in Stalling & Hege) is fastest and least accurate.

    Returns
    -------
    (ny, nx) float64 array
        Pixels of the flow map are computed in float32 about the texture's mean
        (relative rounding about 1e-7 of the texture's spread).
    """
    tex = _as_field("texture", texture, None)
    uu = _as_field("u", u, tex.shape)
    vv = _as_field("v", v, tex.shape)
    scan = np.empty((tex.shape[0], 3))
    _scan_inputs(uu, vv, tex, scan)
    if not np.all(scan[:, 2]):
        raise ValueError("texture: expected finite values")
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"length: expected a positive number of pixels, got {length!r}")
    if kernel not in KERNELS:
        raise ValueError(f"kernel: expected one of {KERNELS}, got {kernel!r}")
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator: expected one of {INTEGRATORS}, got {integrator!r}")
    if not (np.isfinite(step) and 0 < step <= 2):
        raise ValueError(f"step: expected a number in (0, 2] pixels, got {step!r}")
    if method == "stalling-hege" and kernel != "box":
        raise ValueError("method: 'stalling-hege' needs kernel='box'")
    if not (np.isfinite(max_offset) and 0 < max_offset <= 0.5):
        raise ValueError(f"max_offset: expected a number in (0, 0.5] pixels, got {max_offset!r}")
    # Scale the field by a power of two (exact: directions do not change) so that its
    # largest finite component lies in [0.5, 1): the zero-vector threshold (1e-12) is
    # then relative to the field's size, and float32 cannot overflow.
    largest = float(scan[:, 0].max())
    scale = math.ldexp(1.0, -math.frexp(largest)[1]) if largest > 0 else 1.0
    # A whole number of steps spans the half-length exactly.
    n_steps = max(1, math.ceil(length / step - 1e-9))
    step = length / n_steps
    rk4 = integrator == "rk4"
    ny, nx = tex.shape
    if method == "flowmap":
        field = np.empty((ny + 2, nx + 2, 2), dtype=np.float32)
        padded_texture = np.empty((ny + 2, nx + 2), dtype=np.float32)
        # Centred, so that float32 keeps the texture's detail whatever its offset.
        mean = float(scan[:, 1].sum()) / tex.size
        _pad_inputs(uu, vv, scale, tex, mean, field, padded_texture)
        maps = np.empty((2, ny + 2, nx + 2, 2), dtype=np.float32)
        _build_step_maps(field.reshape(-1), float(step), rk4, maps)
        hann = kernel == "hann"
        weights = np.array([_kernel_weight(k, n_steps, hann) for k in range(1, n_steps + 1)], np.float32)
        out = np.empty((ny, nx))
        forward, backward = maps[0].reshape(-1), maps[1].reshape(-1)
        _lic_flowmap(forward, backward, padded_texture.reshape(-1), nx, ny, float(step), mean, weights, out)
        return out
    uu = np.where(np.isfinite(uu), uu * scale, np.nan)
    vv = np.where(np.isfinite(vv), vv * scale, np.nan)
    if method == "exact":
        out = np.empty_like(tex)
        _lic_per_pixel(uu, vv, tex, np.int64(n_steps), float(step), rk4, kernel == "hann", out)
        return out
    bands = max(1, min(_BANDS, ny))
    sums = np.zeros((bands, ny, nx), dtype=np.float64)
    hits = np.zeros((bands, ny, nx), dtype=np.int32)
    # Streamlines grow while they cover new pixels, up to this many steps each way.
    cap = np.int64(max(16 * n_steps, round(64 / step)))
    _lic_fast_box(uu, vv, tex, np.int64(n_steps), cap, float(step), rk4, float(max_offset), sums, hits)
    total_hits = hits.sum(axis=0)
    return sums.sum(axis=0) / np.maximum(total_hits, 1)
