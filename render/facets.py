"""A glossmeter on facets: the gloss, haze and highlight of a relief from its slopes alone, no rays traced.

The cheap predictor (the surrogate) that ``printapp solve`` searches on, before it confirms
its best candidates with the traced BRDF (:func:`render.appearance.predict_appearance`).
It sees the relief as the tracer does, four triangles per cell around its centre (the mean
of its corners), and takes one bounce off each: a collimated beam at
``theta`` in the xz plane lights a facet of normal ``n`` with the share
``(wi . n) / (n_z cos theta)`` of its projected area, the facet reflects the Fresnel fraction
``R(wi . n)`` into the mirror direction about ``n``, and what lands in the ISO 2813 receptor
aperture (tested as the tracer tests it) counts, relative to black glass; the pigmented
body adds its Lambertian share of the aperture's solid angle (the tracer's body model,
:func:`render.gonio.body_factor`). Shadowing, masking and second bounces are left out:
the gap to the tracer, which ``printapp solve`` measures and corrects, is largest at
85 degrees on steep reliefs. The highlight's anisotropy and direction are those of the
slope covariance (:func:`render.microfacet.slope_roughness`), which is also what a
design's ``anisotropy`` target is checked against.
"""

from __future__ import annotations

import math

import numpy as np

from noise.heightfield import HeightField
from render.appearance import BLACK_GLASS_INDEX, GLOSS_APERTURES_DEG
from render.brdf_fit import lobe_alpha
from render.fresnel import fresnel_dielectric
from render.gonio import body_factor, projected_solid_angle
from render.microfacet import slope_roughness


