"""Numba kernels of the tabulated-NDF model (private; :mod:`render.tabulated_ndf` documents and wraps them).

The microsurface is a list of facet normals ``m`` (unit, ``m_z > 0``) with weights ``w``
that carry ``D(m) dm_x dm_y`` (a facet normal's share of the macro area), so an integral
``integral f(m) D(m) d omega_m`` is ``sum_k w_k f(m_k) / m_z,k``. Directions live on a
grid of ``n_t`` polar angles (evenly from 0 to ``theta_max``) and ``n_p`` azimuths
(evenly over [0, 2 pi), periodic). Every loop over directions is a ``prange`` whose
iterations each sum in a fixed order, so the results do not depend on threading.
"""

from __future__ import annotations

import math

from numba import njit, prange

from render.fresnel import _fresnel


@njit(cache=True, inline="always")
def _grid_value(table, theta_max, x, y, z):
    """Bilinear lookup of a (n_t, n_p) direction table at the unit direction (x, y, z)."""
    theta = math.acos(min(max(z, -1.0), 1.0))
    phi = math.atan2(y, x)
    if phi < 0.0:
        phi += 2.0 * math.pi
    return _grid_at(table, theta_max, theta, phi)


@njit(cache=True, inline="always")
def _grid_cell(n_t, n_p, theta_max, theta, phi):
    """The cell of a (n_t, n_p) direction grid about (theta, phi): rows i0, i0 + 1, columns j0, j1 and
    the bilinear fractions along each."""
    ft = min(theta / theta_max * (n_t - 1), n_t - 1.0)
    i0 = min(int(ft), n_t - 2)
    at = ft - i0
    fp = phi / (2.0 * math.pi) * n_p
    j0 = int(fp)
    ap = fp - j0
    j0 = j0 % n_p
    j1 = (j0 + 1) % n_p
    return i0, j0, j1, at, ap


@njit(cache=True, inline="always")
def _grid_at(table, theta_max, theta, phi):
    """Bilinear lookup of a (n_t, n_p) direction table at polar angle theta and azimuth phi in [0, 2 pi)."""
    n_t, n_p = table.shape
    i0, j0, j1, at, ap = _grid_cell(n_t, n_p, theta_max, theta, phi)
    low = (1.0 - ap) * table[i0, j0] + ap * table[i0, j1]
    high = (1.0 - ap) * table[i0 + 1, j0] + ap * table[i0 + 1, j1]
    return (1.0 - at) * low + at * high


@njit(cache=True, parallel=True)
def _projected_area(m, w, dirs, out):
    """``out[j] = integral max(0, -d_j . m) D(m) d omega_m``: Smith's ``Lambda cos``."""
    for j in prange(dirs.shape[0]):
        dx, dy, dz = dirs[j, 0], dirs[j, 1], dirs[j, 2]
        acc = 0.0
        for k in range(m.shape[0]):
            c = -(dx * m[k, 0] + dy * m[k, 1] + dz * m[k, 2])
            if c > 0.0:
                acc += w[k] * c / m[k, 2]
        out[j] = acc


@njit(cache=True, inline="always")
def _g2_over_g1(cos_i, area_i, cos_o, area_o):
    """Height-correlated Smith ``G2 / G1(wi) = (1 + L_i) / (1 + L_i + L_o)`` from ``L cos = area``."""
    a = cos_i + area_i
    return a * cos_o / max(a * cos_o + area_o * cos_i, 1e-300)


