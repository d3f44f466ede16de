"""A compact BRDF for printed resin: anisotropic microfacet reflection over a Lambertian body.

Surface reflection is the microfacet model of Walter et al. (2007), "Microfacet models
for refraction through rough surfaces", with the anisotropic GGX or Beckmann normal
distribution and the height-correlated Smith masking-shadowing of Heitz (2014),
"Understanding the masking-shadowing function in microfacet-based BRDFs" (eqs. 85-86
for GGX's and Beckmann's Lambda, eq. 99 for G2):

    f_s = F(wi . h) D(h) G2(wi, wo) / (4 cos(theta_i) cos(theta_o)),

with the dielectric Fresnel factor at the resin's index. In the frame of the
anisotropy (x' along ``azimuth_rad``), for a microfacet normal m:

    GGX:      D(m) = 1 / (pi a_u a_v (m_x'^2/a_u^2 + m_y'^2/a_v^2 + m_z^2)^2)
    Beckmann: D(m) = exp(-(m_x'^2/a_u^2 + m_y'^2/a_v^2) / m_z^2) / (pi a_u a_v m_z^4).

The body is the resin's pigment seen through the smooth interface (as in
:mod:`render.gonio` and Mitsuba's ``plastic``):

    f_b = rho (1 - F(theta_i)) (1 - F(theta_o)) / (pi n^2 (1 - rho F_dr,int)).

Printed reliefs are often two-scale: the flat tops of the printer's layers are
mirrors, the steps between them scatter broadly. So the model may carry a second,
isotropic and sharp lobe (``spike_weight`` of the surface reflection, roughness
``spike_alpha``): ``f_s = (1 - w) f_s(alpha_u, alpha_v) + w f_s(spike_alpha)``. The fit
adds it only where it explains the table markedly better.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np
from numba import njit, prange
from scipy.special import erf

from render.fresnel import _fresnel, diffuse_fresnel_reflectance, fresnel_dielectric

DISTRIBUTIONS = ("ggx", "beckmann")


@dataclass(frozen=True)
class MicrofacetBRDF:
    """Parameters of the compact model.

    Attributes
    ----------
    distribution : {"ggx", "beckmann"}
    alpha_u, alpha_v : float
        Roughness along ``azimuth_rad`` and across it (dimensionless; for Beckmann,
        sqrt(2) times the RMS slope).
    azimuth_rad : float
        Direction of ``alpha_u`` in the surface plane, from +x towards +y, in [0, pi).
    body_albedo : float
        Albedo of the diffuse body under the interface.
    ior : float
        Refractive index of the resin.
    spike_weight, spike_alpha : float
        Share of the surface reflection in a second, sharp isotropic lobe, and its
        roughness (0 when there is none).
    """

    distribution: str
    alpha_u: float
    alpha_v: float
    azimuth_rad: float
    body_albedo: float
    ior: float
    spike_weight: float = 0.0
    spike_alpha: float = 0.0

    def as_dict(self) -> dict[str, float | str]:
        d = asdict(self)
        d["azimuth_deg"] = math.degrees(d.pop("azimuth_rad"))
        return d


def _to_local(w: np.ndarray, azimuth_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c, s = math.cos(azimuth_rad), math.sin(azimuth_rad)
    return w[..., 0] * c + w[..., 1] * s, -w[..., 0] * s + w[..., 1] * c, w[..., 2]


def _ndf(distribution: str, mx, my, mz, au: float, av: float) -> np.ndarray:
    if distribution == "ggx":
        q = mx * mx / (au * au) + my * my / (av * av) + mz * mz
        return 1.0 / (math.pi * au * av * q * q)
    mz2 = np.maximum(mz * mz, 1e-300)
    return np.exp(-(mx * mx / (au * au) + my * my / (av * av)) / mz2) / (math.pi * au * av * mz2 * mz2)


def smith_lambda(distribution: str, wx, wy, wz, au: float, av: float) -> np.ndarray:
    """Smith's Lambda of direction ``(wx, wy, wz)`` (local frame) for an anisotropic GGX or Beckmann
    distribution (Heitz 2014, "Understanding the masking-shadowing function"; Beckmann: eq. 86);
    ``G1 = 1 / (1 + Lambda)``."""
    proj = np.sqrt(au * au * wx * wx + av * av * wy * wy)
    wz = np.maximum(wz, 1e-12)
    if distribution == "ggx":
        return 0.5 * (np.sqrt(1.0 + (proj / wz) ** 2) - 1.0)
    a = wz / np.maximum(proj, 1e-300)
    # Heitz 2014 eq. 86; exact for the Beckmann distribution, a -> inf gives 0.
    with np.errstate(over="ignore", invalid="ignore"):
        lam = 0.5 * (erf(a) - 1.0) + np.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))
    return np.where(a > 26.0, 0.0, lam)


def _lobe(distribution: str, au: float, av: float, azimuth: float, ior: float, wi, wo) -> np.ndarray:
    """One microfacet lobe's BRDF (1/sr), zero outside the upper hemisphere."""
    cos_i = wi[..., 2]
    cos_o = wo[..., 2]
    hv = wi + wo
    hv = hv / np.maximum(np.linalg.norm(hv, axis=-1, keepdims=True), 1e-300)
    hx, hy, hz = _to_local(hv, azimuth)
    ix, iy, iz = _to_local(wi, azimuth)
    ox, oy, oz = _to_local(wo, azimuth)
    d = _ndf(distribution, hx, hy, hz, au, av)
    g2 = 1.0 / (
        1.0 + smith_lambda(distribution, ix, iy, iz, au, av) + smith_lambda(distribution, ox, oy, oz, au, av)
    )
    f_h = fresnel_dielectric(np.sum(wi * hv, axis=-1), ior)
    valid = (cos_i > 0.0) & (cos_o > 0.0) & (hz > 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.where(valid, f_h * d * g2 / (4.0 * cos_i * cos_o), 0.0)


def _body(model: MicrofacetBRDF, cos_i, cos_o) -> np.ndarray:
    rho, n = model.body_albedo, model.ior
    factor = rho / (math.pi * n * n * (1.0 - rho * diffuse_fresnel_reflectance(1.0 / n)))
    value = factor * (1.0 - fresnel_dielectric(cos_i, n)) * (1.0 - fresnel_dielectric(cos_o, n))
    return np.where((cos_i > 0.0) & (cos_o > 0.0), value, 0.0)


def evaluate(
    model: MicrofacetBRDF, wi: np.ndarray, wo: np.ndarray, *, specular_only: bool = False
) -> np.ndarray:
    """The model's BRDF (1/sr) for directions ``wi`` and ``wo`` (unit, broadcastable, ``(..., 3)``)."""
    if model.distribution not in DISTRIBUTIONS:
        raise ValueError(
            f"distribution: expected one of {', '.join(DISTRIBUTIONS)}, got {model.distribution!r}"
        )
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    w = model.spike_weight
    f = (1.0 - w) * _lobe(
        model.distribution, model.alpha_u, model.alpha_v, model.azimuth_rad, model.ior, wi, wo
    )
    if w > 0.0:
        f = f + w * _lobe(model.distribution, model.spike_alpha, model.spike_alpha, 0.0, model.ior, wi, wo)
    if specular_only or model.body_albedo <= 0.0:
        return f
    return f + _body(model, wi[..., 2], wo[..., 2])


def bin_directions(theta_edges: np.ndarray, phi_edges: np.ndarray, sub: int = 4) -> np.ndarray:
    """Sub-sample directions in each bin, equally spaced in sin^2(theta) and phi.

    Equal steps in ``sin^2 theta`` carry equal projected solid angle, so the plain mean
    of a function over the sub-samples of a bin is its cosine-weighted bin average
    (midpoint rule). Returns ``(n_theta, n_phi, sub * sub, 3)``.
    """
    s2 = np.sin(np.asarray(theta_edges)) ** 2
    frac = (np.arange(sub) + 0.5) / sub
    s2_sub = s2[:-1, None] + np.diff(s2)[:, None] * frac[None, :]  # (n_theta, sub)
    phi = np.asarray(phi_edges)
    phi_sub = phi[:-1, None] + np.diff(phi)[:, None] * frac[None, :]  # (n_phi, sub)
    sin_t = np.sqrt(s2_sub)
    cos_t = np.sqrt(np.clip(1.0 - s2_sub, 0.0, None))
    x = sin_t[:, None, :, None] * np.cos(phi_sub)[None, :, None, :]
    y = sin_t[:, None, :, None] * np.sin(phi_sub)[None, :, None, :]
    z = np.broadcast_to(cos_t[:, None, :, None], x.shape)
    nt, npf = len(theta_edges) - 1, len(phi_edges) - 1
    return np.stack([x, y, z], axis=-1).reshape(nt, npf, sub * sub, 3)


def bin_average(
    model: MicrofacetBRDF,
    wi: np.ndarray,
    theta_edges: np.ndarray,
    phi_edges: np.ndarray,
    *,
    sub: int = 4,
    specular_only: bool = False,
) -> np.ndarray:
    """The model averaged over each outgoing bin, cosine-weighted: ``(n_in, n_theta, n_phi)``.

    This is what the gonioreflectometer's table estimates, so the two compare bin by bin.
    """
    dirs = bin_directions(theta_edges, phi_edges, sub)
    wis = np.atleast_2d(wi)
    out = np.empty((wis.shape[0], dirs.shape[0], dirs.shape[1]))
    for k, w in enumerate(wis):
        out[k] = evaluate(model, w[None, None, None, :], dirs, specular_only=specular_only).mean(axis=-1)
    return out


def standard_slopes(distribution: str, n_side: int) -> tuple[np.ndarray, np.ndarray]:
    """Stratified slopes of the distribution with alpha = 1 (projected-area density P22)."""
    from scipy.special import ndtri

    u = (np.arange(n_side) + 0.5) / n_side
    u1, u2 = np.meshgrid(u, u, indexing="ij")
    if distribution == "beckmann":
        # Independent Gaussian slopes of variance 1/2 along each axis.
        return ndtri(u1.ravel()) / math.sqrt(2.0), ndtri(u2.ravel()) / math.sqrt(2.0)
    # GGX: radial CDF r^2 / (1 + r^2) = u.
    r = np.sqrt(u1 / (1.0 - u1)).ravel()
    phi = 2.0 * math.pi * u2.ravel()
    return r * np.cos(phi), r * np.sin(phi)


@functools.lru_cache(maxsize=8)
def _standard_slopes_cached(distribution: str, n_side: int) -> tuple[np.ndarray, np.ndarray]:
    return standard_slopes(distribution, n_side)


@njit(cache=True, inline="always")
def _smith_lambda_one(ggx: bool, wx: float, wy: float, wz: float, au: float, av: float) -> float:
    proj = math.sqrt(au * au * wx * wx + av * av * wy * wy)
    wz = max(wz, 1e-12)
    if ggx:
        return 0.5 * (math.sqrt(1.0 + (proj / wz) ** 2) - 1.0)
    a = wz / max(proj, 1e-300)
    if a > 26.0:
        return 0.0
    return 0.5 * (math.erf(a) - 1.0) + math.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))