def facet_normals(field: HeightField) -> np.ndarray:
    """Unit normals ``(4 (ny-1) (nx-1), 3)`` of the field's triangles, four per cell around its centre
    (the mean of its corners), as the tracer sees them (:func:`render.gonio.facet_slopes`): bottom,
    right, top and left triangles in blocks, each standing for a quarter of a cell of projected area."""
    h = field.heights_mm
    px, py = field.pitch_x_mm, field.pitch_y_mm
    h00, h10, h01, h11 = h[:-1, :-1], h[:-1, 1:], h[1:, :-1], h[1:, 1:]
    hc = 0.25 * ((h00 + h11) + (h10 + h01))
    gx = [h10 - h00, (h10 + h11) - 2.0 * hc, h11 - h01, 2.0 * hc - (h00 + h01)]
    gy = [2.0 * hc - (h00 + h10), h11 - h10, (h01 + h11) - 2.0 * hc, h01 - h00]
    sx = np.concatenate([g.ravel() for g in gx]) / px
    sy = np.concatenate([g.ravel() for g in gy]) / py
    n = np.column_stack([-sx, -sy, np.ones_like(sx)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _row_horizon(h: np.ndarray, pitch_x_mm: float, cot: float, towards_plus_x: bool) -> np.ndarray:
    """Per sample: whether the relief along its row, taken as periodic, leaves it open to a direction
    of elevation ``atan(1 / cot)`` in the xz plane, towards +x or towards -x."""
    rows = h if towards_plus_x else h[:, ::-1]
    n = rows.shape[1]
    ext = np.concatenate([rows, rows], axis=1)
    g = ext - np.arange(2 * n) * pitch_x_mm * cot
    ahead = np.maximum.accumulate(g[:, ::-1], axis=1)[:, ::-1]  # max over x' >= x
    open_ = g[:, :n] >= ahead[:, 1 : n + 1]
    return open_ if towards_plus_x else open_[:, ::-1]


def facet_openness(field: HeightField, theta_deg: float) -> np.ndarray:
    """Per triangle (in :func:`facet_normals`' order), the share of its corners both lit by a beam at
    ``theta_deg`` from +x and seen from the mirror direction (towards -x): row-wise horizons, exact
    for the plane of incidence, the tile taken as periodic along x."""
    t = math.radians(theta_deg)
    cot = math.cos(t) / max(math.sin(t), 1e-12)
    h = field.heights_mm
    both = (
        _row_horizon(h, field.pitch_x_mm, cot, True) & _row_horizon(h, field.pitch_x_mm, cot, False)
    ).astype(np.float64)
    o00, o10, o01, o11 = both[:-1, :-1], both[:-1, 1:], both[1:, :-1], both[1:, 1:]
    oc = 0.25 * (o00 + o10 + o01 + o11)  # the centre, open as its corners are on average
    sides = [(o00 + o10 + oc), (o10 + o11 + oc), (o11 + o01 + oc), (o01 + o00 + oc)]
    return np.concatenate([(t / 3.0).ravel() for t in sides])


def aperture_fraction(
    normals: np.ndarray, theta_deg: float, ior: float, openness: np.ndarray | None = None
) -> float:
    """Share of a collimated beam at ``theta_deg`` (plane of incidence xz) that one bounce off the
    facets sends into the ISO 2813 receptor aperture of that angle (each facet weighted by its
    ``openness`` to the beam and the receptor, when given)."""
    a_in, a_perp = (math.radians(0.5 * a) for a in GLOSS_APERTURES_DEG[int(theta_deg)])
    t = math.radians(theta_deg)
    sin_t, cos_t = math.sin(t), math.cos(t)
    # Only facets tilted less than this can send the beam into the aperture: a tilt e in the
    # plane of incidence turns the reflection by 2e, across it by about 2e cos(theta).
    tilt = 0.5 * max(a_in, a_perp / max(cos_t, 1e-6)) * 1.2 + math.radians(0.5)
    near = normals[:, 2] >= math.cos(min(tilt, 0.5 * math.pi))
    if openness is not None:
        near &= openness > 0.0
    n = normals[near]
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    c = nx * sin_t + nz * cos_t  # wi . n
    rx, ry, rz = 2.0 * c * nx - sin_t, 2.0 * c * ny, 2.0 * c * nz - cos_t
    qn = np.sqrt(rx * rx + rz * rz)
    c_in = np.clip((-rx * sin_t + rz * cos_t) / np.where(qn > 0, qn, 1.0), -1.0, 1.0)  # against the mirror
    ok = (c > 0.0) & (rz > 0.0) & (qn > 0.0) & (c_in >= math.cos(a_in)) & (np.abs(ry) <= math.sin(a_perp))
    share = np.ones(int(ok.sum())) if openness is None else openness[near][ok]
    weight = share * fresnel_dielectric(c[ok], ior) * c[ok] / (nz[ok] * cos_t)
    return float(weight.sum()) / normals.shape[0]


def highlight(normals: np.ndarray, ior: float, n_theta: int, n_phi: int) -> tuple[float, float, float]:
    """``(alpha_long, alpha_short, azimuth_rad)`` of the one-bounce reflection lobe at normal incidence,
    binned as the traced table is and measured as :func:`render.appearance.predict_appearance` does
    (:func:`render.brdf_fit.lobe_alpha`)."""
    r = 2.0 * normals[:, 2:3] * normals - np.array([0.0, 0.0, 1.0])
    up = r[:, 2] > 0.0
    r = r[up]
    weight = fresnel_dielectric(normals[up, 2], ior)
    theta = np.arccos(np.clip(r[:, 2], -1.0, 1.0))
    phi = np.arctan2(r[:, 1], r[:, 0]) % (2.0 * math.pi)
    theta_edges = np.linspace(0.0, math.pi / 2, n_theta + 1)
    phi_edges = np.linspace(0.0, 2 * math.pi, n_phi + 1)
    energy, _, _ = np.histogram2d(theta, phi, bins=[theta_edges, phi_edges], weights=weight)
    f = energy / projected_solid_angle(theta_edges, phi_edges)
    return lobe_alpha(f, theta_edges, phi_edges)


def body_aperture_fraction(theta_deg: float, ior: float, body_albedo: float) -> float:
    """Share of the beam the pigmented body sends into the aperture (Lambertian, flat surface)."""
    a_in, a_perp = (math.radians(0.5 * a) for a in GLOSS_APERTURES_DEG[int(theta_deg)])
    c = math.cos(math.radians(theta_deg))
    r = float(fresnel_dielectric(c, ior))
    f_body = (1.0 - r) * (1.0 - r) * body_factor(body_albedo, ior) / math.pi
    return f_body * c * (2.0 * a_in) * (2.0 * math.sin(a_perp))


def facet_appearance(
    field: HeightField, *, ior: float = 1.5, body_albedo: float = 0.8, n_theta: int = 45, n_phi: int = 90
) -> dict[str, float]:
    """Gloss (GU at 20, 60, 85 degrees, plane of incidence along x), haze, anisotropy and highlight
    azimuth of a relief, from its facets (see the module).

    Returns
    -------
    dict
        ``gloss_20``, ``gloss_60``, ``gloss_85``, ``haze`` (G60 - G20), ``anisotropy`` (ratio of
        the principal slope roughnesses), ``highlight_azimuth_deg`` (in [0, 180)),
        ``roughness`` (their geometric mean) and ``flat_fraction`` (share of facets within a
        thousandth of level: the mirror-flat layer tops).
    """
    normals = facet_normals(field)
    out: dict[str, float] = {}
    for angle in sorted(GLOSS_APERTURES_DEG):
        specular = aperture_fraction(normals, angle, ior, facet_openness(field, angle))
        share = specular + body_aperture_fraction(angle, ior, body_albedo)
        reference = float(fresnel_dielectric(math.cos(math.radians(angle)), BLACK_GLASS_INDEX))
        out[f"gloss_{angle}"] = 100.0 * share / reference
    out["haze"] = out["gloss_60"] - out["gloss_20"]
    rough = slope_roughness(*field.slopes())
    out["anisotropy"] = rough.anisotropy if math.isfinite(rough.anisotropy) else 1000.0
    long, short, azimuth = highlight(normals, ior, n_theta, n_phi)
    out["highlight_azimuth_deg"] = math.degrees(azimuth) % 180.0
    out["highlight_anisotropy"] = long / short
    out["roughness"] = rough.roughness
    out["flat_fraction"] = float(np.mean(normals[:, 2] > 1.0 - 5e-7))
    return out
