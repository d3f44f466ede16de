"""The tabulated-NDF model (:mod:`render.tabulated_ndf`) against a traced table: bin averages and errors.

The traced table (:mod:`render.gonio`) holds bin averages of the BRDF, cosine-weighted
over each outgoing bin; :func:`model_bins` gives the model's, for either compact model,
and :func:`table_error` compares them as :func:`render.brdf_fit.relative_error` does,
with the bins round each mirror direction pooled where the relief has flat facets.
"""

from __future__ import annotations

import math

import numpy as np

from render._tabulated_kernels import _facet_bins
from render.brdf_model import MicrofacetBRDF, bin_directions
from render.brdf_model import model_bins as analytic_model_bins
from render.tabulated_ndf import TabulatedMicrofacet, _body_term, _surface, spike_energy, surface_tables


def model_bins(
    model: TabulatedMicrofacet | MicrofacetBRDF,
    wi: np.ndarray,
    theta_edges: np.ndarray,
    phi_edges: np.ndarray,
    *,
    sub: int | None = None,
    specular_only: bool = False,
) -> np.ndarray:
    """Bin averages ``(n_in, n_theta, n_phi)`` of either compact model, as the traced table holds them.

    An analytic model goes to :func:`render.brdf_model.model_bins`. For the tabulated
    one the surface term is integrated over the table's facets (2 x 2 to 4 x 4 points per
    cell of the table, each reflected into its bin, so that reflected directions lie an
    eighth of a bin apart), except in the rings round the pole, whose
    wedges are too thin for that: there it is averaged over ``sub x sub`` directions per
    bin (equal steps in ``sin^2 theta`` and ``phi``, default 8). The spike's power goes to
    the bin of the mirror direction; the body (smooth) is averaged over 2 x 2 directions.
    """
    from render.gonio import projected_solid_angle

    if isinstance(model, MicrofacetBRDF):
        if specular_only:
            model = MicrofacetBRDF(
                model.distribution, model.alpha_u, model.alpha_v, model.azimuth_rad, 0.0, model.ior,
                model.spike_weight, model.spike_alpha,
            )  # fmt: skip
        return analytic_model_bins(model, wi, theta_edges, phi_edges)
    wis = np.atleast_2d(np.asarray(wi, dtype=np.float64))
    n_t, n_p = len(theta_edges) - 1, len(phi_edges) - 1
    omega = projected_solid_angle(theta_edges, phi_edges)
    uniform = np.allclose(theta_edges, np.linspace(0.0, math.pi / 2, n_t + 1)) and np.allclose(
        phi_edges, np.linspace(0.0, 2.0 * math.pi, n_p + 1)
    )
    ndf = model.ndf
    # Facets by quadrature (points in each cell of the table: each lands in one bin), except
    # in the rings round the pole whose thin wedges are narrower than a few points' spacing:
    # those average sub-sampled directions (as everywhere where the bins are not uniform).
    width = float(np.min(np.diff(theta_edges)))
    points = int(min(max(math.ceil(16.0 * ndf.step / width), 2), 4))  # per cell side: wo every width / 8
    spacing = 2.0 * ndf.step / points
    arc = np.sin(np.asarray(theta_edges)[1:]) * np.diff(phi_edges).min()
    direct_rings = n_t if not uniform else int(np.sum(arc < 8.0 * spacing))
    if sub is None:
        sub = 8
    out = np.zeros((wis.shape[0], n_t, n_p))
    if direct_rings < n_t and ndf.spike_weight < 1.0:
        sums = np.zeros((wis.shape[0], n_t * n_p))
        _facet_bins(
            ndf.density, ndf.extent, points, wis, ndf.area, model.ms_factor, math.pi / 2,
            -1.0 if model.ior is None else float(model.ior), n_t, n_p, sums,
        )  # fmt: skip
        out += (1.0 - ndf.spike_weight) * sums.reshape(out.shape) / omega
    body = model.body_albedo > 0.0 and not specular_only
    spike = spike_energy(model, wis) if model.spike_weight > 0.0 else np.zeros(len(wis))
    rings = slice(0, direct_rings)
    dirs = bin_directions(theta_edges[: direct_rings + 1], phi_edges, sub) if direct_rings else None
    body_dirs = bin_directions(theta_edges, phi_edges, 2) if body else None  # smooth: 2 x 2 a bin
    dirs_tables = surface_tables(model, dirs) if dirs is not None else None  # (the same for every wi)
    for k, w in enumerate(wis):
        if dirs is not None:
            out[k, rings] = _surface(
                model, w[None, None, None, :], dirs, spike=False, wo_tables=dirs_tables
            ).mean(axis=-1)
        if body_dirs is not None:
            out[k] += _body_term(model, w[None, None, None, :], body_dirs).mean(axis=-1)
        if spike[k] > 0.0:
            theta = math.acos(min(w[2], 1.0))
            phi = (math.atan2(w[1], w[0]) + math.pi) % (2.0 * math.pi)
            it = min(int(np.searchsorted(theta_edges, theta, side="right")) - 1, n_t - 1)
            ip = min(int(phi / (2.0 * math.pi) * n_p), n_p - 1)
            out[k, it, ip] += spike[k] / omega[it, ip]
    return out


def mirror_bins(wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray) -> np.ndarray:
    """``(n_in, n_theta, n_phi)`` mask: the bin of each mirror direction and its neighbours.

    A flat facet reflects exactly into the mirror direction; which side of a bin edge that
    falls on is an accident of rounding (a 40-degree mirror direction lies on the edge of
    2-degree bins), so the spike's power is compared over these bins pooled.
    """
    from render.brdf_fit import _grow

    wis = np.atleast_2d(wi)
    n_t, n_p = len(theta_edges) - 1, len(phi_edges) - 1
    mask = np.zeros((len(wis), n_t, n_p), dtype=bool)
    theta = np.arccos(np.clip(wis[:, 2], -1.0, 1.0))
    phi = (np.arctan2(wis[:, 1], wis[:, 0]) + math.pi) % (2.0 * math.pi)
    it = np.clip(np.searchsorted(theta_edges, theta, side="right") - 1, 0, n_t - 1)
    ip = np.minimum((phi / (2.0 * math.pi) * n_p).astype(np.int64), n_p - 1)
    mask[np.arange(len(wis)), it, ip] = True
    return _grow(mask)


def table_error(
    model: TabulatedMicrofacet | MicrofacetBRDF,
    wi: np.ndarray,
    f_table: np.ndarray,
    stderr: np.ndarray | None,
    theta_edges: np.ndarray,
    phi_edges: np.ndarray,
    f_model: np.ndarray | None = None,
) -> tuple[float, int]:
    """:func:`render.brdf_fit.relative_error` of a model against a table (mirror bins pooled for a spike).

    ``f_model``: the model's bin averages (:func:`model_bins`) when the caller has them already.
    """
    from render.brdf_fit import _relative_error_merged, relative_error
    from render.gonio import projected_solid_angle

    if f_model is None:
        f_model = model_bins(model, wi, theta_edges, phi_edges)
    omega = projected_solid_angle(theta_edges, phi_edges)
    if model.spike_weight > 0.0:
        return _relative_error_merged(
            f_model, f_table, omega, stderr, mirror_bins(wi, theta_edges, phi_edges)
        )
    return relative_error(f_model, f_table, omega, stderr)