@njit(cache=True, parallel=True)
def _second_bounce(m, w, dirs, area, theta_max, eta, out):
    """Per travel direction d (a blocked ray), the expected ``F G1(o2)`` of its next facet.

    The next facet is drawn, as Smith's microsurface has it (Heitz et al. 2016), from the
    normals facing the ray, ``max(0, -d . m) D(m)``; ``o2`` is the reflection, which
    escapes with probability ``G1(o2)`` (zero below the horizon). ``eta <= 0``: F = 1.
    """
    for j in prange(dirs.shape[0]):
        dx, dy, dz = dirs[j, 0], dirs[j, 1], dirs[j, 2]
        num = 0.0
        den = 0.0
        for k in range(m.shape[0]):
            c = -(dx * m[k, 0] + dy * m[k, 1] + dz * m[k, 2])
            if c <= 0.0:
                continue
            wk = w[k] * c / m[k, 2]
            den += wk
            ox = dx + 2.0 * c * m[k, 0]
            oy = dy + 2.0 * c * m[k, 1]
            oz = dz + 2.0 * c * m[k, 2]
            if oz <= 0.0:
                continue
            a_o = _grid_value(area, theta_max, ox, oy, oz)
            fr = 1.0 if eta <= 0.0 else _fresnel(min(c, 1.0), eta)
            num += wk * fr * oz / (oz + a_o)
        out[j] = num / den if den > 0.0 else 0.0


@njit(cache=True, parallel=True)
def _energies(m, w, wis, area, bounce, theta_max, bounce_theta_max, eta, n_t, n_p, out, weights):
    """Per incident direction: single-scattering albedo, the second bounce, and the albedo's weights.

    ``out[j] = (E_ss, E_2)`` for the single-scattering microfacet BRDF with height-correlated
    Smith masking and the expected second bounce of the light it blocks (``bounce``, indexed
    by the blocked ray's travel direction over the whole sphere); ``weights[j]`` (over the
    cells of an (n_t, n_p) direction table up to ``theta_max``, flattened) is such that
    ``weights[j] @ factor.ravel()`` is ``integral f_ss(wi, wo) factor(wo) cos d omega_o`` for
    any such table ``factor`` looked up bilinearly: one pass serves every factor the
    multiple-scattering iteration tries.
    """
    for j in prange(wis.shape[0]):
        ix, iy, iz = wis[j, 0], wis[j, 1], wis[j, 2]
        a_i = _grid_value(area, theta_max, ix, iy, iz)
        norm = iz + a_i  # cos(theta_i) (1 + Lambda_i): the visible projected area
        e_ss = 0.0
        e_2 = 0.0
        row = weights[j]
        row[:] = 0.0
        if norm > 0.0:
            for k in range(m.shape[0]):
                c = ix * m[k, 0] + iy * m[k, 1] + iz * m[k, 2]
                if c <= 0.0:
                    continue
                vis = w[k] * c / m[k, 2] / norm
                fr = 1.0 if eta <= 0.0 else _fresnel(min(c, 1.0), eta)
                ox = 2.0 * c * m[k, 0] - ix
                oy = 2.0 * c * m[k, 1] - iy
                oz = 2.0 * c * m[k, 2] - iz
                escape = 0.0
                if oz > 0.0:
                    theta = math.acos(min(oz, 1.0))
                    phi = math.atan2(oy, ox)
                    if phi < 0.0:
                        phi += 2.0 * math.pi
                    a_o = _grid_at(area, theta_max, theta, phi)
                    escape = _g2_over_g1(iz, a_i, oz, a_o)
                    share = vis * fr * escape
                    e_ss += share
                    i0, j0, j1, at, ap = _grid_cell(n_t, n_p, theta_max, theta, phi)
                    row[i0 * n_p + j0] += share * (1.0 - at) * (1.0 - ap)
                    row[i0 * n_p + j1] += share * (1.0 - at) * ap
                    row[(i0 + 1) * n_p + j0] += share * at * (1.0 - ap)
                    row[(i0 + 1) * n_p + j1] += share * at * ap
                if escape < 1.0:
                    e_2 += vis * fr * (1.0 - escape) * _grid_value(bounce, bounce_theta_max, ox, oy, oz)
        out[j, 0] = e_ss
        out[j, 1] = e_2