@njit(cache=True, nogil=True)  # (on the background thread: the main one goes on meanwhile)
def _lobe_row_means(ggx, au, av, azimuth, ior, wis, wi_of_row, dirs, out) -> None:
    """``out[r]``: the mean of :func:`_lobe` from ``wis[wi_of_row[r]]`` over the directions ``dirs[r]``.

    The same arithmetic as the numpy :func:`_lobe`, one direction at a time, without its
    dozen temporaries: the analytic fit evaluates it some 600 times (tests/test_brdf.py holds
    the two equal).
    """
    c, s = math.cos(azimuth), math.sin(azimuth)
    inv_pi_a = 1.0 / (math.pi * au * av)
    for r in range(dirs.shape[0]):
        k = wi_of_row[r]
        wx, wy, wz = wis[k, 0], wis[k, 1], wis[k, 2]
        total = 0.0
        if wz > 0.0:
            lam_i = _smith_lambda_one(ggx, wx * c + wy * s, -wx * s + wy * c, wz, au, av)
            for j in range(dirs.shape[1]):
                ox, oy, oz = dirs[r, j, 0], dirs[r, j, 1], dirs[r, j, 2]
                if oz <= 0.0:
                    continue
                hx, hy, hz = wx + ox, wy + oy, wz + oz
                norm = max(math.sqrt(hx * hx + hy * hy + hz * hz), 1e-300)
                hx, hy, hz = hx / norm, hy / norm, hz / norm
                if hz <= 0.0:
                    continue
                mx, my = hx * c + hy * s, -hx * s + hy * c
                if ggx:
                    q = mx * mx / (au * au) + my * my / (av * av) + hz * hz
                    d = inv_pi_a / (q * q)
                else:
                    mz2 = max(hz * hz, 1e-300)
                    d = math.exp(-(mx * mx / (au * au) + my * my / (av * av)) / mz2) * inv_pi_a / (mz2 * mz2)
                lam_o = _smith_lambda_one(ggx, ox * c + oy * s, -ox * s + oy * c, oz, au, av)
                f_h = _fresnel(wx * hx + wy * hy + wz * hz, ior)
                total += f_h * d / (1.0 + lam_i + lam_o) / (4.0 * wz * oz)
        out[r] = total / dirs.shape[1]


