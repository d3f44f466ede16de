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

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.special import erf

from render.fresnel import diffuse_fresnel_reflectance, fresnel_dielectric

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


def _smith_lambda(distribution: str, wx, wy, wz, au: float, av: float) -> np.ndarray:
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
        1.0
        + _smith_lambda(distribution, ix, iy, iz, au, av)
        + _smith_lambda(distribution, ox, oy, oz, au, av)
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


def _standard_slopes(distribution: str, n_side: int) -> tuple[np.ndarray, np.ndarray]:
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
    """One lobe's bin averages by importance sampling it (see :func:`sampled_bin_average`)."""
    from render.gonio import projected_solid_angle

    sx0, sy0 = _standard_slopes(distribution, n_side)
    c, s = math.cos(azimuth), math.sin(azimuth)
    su, sv = au * sx0, av * sy0
    sx, sy = su * c - sv * s, su * s + sv * c
    inv = 1.0 / np.sqrt(1.0 + sx * sx + sy * sy)
    m = np.stack([-sx * inv, -sy * inv, inv], axis=-1)
    n_t, n_p = len(theta_edges) - 1, len(phi_edges) - 1
    omega = projected_solid_angle(theta_edges, phi_edges)
    out = np.zeros((wis.shape[0], n_t, n_p))
    for k, w in enumerate(wis):
        wm = m @ w
        o = 2.0 * wm[:, None] * m - w[None, :]
        ok = (wm > 0.0) & (o[:, 2] > 0.0)
        o, wm_ok, mz = o[ok], wm[ok], m[ok, 2]
        ix, iy, iz = _to_local(w[None, :], azimuth)
        ox, oy, oz = _to_local(o, azimuth)
        g2 = 1.0 / (
            1.0
            + _smith_lambda(distribution, ix, iy, iz, au, av)
            + _smith_lambda(distribution, ox, oy, oz, au, av)
        )
        weight = fresnel_dielectric(wm_ok, ior) * g2 * wm_ok / (w[2] * mz) / sx0.size
        theta = np.arccos(np.clip(o[:, 2], -1.0, 1.0))
        phi = np.arctan2(o[:, 1], o[:, 0]) % (2.0 * math.pi)
        it = np.minimum((theta / (theta_edges[-1] - theta_edges[0]) * n_t).astype(np.int64), n_t - 1)
        ip = np.minimum((phi / (2.0 * math.pi) * n_p).astype(np.int64), n_p - 1)
        out[k] = np.bincount(it * n_p + ip, weights=weight, minlength=n_t * n_p).reshape(n_t, n_p) / omega
    return out


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


@dataclass(frozen=True)
class FitResult:
    """A fitted compact model and how well it matches the table."""

    model: MicrofacetBRDF
    relative_error: float
    """Energy-weighted RMS relative error over the bins that carry energy (noise removed)."""
    bins_used: int
    table_noise: float = math.nan
    """The table's own RMS relative noise over the same bins: errors below it cannot be seen."""


def _sub_directions(theta_edges, phi_edges, it: np.ndarray, ip: np.ndarray, sub: int) -> np.ndarray:
    """Sub-sample directions of the bins ``(it, ip)``, as :func:`bin_directions` does: ``(n, sub^2, 3)``."""
    s2 = np.sin(np.asarray(theta_edges)) ** 2
    phi = np.asarray(phi_edges)
    frac = (np.arange(sub) + 0.5) / sub
    s2_sub = s2[it, None] + (s2[it + 1] - s2[it])[:, None] * frac[None, :]
    phi_sub = phi[ip, None] + (phi[ip + 1] - phi[ip])[:, None] * frac[None, :]
    sin_t = np.sqrt(s2_sub)[:, :, None]
    cos_t = np.sqrt(np.clip(1.0 - s2_sub, 0.0, None))[:, :, None]
    x = sin_t * np.cos(phi_sub)[:, None, :]
    y = sin_t * np.sin(phi_sub)[:, None, :]
    z = np.broadcast_to(cos_t, x.shape)
    return np.stack([x, y, z], axis=-1).reshape(len(it), sub * sub, 3)


