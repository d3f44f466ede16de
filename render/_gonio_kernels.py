"""The gonioreflectometer's numba kernels (private; :mod:`render.gonio` documents and wraps them).

See :mod:`render.gonio` for the tracer (max-mipmap DDA over a height field, watertight
by construction), the energy split at each hit and the binning.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from noise.hashing import mix64, stream_uniform
from render.fresnel import _fresnel

_STACK = 64  # pending rays per primary ray (each hit pushes at most two)
_LOCAL = 64  # distinct deposits per primary ray before they are flushed
_MAX_DEPTH = 64  # bounces along one path
_MAX_STEPS = 1 << 22  # cells and blocks visited by one ray before it counts as lost
_ROULETTE_W = 1e-3  # paths below this weight play Russian roulette (unbiased)
_CHUNKS = 8  # fixed chunks per incident direction: results do not depend on threading

_INF = np.inf


@njit(cache=True)
def _trace(
    h, px, py, mip, mip_off, mip_nx, n_levels, zmax, zmin, ox, oy, oz, dx, dy, dz, skip_ci, skip_cj, skip_tri
):
    """First hit of a ray with the periodic height field.

    Each cell is four triangles around its centre (the mean of its corners): 0 bottom
    (v00, v10, c), 1 right (v10, v11, c), 2 top (v11, v01, c), 3 left (v01, v00, c).
    Returns ``(status, t, nx, ny, nz, ci, cj, tri, steps)``: status 0 escaped (above every
    sample, going up), 1 hit (unwrapped cell ``ci, cj``, triangle ``tri``, unit normal),
    2 lost (step budget exhausted).
    """
    ny_, nx_ = h.shape
    if skip_tri >= 0:
        ci, cj = skip_ci, skip_cj
        d_valid = True
    else:
        ci = int(math.floor(ox / px))
        cj = int(math.floor(oy / py))
        d_valid = False
    d_prev = 0.0
    t = 0.0
    level = 0
    steps = 0
    # Reciprocals once per ray: the loop below multiplies instead of dividing.
    inv_dx = 1.0 / dx if dx != 0.0 else 0.0
    inv_dy = 1.0 / dy if dy != 0.0 else 0.0
    inv_px = 1.0 / px
    inv_py = 1.0 / py
    du = dx * inv_px
    dv = dy * inv_py
    while steps < _MAX_STEPS:
        steps += 1
        z = oz + t * dz
        if dz >= 0.0 and z >= zmax:
            return 0, t, 0.0, 0.0, 0.0, ci, cj, -1, steps
        # Most steps stay in the base tile, where wrapping needs no division.
        wi_ = ci if 0 <= ci < nx_ else ci % nx_
        wj_ = cj if 0 <= cj < ny_ else cj % ny_
        size = 1 << level
        bi = wi_ >> level
        bj = wj_ >> level
        xa = ci - wi_ + bi * size
        xb = ci - wi_ + min((bi + 1) * size, nx_)
        ya = cj - wj_ + bj * size
        yb = cj - wj_ + min((bj + 1) * size, ny_)
        if dx > 0.0:
            tx = (xb * px - ox) * inv_dx
        elif dx < 0.0:
            tx = (xa * px - ox) * inv_dx
        else:
            tx = _INF
        if dy > 0.0:
            ty = (yb * py - oy) * inv_dy
        elif dy < 0.0:
            ty = (ya * py - oy) * inv_dy
        else:
            ty = _INF
        t_exit = min(tx, ty)
        if t_exit == _INF:
            # Vertical ray: it leaves through the top or meets the surface below.
            if dz > 0.0:
                return 0, t, 0.0, 0.0, 0.0, ci, cj, -1, steps
            t_exit = t + (z - zmin + 1.0) / (-dz)
        if t_exit < t:
            t_exit = t
        z_exit = oz + t_exit * dz
        # Strictly above the block's highest sample: skip it whole. (A cell skipped this
        # way starts the next cell's height chain afresh; the ray is above both there.)
        skip = min(z, z_exit) > mip[mip_off[level] + bj * mip_nx[level] + bi]
        if not skip and level > 0:
            level -= 1
            continue
        if not skip:
            # Level 0: the cell (ci, cj). u, v are cell-local coordinates in [0, 1]; every
            # triangle's plane passes through the centre (1/2, 1/2, hc).
            c1 = wi_ + 1 if wi_ + 1 < nx_ else 0
            r1 = wj_ + 1 if wj_ + 1 < ny_ else 0
            h00 = h[wj_, wi_]
            h10 = h[wj_, c1]
            h01 = h[r1, wi_]
            h11 = h[r1, c1]
            hc = 0.25 * ((h00 + h11) + (h10 + h01))
            u0 = (ox - ci * px) * inv_px - 0.5
            v0 = (oy - cj * py) * inv_py - 0.5
            # The ray crosses the diagonals u = v and u = -v (centred coordinates) at most once each.
            t1 = (v0 - u0) / (du - dv) if du != dv else _INF
            t2 = -(u0 + v0) / (du + dv) if du != -dv else _INF
            if t2 < t1:
                t1, t2 = t2, t1
            # Segment ends: the crossings inside (t, t_exit), in order, then the exit.
            n_cross = 0
            c_a = t_exit
            c_b = t_exit
            if t < t1 < t_exit:
                c_a = t1
                n_cross = 1
            if t < t2 < t_exit:
                if n_cross == 0:
                    c_a = t2
                else:
                    c_b = t2
                n_cross += 1
            a = t
            for seg in range(n_cross + 1):
                b = c_a if seg == 0 else (c_b if seg == 1 else t_exit)
                tm = 0.5 * (a + b)
                um = u0 + tm * du
                vm = v0 + tm * dv
                # Below u = v: bottom or right; above: top or left (split by u + v = 0).
                below = um + vm < 0.0
                tri = (0 if below else 1) if um >= vm else (3 if below else 2)
                if tri == 0:
                    su = h10 - h00
                    sv = 2.0 * hc - (h00 + h10)
                elif tri == 1:
                    su = (h10 + h11) - 2.0 * hc
                    sv = h11 - h10
                elif tri == 2:
                    su = h11 - h01
                    sv = (h01 + h11) - 2.0 * hc
                else:
                    su = 2.0 * hc - (h00 + h01)
                    sv = h01 - h00
                gx = su * inv_px
                gy = sv * inv_py
                if tri == skip_tri and ci == skip_ci and cj == skip_cj:
                    # The facet the ray leaves: d(t) = t * slope exactly, never a hit.
                    d_b = b * (dz - gx * dx - gy * dy)
                else:
                    d_b = (oz + b * dz) - (hc + (u0 + b * du) * su + (v0 + b * dv) * sv)
                    if d_b < 0.0:
                        if d_valid:
                            d_a = max(d_prev, 0.0)
                        else:
                            d_a = max((oz + a * dz) - (hc + (u0 + a * du) * su + (v0 + a * dv) * sv), 0.0)
                        t_hit = a + d_a * (b - a) / (d_a - d_b)
                        inv = 1.0 / math.sqrt(gx * gx + gy * gy + 1.0)
                        return 1, t_hit, -gx * inv, -gy * inv, inv, ci, cj, tri, steps
                d_prev = d_b
                d_valid = True
                a = b
        else:
            d_valid = False
        # Step into the next block (or cell) along the ray.
        t = t_exit
        if tx <= ty:
            ci = xb if dx > 0.0 else xa - 1
            if tx == ty:
                cj = yb if dy > 0.0 else ya - 1
            else:
                cj = min(max(int(math.floor((oy + t * dy) / py)), ya), yb - 1)
        else:
            cj = yb if dy > 0.0 else ya - 1
            ci = min(max(int(math.floor((ox + t * dx) / px)), xa), xb - 1)
        if skip and level < n_levels - 1:
            level += 1
    return 2, t, 0.0, 0.0, 0.0, ci, cj, -1, steps


@njit(cache=True, inline="always")
def _roulette(w: float, u: float) -> float:
    """Russian roulette: a small weight survives, raised to the threshold, with probability w / threshold."""
    return _ROULETTE_W if u * _ROULETTE_W < w else 0.0


@njit(cache=True, inline="always")
def _push(
    st_o, st_d, st_w, st_cell, st_depth, st_spec, top, ox, oy, oz, dx, dy, dz, w, ci, cj, tri, depth, spec
):
    st_o[top, 0], st_o[top, 1], st_o[top, 2] = ox, oy, oz
    st_d[top, 0], st_d[top, 1], st_d[top, 2] = dx, dy, dz
    st_w[top] = w
    st_cell[top, 0], st_cell[top, 1], st_cell[top, 2] = ci, cj, tri
    st_depth[top] = depth
    st_spec[top] = spec


@njit(cache=True, inline="always")
def _primary_origin(ray_key, window, d_idx, px, py, wix, wiy, wiz, zmax, period_x, period_y):
    """Where primary ray ``ray_key`` starts (at z = zmax), from the first two numbers of its stream.

    Uniform over the lit window on the mean plane z = 0, moved up along the ray to zmax
    and wrapped into the tile.
    """
    x0 = (window[d_idx, 0] + stream_uniform(ray_key, np.uint64(0)) * window[d_idx, 1]) * px + wix / wiz * zmax
    y0 = (window[d_idx, 2] + stream_uniform(ray_key, np.uint64(1)) * window[d_idx, 3]) * py + wiy / wiz * zmax
    x0 -= math.floor(x0 / period_x) * period_x
    y0 -= math.floor(y0 / period_y) * period_y
    return x0, y0


@njit(cache=True, inline="always")
def _deposit(local_bin, local_all, local_spec, n_local, acc_all, sq_all, acc_spec, sq_spec, c, b, w, spec):
    for k in range(n_local):
        if local_bin[k] == b:
            local_all[k] += w
            if spec:
                local_spec[k] += w
            return n_local
    if n_local == _LOCAL:
        # Out of room: add straight in (the variance estimate loses a cross term only).
        acc_all[c, b] += w
        sq_all[c, b] += w * w
        if spec:
            acc_spec[c, b] += w
            sq_spec[c, b] += w * w
        return n_local
    local_bin[n_local] = b
    local_all[n_local] = w
    local_spec[n_local] = w if spec else 0.0
    return n_local + 1


@njit(cache=True, parallel=True, nogil=True)
def _gonio(
    h,
    px,
    py,
    mip,
    mip_off,
    mip_nx,
    n_levels,
    zmax,
    zmin,
    wis,
    rays,
    window,
    mirror,
    e_perp,
    ap_in,
    ap_perp,
    eta,
    body_factor,
    perfect,
    n_theta,
    n_phi,
    key,
    acc_all,
    sq_all,
    acc_spec,
    sq_spec,
    scalars,
):
    ny_, nx_ = h.shape
    period_x = nx_ * px
    period_y = ny_ * py
    n_dir = wis.shape[0]
    for job in prange(n_dir * _CHUNKS):
        d_idx = job // _CHUNKS
        chunk = job % _CHUNKS
        n_rays = rays[d_idx]
        k0 = chunk * n_rays // _CHUNKS
        k1 = (chunk + 1) * n_rays // _CHUNKS
        st_o = np.empty((_STACK, 3))
        st_d = np.empty((_STACK, 3))
        st_w = np.empty(_STACK)
        st_cell = np.empty((_STACK, 3), dtype=np.int64)
        st_depth = np.empty(_STACK, dtype=np.int64)
        st_spec = np.empty(_STACK, dtype=np.bool_)
        local_bin = np.empty(_LOCAL, dtype=np.int64)
        local_all = np.empty(_LOCAL)
        local_spec = np.empty(_LOCAL)
        wix, wiy, wiz = wis[d_idx, 0], wis[d_idx, 1], wis[d_idx, 2]
        for k in range(k0, k1):
            ray_key = mix64(key ^ (np.uint64(d_idx) << np.uint64(40)) ^ np.uint64(k))
            x0, y0 = _primary_origin(ray_key, window, d_idx, px, py, wix, wiy, wiz, zmax, period_x, period_y)
            counter = np.uint64(2)  # the stream's first two numbers placed the ray
            st_o[0, 0], st_o[0, 1], st_o[0, 2] = x0, y0, zmax
            st_d[0, 0], st_d[0, 1], st_d[0, 2] = -wix, -wiy, -wiz
            st_w[0] = 1.0
            st_cell[0, 0], st_cell[0, 1], st_cell[0, 2] = 0, 0, -1
            st_depth[0] = 0
            st_spec[0] = True
            top = 1
            n_local = 0
            aperture = 0.0
            escaped = 0.0
            while top > 0:
                top -= 1
                ox, oy, oz = st_o[top, 0], st_o[top, 1], st_o[top, 2]
                dx, dy, dz = st_d[top, 0], st_d[top, 1], st_d[top, 2]
                w = st_w[top]
                sci, scj, stri = st_cell[top, 0], st_cell[top, 1], st_cell[top, 2]
                depth = st_depth[top]
                spec = st_spec[top]
                status, t, nx, ny, nz, ci, cj, tri, n_steps = _trace(
                    h,
                    px,
                    py,
                    mip,
                    mip_off,
                    mip_nx,
                    n_levels,
                    zmax,
                    zmin,
                    ox,
                    oy,
                    oz,
                    dx,
                    dy,
                    dz,
                    sci,
                    scj,
                    stri,
                )
                scalars[job, 5] += n_steps
                scalars[job, 6] += 1.0
                if status == 2:
                    scalars[job, 4] += w
                    continue
                if status == 0:
                    escaped += w
                    theta = math.acos(min(dz, 1.0))
                    phi = math.atan2(dy, dx)
                    if phi < 0.0:
                        phi += 2.0 * math.pi
                    it = min(int(theta * (2.0 / math.pi) * n_theta), n_theta - 1)
                    ip = min(int(phi * (0.5 / math.pi) * n_phi), n_phi - 1)
                    n_local = _deposit(
                        local_bin,
                        local_all,
                        local_spec,
                        n_local,
                        acc_all,
                        sq_all,
                        acc_spec,
                        sq_spec,
                        job,
                        it * n_phi + ip,
                        w,
                        spec,
                    )
                    if ap_in[d_idx] > 0.0:
                        ex, ey, ez = e_perp[d_idx, 0], e_perp[d_idx, 1], e_perp[d_idx, 2]
                        across = dx * ex + dy * ey + dz * ez
                        qx, qy, qz = dx - across * ex, dy - across * ey, dz - across * ez
                        qn = math.sqrt(qx * qx + qy * qy + qz * qz)
                        if qn > 0.0:
                            mx, my, mz = mirror[d_idx, 0], mirror[d_idx, 1], mirror[d_idx, 2]
                            c_in = min(max((qx * mx + qy * my + qz * mz) / qn, -1.0), 1.0)
                            if (
                                math.acos(c_in) <= ap_in[d_idx]
                                and abs(math.asin(min(max(across, -1.0), 1.0))) <= ap_perp[d_idx]
                            ):
                                aperture += w
                    continue
                if depth >= _MAX_DEPTH:
                    scalars[job, 4] += w
                    continue
                # A hit: wrap the point back into the base tile, keeping its cell.
                hx = ox + t * dx
                hy = oy + t * dy
                hz = oz + t * dz
                tile_i = ci - ci % nx_
                tile_j = cj - cj % ny_
                hx -= tile_i * px
                hy -= tile_j * py
                ci -= tile_i
                cj -= tile_j
                cos_i = -(dx * nx + dy * ny + dz * nz)
                fr = 1.0 if perfect else _fresnel(cos_i, eta)
                # Mirror reflection keeps the specular flag.
                wr = w * fr
                if wr > 0.0:
                    if wr < _ROULETTE_W:
                        wr = _roulette(wr, stream_uniform(ray_key, counter))
                        counter += np.uint64(1)
                    if wr > 0.0 and top < _STACK:
                        _push(st_o, st_d, st_w, st_cell, st_depth, st_spec, top, hx, hy, hz,
                              dx + 2.0 * cos_i * nx, dy + 2.0 * cos_i * ny, dz + 2.0 * cos_i * nz,
                              wr, ci, cj, tri, depth + 1, spec)  # fmt: skip
                        top += 1
                    elif wr > 0.0:
                        scalars[job, 4] += wr
                # The body: a cosine-distributed ray leaving the facet, weighted by 1 - R(theta_o).
                if body_factor > 0.0 and not perfect:
                    u1 = stream_uniform(ray_key, counter)
                    u2 = stream_uniform(ray_key, counter + np.uint64(1))
                    counter += np.uint64(2)
                    r = math.sqrt(u1)
                    lx = r * math.cos(2.0 * math.pi * u2)
                    ly = r * math.sin(2.0 * math.pi * u2)
                    lz = math.sqrt(max(1.0 - u1, 0.0))
                    s = math.copysign(1.0, nz)
                    aa = -1.0 / (s + nz)
                    bb = nx * ny * aa
                    b1x, b1y, b1z = 1.0 + s * nx * nx * aa, s * bb, -s * nx
                    b2x, b2y, b2z = bb, s + ny * ny * aa, -ny
                    ddx = lx * b1x + ly * b2x + lz * nx
                    ddy = lx * b1y + ly * b2y + lz * ny
                    ddz = lx * b1z + ly * b2z + lz * nz
                    wd = w * (1.0 - fr) * body_factor * (1.0 - _fresnel(lz, eta))
                    if wd < _ROULETTE_W:
                        wd = _roulette(wd, stream_uniform(ray_key, counter))
                        counter += np.uint64(1)
                    if wd > 0.0 and top < _STACK:
                        _push(st_o, st_d, st_w, st_cell, st_depth, st_spec, top, hx, hy, hz,
                              ddx, ddy, ddz, wd, ci, cj, tri, depth + 1, False)  # fmt: skip
                        top += 1
                    elif wd > 0.0:
                        scalars[job, 4] += wd
            for m in range(n_local):
                b = local_bin[m]
                v = local_all[m]
                acc_all[job, b] += v
                sq_all[job, b] += v * v
                v = local_spec[m]
                if v != 0.0:
                    acc_spec[job, b] += v
                    sq_spec[job, b] += v * v
            scalars[job, 0] += escaped
            scalars[job, 1] += escaped * escaped
            scalars[job, 2] += aperture
            scalars[job, 3] += aperture * aperture