def lobe_row_means(
    distribution: str,
    au: float,
    av: float,
    azimuth: float,
    ior: float,
    wis: np.ndarray,
    wi_of_row: np.ndarray,
    dirs: np.ndarray,
) -> np.ndarray:
    """One microfacet lobe (1/sr) averaged over each row's directions: ``(n_rows,)``.

    ``wis`` ``(n_in, 3)`` are incident directions, ``wi_of_row`` ``(n_rows,)`` picks row r's, and
    ``dirs`` ``(n_rows, m, 3)`` are its outgoing directions (unit, upper hemisphere). Equal to
    ``_lobe(distribution, au, av, azimuth, ior, wis[wi_of_row][:, None], dirs).mean(-1)``, the
    microfacet lobe of Walter et al. (2007) with Heitz's (2014) height-correlated Smith G2.
    """
    out = np.empty(len(dirs))
    _lobe_row_means(
        distribution == "ggx",
        float(au),
        float(av),
        float(azimuth),
        float(ior),
        np.ascontiguousarray(wis, dtype=np.float64),
        np.ascontiguousarray(wi_of_row, dtype=np.int64),
        np.ascontiguousarray(dirs, dtype=np.float64),
        out,
    )
    return out


@njit(cache=True, parallel=True, nogil=True)
def _lobe_sampled_sums(ggx, au, av, azimuth, ior, wis, sx0, sy0, theta_range, out) -> None:
    """Sum each facet sample's weight into its outgoing bin, per incident direction (see below)."""
    n_in, n_t, n_p = out.shape
    c, s = math.cos(azimuth), math.sin(azimuth)
    inv_n = 1.0 / sx0.size
    two_pi = 2.0 * math.pi
    for k in prange(n_in):  # each incident direction has its own slice of out
        wx, wy, wz = wis[k, 0], wis[k, 1], wis[k, 2]
        lam_i = _smith_lambda_one(ggx, wx * c + wy * s, -wx * s + wy * c, wz, au, av)
        for j in range(sx0.size):
            su, sv = au * sx0[j], av * sy0[j]
            sx, sy = su * c - sv * s, su * s + sv * c
            inv = 1.0 / math.sqrt(1.0 + sx * sx + sy * sy)
            mx, my, mz = -sx * inv, -sy * inv, inv
            wm = mx * wx + my * wy + mz * wz
            if wm <= 0.0:
                continue
            ox, oy, oz = 2.0 * wm * mx - wx, 2.0 * wm * my - wy, 2.0 * wm * mz - wz
            if oz <= 0.0:
                continue
            lam_o = _smith_lambda_one(ggx, ox * c + oy * s, -ox * s + oy * c, oz, au, av)
            weight = _fresnel(wm, ior) / (1.0 + lam_i + lam_o) * wm / (wz * mz) * inv_n
            theta = math.acos(min(max(oz, -1.0), 1.0))
            phi = math.atan2(oy, ox) % two_pi
            it = min(int(theta / theta_range * n_t), n_t - 1)
            ip = min(int(phi / two_pi * n_p), n_p - 1)
            out[k, it, ip] += weight