def relative_error(
    f_model: np.ndarray,
    f_table: np.ndarray,
    omega: np.ndarray,
    stderr: np.ndarray | None = None,
    floor: float = 1e-4,
) -> tuple[float, int]:
    """Energy-weighted RMS relative difference over the bins that carry energy.

    ``sqrt(sum_b E_b ((f_model - f_table)^2 - stderr^2) / f_table^2 / sum_b E_b)``
    with ``E_b = f_table * omega_b``, over bins holding at least ``floor`` of the
    reflected energy of their incident direction. With ``stderr``, only bins measured
    to 25 % or better count, and their variance is taken off, so that the figure is the
    model's error and not the estimator's noise (NaN when no bin is measured well enough:
    too few rays).
    """
    energy = f_table * omega
    total = energy.sum(axis=(-2, -1), keepdims=True)
    mask = energy > floor * np.maximum(total, 1e-300)
    if stderr is not None:
        mask &= stderr <= 0.25 * f_table
    if not np.any(mask):
        return math.nan, 0
    diff2 = (f_model[mask] - f_table[mask]) ** 2
    if stderr is not None:
        diff2 = diff2 - stderr[mask] ** 2
    e = energy[mask]
    value = np.sum(e * diff2 / f_table[mask] ** 2) / np.sum(e)
    return float(math.sqrt(max(value, 0.0))), int(mask.sum())


def table_noise(f_table: np.ndarray, omega: np.ndarray, stderr: np.ndarray, floor: float = 1e-4) -> float:
    """Energy-weighted RMS relative standard error of the bins :func:`relative_error` uses."""
    energy = f_table * omega
    total = energy.sum(axis=(-2, -1), keepdims=True)
    mask = (energy > floor * np.maximum(total, 1e-300)) & (stderr <= 0.25 * f_table)
    if not np.any(mask):
        return math.nan
    e = energy[mask]
    return float(math.sqrt(np.sum(e * (stderr[mask] / f_table[mask]) ** 2) / np.sum(e)))


def _relative_error_merged(
    f_model: np.ndarray, f_table: np.ndarray, omega: np.ndarray, stderr: np.ndarray | None, merged: np.ndarray
) -> tuple[float, int]:
    """:func:`relative_error` with the bins in ``merged`` pooled into one bin per incident direction."""
    n_in = f_table.shape[0]
    e_model = f_model * omega
    e_table = f_table * omega
    var = (stderr * omega) ** 2 if stderr is not None else np.zeros_like(e_table)
    pooled_m = np.where(merged, e_model, 0.0).sum(axis=(1, 2))
    pooled_t = np.where(merged, e_table, 0.0).sum(axis=(1, 2))
    pooled_v = np.where(merged, var, 0.0).sum(axis=(1, 2))
    rest = ~merged
    em = np.concatenate([pooled_m, e_model[rest]])
    et = np.concatenate([pooled_t, e_table[rest]])
    ev = np.concatenate([pooled_v, var[rest]])
    rows = np.concatenate([np.arange(n_in), np.nonzero(rest)[0]])
    total = np.bincount(rows, weights=et, minlength=n_in)
    mask = (et > 1e-4 * np.maximum(total[rows], 1e-300)) & (ev <= (0.25 * et) ** 2)
    if not np.any(mask):
        return math.nan, 0
    diff2 = (em[mask] - et[mask]) ** 2 - ev[mask]
    value = np.sum(diff2 / et[mask]) / np.sum(et[mask])
    return float(math.sqrt(max(value, 0.0))), int(mask.sum())


def _body_shape(wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray, ior: float) -> np.ndarray:
    """``(1 - F_i)(1 - F_o) / (pi n^2)`` at the bin centres (smooth, so centres suffice)."""
    t = 0.5 * (np.asarray(theta_edges)[:-1] + np.asarray(theta_edges)[1:])
    fo = 1.0 - fresnel_dielectric(np.cos(t), ior)
    fi = 1.0 - fresnel_dielectric(np.atleast_2d(wi)[:, 2], ior)
    return (fi[:, None, None] * fo[None, :, None] / (math.pi * ior * ior)) * np.ones(
        (1, 1, len(phi_edges) - 1)
    )


