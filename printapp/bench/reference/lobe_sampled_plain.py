"""The importance-sampled bin averages of one microfacet lobe, in plain numpy: the reference that
``render.brdf_model``'s numba kernel is checked against (it was the production code before it;
it shares the numpy Smith Lambda and the stratified slopes, which the kernel does not use).

Walter et al. 2007, eqs. 38-41: facet slopes drawn stratified from the lobe's slope
distribution, ``wi`` reflected off each facet, weight ``F G2 (wi . m) / (cos(theta_i) cos(theta_m))``.
"""

import math

import numpy as np

from render.brdf_model import smith_lambda, standard_slopes
from render.fresnel import fresnel_dielectric
from render.gonio import projected_solid_angle


def lobe_sampled_plain(distribution, au, av, azimuth, ior, wis, theta_edges, phi_edges, n_side):
    """``(n_in, n_theta, n_phi)`` bin averages (1/sr) of one lobe, for each incident direction."""
    sx0, sy0 = standard_slopes(distribution, n_side)
    c, s = math.cos(azimuth), math.sin(azimuth)
    su, sv = au * sx0, av * sy0
    sx, sy = su * c - sv * s, su * s + sv * c
    inv = 1.0 / np.sqrt(1.0 + sx * sx + sy * sy)
    m = np.stack([-sx * inv, -sy * inv, inv], axis=-1)
    n_t, n_p = len(theta_edges) - 1, len(phi_edges) - 1
    omega = projected_solid_angle(theta_edges, phi_edges)
    out = np.zeros((wis.shape[0], n_t, n_p))

    def local(w):
        return w[..., 0] * c + w[..., 1] * s, -w[..., 0] * s + w[..., 1] * c, w[..., 2]

    for k, w in enumerate(wis):
        wm = m @ w
        o = 2.0 * wm[:, None] * m - w[None, :]
        ok = (wm > 0.0) & (o[:, 2] > 0.0)
        o, wm_ok, mz = o[ok], wm[ok], m[ok, 2]
        g2 = 1.0 / (
            1.0
            + smith_lambda(distribution, *local(w[None, :]), au, av)
            + smith_lambda(distribution, *local(o), au, av)
        )
        weight = fresnel_dielectric(wm_ok, ior) * g2 * wm_ok / (w[2] * mz) / sx0.size
        theta = np.arccos(np.clip(o[:, 2], -1.0, 1.0))
        phi = np.arctan2(o[:, 1], o[:, 0]) % (2.0 * math.pi)
        it = np.minimum((theta / (theta_edges[-1] - theta_edges[0]) * n_t).astype(np.int64), n_t - 1)
        ip = np.minimum((phi / (2.0 * math.pi) * n_p).astype(np.int64), n_p - 1)
        out[k] = np.bincount(it * n_p + ip, weights=weight, minlength=n_t * n_p).reshape(n_t, n_p) / omega
    return out