def _lobe_sampled(
    distribution: str,
    au: float,
    av: float,
    azimuth: float,
    ior: float,
    wis: np.ndarray,
    theta_edges: np.ndarray,
    phi_edges: np.ndarray,
    n_side: int,
) -> np.ndarray:
    """One lobe's bin averages by importance sampling it (see :func:`sampled_bin_average`).

    A numba kernel over the samples, checked against the plain numpy version it replaced
    (``printapp.bench.reference.lobe_sampled_plain``): 2.5x faster on one core, and the incident
    directions run in parallel; it was most of the analytic fit's time.
    """
    from render.gonio import projected_solid_angle

    sx0, sy0 = _standard_slopes_cached(distribution, n_side)
    out = np.zeros((np.shape(wis)[0], len(theta_edges) - 1, len(phi_edges) - 1))
    _lobe_sampled_sums(
        distribution == "ggx",
        float(au),
        float(av),
        float(azimuth),
        float(ior),
        np.ascontiguousarray(wis, dtype=np.float64),
        sx0,
        sy0,
        float(theta_edges[-1] - theta_edges[0]),
        out,
    )
    return out / projected_solid_angle(theta_edges, phi_edges)


def sampled_bin_average(
    model: MicrofacetBRDF, wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray, n_side: int = 512
) -> np.ndarray:
    """Bin averages of the model by importance sampling its lobes: right for lobes of any width.

    Facet slopes are drawn (stratified) from each lobe's slope distribution, so facet
    normals m have density ``D(m) cos(theta_m)``; reflecting ``wi`` off m gives the
    estimator ``F G2 (wi . m) / (cos(theta_i) cos(theta_m))`` of ``integral_bin f_s
    cos(theta_o) d omega_o`` (Walter et al. 2007, eqs. 38-41). The body term is smooth
    and is taken at the bin centres. Returns ``(n_in, n_theta, n_phi)`` (1/sr).
    """
    wis = np.atleast_2d(wi)
    w = model.spike_weight
    args = (model.ior, wis, theta_edges, phi_edges, n_side)
    out = (1.0 - w) * _lobe_sampled(
        model.distribution, model.alpha_u, model.alpha_v, model.azimuth_rad, *args
    )
    if w > 0.0:
        out += w * _lobe_sampled(model.distribution, model.spike_alpha, model.spike_alpha, 0.0, *args)
    if model.body_albedo > 0.0:
        rho = model.body_albedo
        f_int = diffuse_fresnel_reflectance(1.0 / model.ior)
        out += rho / (1.0 - rho * f_int) * _body_shape(wis, theta_edges, phi_edges, model.ior)
    return out