def lobe_alpha(
    f_specular: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray
) -> tuple[float, float, float]:
    """Beckmann roughness ``(alpha_u, alpha_v, azimuth_rad)`` from the lobe's moments at normal incidence.

    Reflection at normal incidence off a facet of slope s leaves at ``sin(theta) ~ 2|s|``,
    so the lobe's covariance on the unit disk is about four times the slope covariance,
    ``alpha^2 / 2`` per principal axis for Beckmann: ``alpha = sqrt(lambda / 2)``. The
    bins' own width (uniform quantisation, variance ``width^2 / 12``) is taken off.
    """
    from render.gonio import projected_solid_angle

    e = f_specular * projected_solid_angle(theta_edges, phi_edges)
    tc = 0.5 * (theta_edges[:-1] + theta_edges[1:])
    pc = 0.5 * (phi_edges[:-1] + phi_edges[1:])
    t, p = np.meshgrid(tc, pc, indexing="ij")
    x, y = np.sin(t) * np.cos(p), np.sin(t) * np.sin(p)
    total = e.sum()
    if not total > 0:
        return 0.1, 0.1, 0.0
    mx, my = (e * x).sum() / total, (e * y).sum() / total
    cov = (
        np.array(
            [
                [(e * (x - mx) ** 2).sum(), (e * (x - mx) * (y - my)).sum()],
                [(e * (x - mx) * (y - my)).sum(), (e * (y - my) ** 2).sum()],
            ]
        )
        / total
    )
    values, vectors = np.linalg.eigh(cov)
    width = float(theta_edges[1] - theta_edges[0])
    values = np.clip(values - width * width / 12.0, (width / 4.0) ** 2, None)
    azimuth = math.atan2(vectors[1, 1], vectors[0, 1]) % math.pi
    return math.sqrt(values[1] / 2.0), math.sqrt(values[0] / 2.0), azimuth


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


def _grow(mask: np.ndarray) -> np.ndarray:
    """One bin of margin around an (n_in, n_theta, n_phi) mask; the whole polar cap where it reaches it."""
    grown = mask.copy()
    grown[:, 1:, :] |= mask[:, :-1, :]
    grown[:, :-1, :] |= mask[:, 1:, :]
    grown |= np.roll(grown, 1, axis=2) | np.roll(grown, -1, axis=2)
    # Bins around the pole are thin wedges: a lobe there spreads over the whole ring.
    at_pole = grown[:, 0, :].any(axis=1)
    grown[at_pole, :2, :] = True
    return grown


