"""Fitting the compact BRDF (:mod:`render.brdf_model`) to a traced table, and its error measures.

The fit is weighted least squares on bin averages (SciPy's ``least_squares``), over the
bins that hold the reflection lobe; the relative error is measured against the table's
own noise on the same bins, so that an error below it cannot be seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from render.brdf_model import DISTRIBUTIONS, MicrofacetBRDF, _body, _body_shape, lobe_row_means, model_bins
from render.fresnel import diffuse_fresnel_reflectance, fresnel_dielectric


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
                broad = lobe_row_means(distribution, math.exp(p[0]), math.exp(p[1]), p[2], ior, wis, kk, dirs)
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
                broad = lobe_row_means(
                    distribution, model.alpha_u, model.alpha_v, model.azimuth_rad, ior, wis, kk, dirs
                )
                centre_cos = np.cos(0.5 * (theta_edges[it] + theta_edges[it + 1]))
                f_model[kk, it, ip] = broad + _body(model, wis[kk, 2], centre_cos)
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