def _body_shape(wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray, ior: float) -> np.ndarray:
    """``(1 - F_i)(1 - F_o) / (pi n^2)`` at the bin centres (smooth, so centres suffice)."""
    t = 0.5 * (np.asarray(theta_edges)[:-1] + np.asarray(theta_edges)[1:])
    fo = 1.0 - fresnel_dielectric(np.cos(t), ior)
    fi = 1.0 - fresnel_dielectric(np.atleast_2d(wi)[:, 2], ior)
    return (fi[:, None, None] * fo[None, :, None] / (math.pi * ior * ior)) * np.ones(
        (1, 1, len(phi_edges) - 1)
    )


def model_bins(
    model: MicrofacetBRDF, wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray
) -> np.ndarray:
    """The model's bin averages, accurate for lobes of any width.

    Lobes wider than half a bin are averaged over sub-samples of every bin (exact
    up to the midpoint rule); narrower ones are importance sampled.
    """
    wis = np.atleast_2d(wi)
    width = float(theta_edges[1] - theta_edges[0])
    lobes = [(1.0 - model.spike_weight, model.alpha_u, model.alpha_v, model.azimuth_rad)]
    if model.spike_weight > 0.0:
        lobes.append((model.spike_weight, model.spike_alpha, model.spike_alpha, 0.0))
    out = np.zeros((wis.shape[0], len(theta_edges) - 1, len(phi_edges) - 1))
    for weight, au, av, az in lobes:
        one = MicrofacetBRDF(model.distribution, au, av, az, 0.0, model.ior)
        if min(au, av) >= 0.5 * width:
            sub = int(min(max(math.ceil(2.5 * width / min(au, av)), 2), 5))
            out += weight * bin_average(one, wis, theta_edges, phi_edges, sub=sub, specular_only=True)
        else:
            out += weight * sampled_bin_average(one, wis, theta_edges, phi_edges)
    if model.body_albedo > 0.0:
        rho = model.body_albedo
        f_int = diffuse_fresnel_reflectance(1.0 / model.ior)
        out += rho / (1.0 - rho * f_int) * _body_shape(wis, theta_edges, phi_edges, model.ior)
    return out