def fit_microfacet(
    wi: np.ndarray,
    f_table: np.ndarray,
    f_specular: np.ndarray,
    stderr_specular: np.ndarray,
    theta_edges: np.ndarray,
    phi_edges: np.ndarray,
    *,
    ior: float,
    distribution: str = "ggx",
    stderr: np.ndarray | None = None,
    allow_spike: bool = True,
) -> FitResult:
    """Fit the compact model to a tabulated BRDF: ``alpha_u, alpha_v, azimuth, body_albedo`` (and a spike).

    The table separates the light that only ever reflected off the surface
    (``f_specular``) from the light that went through the body, so the two parts are
    fitted separately and neither can stand in for the other:

    1. the body albedo by weighted linear least squares of ``f - f_specular`` on the
       body term's angular shape (the body term is linear in ``rho / (1 - rho F_dr,int)``);
    2. the microfacet lobe by least squares (SciPy's trust-region reflective), with
       residuals in units of the table's standard error (plus 2 % for what a
       four-parameter model cannot follow), over the bins holding the lobe, started
       from the lobe's moments (:func:`lobe_alpha`). Lobes are integrated over their
       bins with up to 8 x 8 sub-samples; a lobe narrower than half a bin cannot be
       measured by the table, and keeps its moment estimate (an upper bound);
    3. with ``allow_spike``, the same with a second, sharp lobe (the mirror-flat part
       of a terraced print, its width below the bins' resolution) and its weight; it is
       kept when it lowers the relative error by a quarter or more.

    ``distribution="auto"`` fits both distributions and keeps the one with the smaller
    error. The index is not fitted: it is the resin's.
    """
    from scipy.optimize import least_squares

    from render.gonio import projected_solid_angle

    if distribution == "auto":
        fits = [
            fit_microfacet(
                wi,
                f_table,
                f_specular,
                stderr_specular,
                theta_edges,
                phi_edges,
                ior=ior,
                distribution=d,
                stderr=stderr,
                allow_spike=allow_spike,
            )
            for d in DISTRIBUTIONS
        ]
        return min(fits, key=lambda r: (not math.isfinite(r.relative_error), r.relative_error))
    if distribution not in DISTRIBUTIONS:
        raise ValueError(
            f"distribution: expected one of {', '.join(DISTRIBUTIONS)} or 'auto', got {distribution!r}"
        )
    wis = np.atleast_2d(wi)
    omega = projected_solid_angle(theta_edges, phi_edges)
    width = float(theta_edges[1] - theta_edges[0])
    spike_alpha = 0.002  # well below any table's bins: what the table cannot resolve

    # 1. The body, in closed form.
    shape = _body_shape(wis, theta_edges, phi_edges, ior)
    diffuse = f_table - f_specular
    k = float(np.sum(omega * diffuse * shape) / max(np.sum(omega * shape * shape), 1e-300))
    f_int = diffuse_fresnel_reflectance(1.0 / ior)
    rho = min(max(k / (1.0 + k * f_int), 0.0), 1.0) if k > 0 else 0.0

    # 2. The lobe, over the bins that hold it.
    normal = int(np.argmin(1.0 - wis[:, 2]))
    energy = f_specular * omega
    total = energy.sum(axis=(-2, -1), keepdims=True)
    grown = _grow(energy > 1e-3 * np.maximum(total, 1e-300))
    kk, it, ip = np.nonzero(grown)
    target = f_specular[kk, it, ip]
    sigma = np.sqrt(stderr_specular[kk, it, ip] ** 2 + (0.02 * target) ** 2)
    sigma = np.maximum(sigma, 1e-3 * max(float(target.max()), 1e-300))
    wi_rows = wis[kk][:, None, :]
    lo = [math.log(1e-3), math.log(1e-3), -math.pi, 0.0]
    hi = [math.log(3.0), math.log(3.0), 2 * math.pi, 1.0]

    def build(p: np.ndarray, spike: bool) -> MicrofacetBRDF:
        au, av, az = float(math.exp(p[0])), float(math.exp(p[1])), float(p[2] % math.pi)
        if av > au:
            # alpha_u is the larger one, so that the azimuth names the highlight's long axis.
            au, av, az = av, au, (az + math.pi / 2) % math.pi
        w = float(p[3]) if spike else 0.0
        return MicrofacetBRDF(distribution, au, av, az, rho, float(ior), w, spike_alpha if spike else 0.0)

    # The bins around each mirror direction, where a mirror-flat part of the relief
    # reflects: the spike's energy is compared there as one pooled bin, so that it does
    # not matter on which side of a bin edge a mirror direction falls.
    mirror = np.zeros_like(grown)
    m_theta = np.arccos(np.clip(wis[:, 2], -1.0, 1.0))
    m_phi = (np.arctan2(wis[:, 1], wis[:, 0]) + math.pi) % (2 * math.pi)
    n_t, n_p = f_table.shape[1], f_table.shape[2]
    mirror[
        np.arange(len(wis)),
        np.minimum((m_theta / width).astype(int), n_t - 1),
        np.minimum((m_phi / (2 * math.pi) * n_p).astype(int), n_p - 1),
    ] = True
    mirror = _grow(mirror)
    pooled_table = (f_specular * omega * mirror).sum(axis=(1, 2))
    pooled_sigma = np.sqrt(
        ((stderr_specular * omega) ** 2 * mirror).sum(axis=(1, 2)) + (0.02 * pooled_table) ** 2
    )
    pooled_sigma = np.maximum(pooled_sigma, 1e-6)
    in_mirror = mirror[kk, it, ip]
    spike_albedo = fresnel_dielectric(wis[:, 2], ior)  # a flat mirror reflects F(theta_i), all of it there

    def fit_lobes(initial: tuple[float, float, float], spike: bool) -> FitResult:
        au0, av0, az0 = initial
        p0 = np.clip(
            [math.log(au0), math.log(av0), az0, 0.3 if spike else 0.0],
            np.array(lo) + 1e-9,
            np.array(hi) - 1e-9,
        )
        if min(au0, av0) > 0.5 * width:
            sub = int(min(max(math.ceil(2.5 * width / min(au0, av0)), 2), 8))
            dirs = _sub_directions(theta_edges, phi_edges, it, ip, sub)
            bin_omega = omega[it, ip]

            def residuals(p: np.ndarray) -> np.ndarray:
                broad = _lobe(distribution, math.exp(p[0]), math.exp(p[1]), p[2], ior, wi_rows, dirs).mean(
                    axis=-1
                )
                if not spike:
                    return (broad - target) / sigma
                w = p[3]
                per_bin = ((1.0 - w) * broad - target)[~in_mirror] / sigma[~in_mirror]
                pooled = (1.0 - w) * np.bincount(
                    kk[in_mirror], weights=(broad * bin_omega)[in_mirror], minlength=len(wis)
                ) + w * spike_albedo
                return np.concatenate([per_bin, (pooled - pooled_table) / pooled_sigma])

            n = 4 if spike else 3
            sol = least_squares(
                lambda q: residuals(np.concatenate([q, p0[n:]])),
                p0[:n],
                bounds=(lo[:n], hi[:n]),
                x_scale=[0.3, 0.3, 0.3, 0.1][:n],
                max_nfev=100,
            )
            model = build(np.concatenate([sol.x, p0[n:]]), spike)
            f_model = model_bins(model, wis, theta_edges, phi_edges)
            if not spike:
                # The lobe's own bins from the sub-samples the fit used (the numbers it minimised).
                broad = _lobe(
                    distribution, model.alpha_u, model.alpha_v, model.azimuth_rad, ior, wi_rows, dirs
                )
                centre_cos = np.cos(0.5 * (theta_edges[it] + theta_edges[it + 1]))
                f_model[kk, it, ip] = broad.mean(axis=-1) + _body(model, wis[kk, 2], centre_cos)
            err, used = relative_error(f_model, f_table, omega, stderr)
            pooled_err, _ = _relative_error_merged(f_model, f_table, omega, stderr, mirror)
            return FitResult(model, pooled_err if spike else err, used), pooled_err
        # A lobe narrower than half a bin cannot be measured by the table: the moment
        # estimate (an upper bound) stands, and the lobe is compared as one pooled bin.
        model = build(p0, False)
        f_model = model_bins(model, wis, theta_edges, phi_edges)
        err, used = _relative_error_merged(f_model, f_table, omega, stderr, grown)
        return FitResult(model, err, used), err

    noise = table_noise(f_table, omega, stderr) if stderr is not None else math.nan
    single, single_pooled = fit_lobes(lobe_alpha(f_specular[normal], theta_edges, phi_edges), spike=False)
    single = replace(single, table_noise=noise)
    if not allow_spike:
        return single
    # The broad lobe's moments without the mirror bins.
    broad_only = f_specular[normal].copy()
    broad_only[mirror[normal]] = 0.0
    au0, av0, az0 = lobe_alpha(broad_only, theta_edges, phi_edges)
    two, two_pooled = fit_lobes((max(au0, width), max(av0, width), az0), spike=True)
    # Both judged with the mirror bins pooled, where the spike is all that differs.
    if two.model.spike_weight > 0.005 and two_pooled < 0.75 * single_pooled:
        return replace(two, table_noise=noise)
    return single