@njit(cache=True)
def _deposit(mx, my, extent, n, grid):
    """Cloud in cell: each normal's unit weight shared bilinearly by its 4 nodes (n x n over [-e, e]^2)."""
    step = 2.0 * extent / (n - 1)
    for k in range(mx.shape[0]):
        fx = (mx[k] + extent) / step
        fy = (my[k] + extent) / step
        i0 = min(max(int(math.floor(fx)), 0), n - 2)
        j0 = min(max(int(math.floor(fy)), 0), n - 2)
        ax = min(max(fx - i0, 0.0), 1.0)
        ay = min(max(fy - j0, 0.0), 1.0)
        grid[j0, i0] += (1.0 - ax) * (1.0 - ay)
        grid[j0, i0 + 1] += ax * (1.0 - ay)
        grid[j0 + 1, i0] += (1.0 - ax) * ay
        grid[j0 + 1, i0 + 1] += ax * ay


@njit(cache=True, parallel=True)
def _facet_bins(density, extent, sub, wis, area, factor, theta_max, eta, n_theta, n_phi, out):
    """Bin sums ``integral_bin f_s cos d omega_o`` of the tabulated surface term, by its facets.

    Every cell of the NDF table is cut into ``sub x sub`` points, ``D`` bilinear there;
    a point's mass ``D dm_x dm_y`` reflects ``wi`` into ``o = 2 (wi . m) m - wi`` and
    carries ``F G2 (wi . m) / (cos_i m_z) k(i) k(o)`` of it (Walter et al. 2007, eqs. 38-41).
    ``out`` is ``(n_in, n_theta * n_phi)``; uniform bins over [0, pi / 2] x [0, 2 pi).
    """
    n = density.shape[0]
    step = 2.0 * extent / (n - 1)
    h = step / sub
    for j in prange(wis.shape[0]):
        ix, iy, iz = wis[j, 0], wis[j, 1], wis[j, 2]
        a_i = _grid_value(area, theta_max, ix, iy, iz)
        k_i = _grid_value(factor, theta_max, ix, iy, iz)
        for r in range(n - 1):
            for c in range(n - 1):
                d00 = density[r, c]
                d10 = density[r, c + 1]
                d01 = density[r + 1, c]
                d11 = density[r + 1, c + 1]
                if d00 == 0.0 and d10 == 0.0 and d01 == 0.0 and d11 == 0.0:
                    continue
                for a in range(sub):
                    fy = (a + 0.5) / sub
                    my = -extent + (r + fy) * step
                    for b in range(sub):
                        fx = (b + 0.5) / sub
                        mx = -extent + (c + fx) * step
                        s2 = mx * mx + my * my
                        if s2 >= 1.0:
                            continue
                        dens = (1.0 - fy) * ((1.0 - fx) * d00 + fx * d10) + fy * ((1.0 - fx) * d01 + fx * d11)
                        if dens <= 0.0:
                            continue
                        mz = math.sqrt(1.0 - s2)
                        cm = ix * mx + iy * my + iz * mz
                        if cm <= 0.0:
                            continue
                        ox = 2.0 * cm * mx - ix
                        oy = 2.0 * cm * my - iy
                        oz = 2.0 * cm * mz - iz
                        if oz <= 0.0:
                            continue
                        theta = math.acos(min(oz, 1.0))
                        phi = math.atan2(oy, ox)
                        if phi < 0.0:
                            phi += 2.0 * math.pi
                        a_o = _grid_at(area, theta_max, theta, phi)
                        k_o = _grid_at(factor, theta_max, theta, phi)
                        fr = 1.0 if eta <= 0.0 else _fresnel(min(cm, 1.0), eta)
                        # G2 / cos_i, finite at grazing.
                        g2_ci = oz / (iz * oz + a_i * oz + a_o * iz)
                        value = dens * h * h * fr * g2_ci * cm / mz * k_i * k_o
                        it = min(int(theta / theta_max * n_theta), n_theta - 1)
                        ip = min(int(phi / (2.0 * math.pi) * n_phi), n_phi - 1)
                        out[j, it * n_phi + ip] += value
