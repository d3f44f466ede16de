"""Appearance from a relief: its BRDF table, a glossmeter's readings, the highlight's shape, a fitted model.

Gloss follows ISO 2813 / ASTM D523: the flux reflected into the receptor aperture
around the mirror direction, relative to the flux a polished black glass of index
1.567 reflects there (100 gloss units), at 20, 60 and 85 degrees. The receptor
apertures (full angles, in the plane of incidence x across it; ISO 2813 Table 1) are
1.8 x 3.6 degrees at 20, 4.4 x 11.7 at 60 and 4.0 x 6.0 at 85. The source is taken as
collimated (the standard's source aperture is 0.75 degrees, well inside every
receptor). Haze is the index of ASTM D4039-09, ``G60 - G20`` (its section 3.2.3):
light scattered a few degrees around the mirror direction, caught by the wide 60-degree
receptor but not by the narrow 20-degree one. The standard defines it for high-gloss,
nonmetallic surfaces only, those whose 60-degree gloss is above 70 GU (its section 4.2):
below that most of the reflected light is outside both receptors and the difference
says nothing about haze (a matte relief can read G20 above G60, a negative "haze").
Elsewhere haze is reported as undefined (None), with the reason.

The compact model is the tabulated-NDF microfacet model of the relief's own facets
(:mod:`render.tabulated_ndf`); the analytic GGX or Beckmann fit (:mod:`render.brdf_fit`)
is kept beside it, for its familiar parameters and for comparison. Where the compact
model misses the traced table by more than ``max(10 %, 3 x the table's noise)``
(:func:`render.representation.tolerance_for`), the table stands in for it, and the
metrics say so, with a warning.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from noise.heightfield import HeightField
from render.brdf_fit import FitResult, fit_microfacet, lobe_alpha, table_noise
from render.fresnel import fresnel_dielectric
from render.gonio import (
    BrdfTable,
    direction_from_angles,
    estimate_brdf,
    lit_window,
    rays_for_lobe_error,
    table_lobe_errors,
)
from render.representation import tolerance_for
from render.tabulated_bins import model_bins, table_error
from render.tabulated_ndf import tabulate_ndf, tabulated_model

BLACK_GLASS_INDEX = 1.567
HAZE_MIN_GLOSS_60 = 70.0
"""ASTM D4039-09, section 4.2: the haze index is for specimens whose 60-degree gloss exceeds 70 GU."""
# A small calibration run underestimates the lobe's error (its lobe holds fewer bins, and
# sparsely hit bins understate their spread), so the budget is refined from each run.
_BUDGET_ROUNDS = 4
GLOSS_APERTURES_DEG = {20: (1.8, 3.6), 60: (4.4, 11.7), 85: (4.0, 6.0)}
"""Receptor apertures (in the plane of incidence, across it), full angles in degrees."""

DEFAULT_INCIDENT_DEG = (
    (0.0, 0.0),
    (20.0, 0.0),
    (40.0, 0.0),
    (60.0, 0.0),
    (75.0, 0.0),
    (40.0, 90.0),
    (60.0, 90.0),
)
"""Incident (theta, phi) in degrees of the default table: a sweep in the xz plane and two across it."""


def _finite(value: float, digits: int = 5) -> float | None:
    """Rounded, or None where undefined (JSON has no NaN)."""
    return round(value, digits) if math.isfinite(value) else None


def gloss_units(aperture_fraction: np.ndarray | float, theta_deg: np.ndarray | float) -> np.ndarray:
    """Specular gloss (GU): aperture reflectance relative to black glass (n = 1.567) at the same angle."""
    reference = fresnel_dielectric(np.cos(np.radians(theta_deg)), BLACK_GLASS_INDEX)
    return 100.0 * np.asarray(aperture_fraction) / reference


def bin_centres(theta_edges: np.ndarray, phi_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polar and azimuthal angle (radians) at the centre of each bin: two ``(n_theta, n_phi)`` arrays."""
    t = 0.5 * (theta_edges[:-1] + theta_edges[1:])
    p = 0.5 * (phi_edges[:-1] + phi_edges[1:])
    return np.meshgrid(t, p, indexing="ij")


def peak_direction(table: BrdfTable, k: int) -> tuple[float, float]:
    """(theta, phi) in degrees of the bin holding the most reflected power for incident direction ``k``."""
    energy = table.f[k] * table.projected_solid_angle
    it, ip = np.unravel_index(int(np.argmax(energy)), energy.shape)
    t, p = bin_centres(table.theta_o_edges, table.phi_o_edges)
    return math.degrees(t[it, ip]), math.degrees(p[it, ip])


def haze_index(gloss_gu: dict[str, float]) -> tuple[float | None, str]:
    """ASTM D4039's haze index ``G60 - G20`` where the standard defines it, else None; and why.

    Defined for high-gloss surfaces: a 60-degree gloss above :data:`HAZE_MIN_GLOSS_60`
    (ASTM D4039-09, section 4.2), which also keeps G60 at or above G20 on every relief
    traced here. A reading of G20 above G60 is refused all the same: it is no haze.
    """
    g20, g60 = float(gloss_gu["20"]), float(gloss_gu["60"])
    if not g60 > HAZE_MIN_GLOSS_60:
        return None, (
            f"n/a: the 60-degree gloss {g60:.1f} GU is not above the {HAZE_MIN_GLOSS_60:g} GU from which "
            "ASTM D4039 defines haze (high-gloss surfaces only)"
        )
    if g20 > g60:
        return None, (
            f"n/a: the 20-degree gloss {g20:.1f} GU is above the 60-degree {g60:.1f} GU, which the "
            "haze index G60 - G20 of ASTM D4039 does not describe"
        )
    return round(g60 - g20, 3), f"G60 - G20 (ASTM D4039; G60 {g60:.1f} GU > {HAZE_MIN_GLOSS_60:g} GU)"


@dataclass
class Appearance:
    """Predicted appearance of a relief: the BRDF table, the glossmeter readings, the compact model.

    ``fit`` is the compact model (the tabulated-NDF model, :mod:`render.tabulated_ndf`)
    and its error against the table; ``analytic`` the GGX or Beckmann fit beside it.
    """

    table: BrdfTable
    gloss_table: BrdfTable
    fit: FitResult
    metrics: dict[str, Any] = field(default_factory=dict)
    analytic: FitResult | None = None
    model_f: np.ndarray | None = None
    """The compact model's bin averages at the table's incident directions (1/sr), where computed."""


def glossmeter(
    heights_mm: np.ndarray,
    pitch_x_mm: float,
    pitch_y_mm: float,
    *,
    rays: int,
    ior: float,
    body_albedo: float,
    seed: int,
    periodic: bool,
) -> tuple[BrdfTable, dict[str, float], dict[str, float]]:
    """The traced glossmeter (module doc): its table, and the gloss (GU) at 20, 60 and 85 degrees
    with the plane of incidence along x, and along y.

    Rays into each ISO 2813 receptor aperture (Table 1), seeded with ``seed + 1`` so that the
    glossmeter and the BRDF table of :func:`predict_appearance` never share rays.
    """
    angles = sorted(GLOSS_APERTURES_DEG)
    gloss_inc = [(a, phi) for phi in (0.0, 90.0) for a in angles]
    g_wi = direction_from_angles(np.radians([a for a, _ in gloss_inc]), np.radians([p for _, p in gloss_inc]))
    apertures = np.radians(
        [[0.5 * GLOSS_APERTURES_DEG[a][0], 0.5 * GLOSS_APERTURES_DEG[a][1]] for a, _ in gloss_inc]
    )
    gloss_table = estimate_brdf(
        heights_mm,
        pitch_x_mm,
        pitch_y_mm,
        g_wi,
        rays=rays,
        ior=ior,
        body_albedo=body_albedo,
        n_theta=18,
        n_phi=36,
        seed=seed + 1,
        aperture_rad=apertures,
        periodic=periodic,
    )
    gu = gloss_units(gloss_table.aperture, np.array([a for a, _ in gloss_inc]))
    gloss = {str(a): round(float(gu[i]), 3) for i, a in enumerate(angles)}
    gloss_y = {str(a): round(float(gu[len(angles) + i]), 3) for i, a in enumerate(angles)}
    return gloss_table, gloss, gloss_y


def predict_appearance(
    field: HeightField,
    *,
    ior: float = 1.5,
    body_albedo: float = 0.8,
    incident_deg: tuple[tuple[float, float], ...] = DEFAULT_INCIDENT_DEG,
    rays: int = 200_000,
    n_theta: int = 45,
    n_phi: int = 90,
    seed: int = 0,
    periodic: bool = False,
    distribution: str = "auto",
    lobe_error_target: float | None = None,
    max_rays: int = 100_000_000,
    analytic: bool = True,
) -> Appearance:
    """Trace a relief's BRDF, read gloss and haze off it, and fit the compact model.

    Parameters
    ----------
    field : noise.heightfield.HeightField
        The relief (heights and pitches in mm; see :func:`render.gonio.estimate_brdf`).
    incident_deg : sequence of (theta, phi) in degrees
        Incident directions of the table.
    rays : int
        Primary rays per incident direction (table and glossmeter alike); with
        ``lobe_error_target``, the table's calibration run.
    lobe_error_target : float, optional
        Trace each incident direction until its surface-reflection lobe reaches this
        relative standard error (:func:`render.gonio.lobe_error`, e.g. 0.01): the error
        falls as 1/sqrt(rays), so a run's errors give each direction's rays
        (:func:`render.gonio.rays_for_lobe_error`), capped at ``max_rays``; the budget is
        refined from each run until every direction meets the target (at most four
        runs). A matte lobe at normal incidence needs far more rays than a grazing one.
    analytic : bool
        Whether to fit the analytic GGX or Beckmann model beside the compact one now; without
        it, ``metrics["fit_analytic"]`` is None until :func:`with_analytic_fit` adds it (a design
        run fits it on its background thread: nothing the preview needs depends on it).
    periodic : bool
        Whether the relief tiles seamlessly; a patch cut from a larger relief does not.

    Returns
    -------
    Appearance
        ``metrics`` holds ``albedo`` (per incident direction), ``gloss_gu`` (20/60/85
        with the plane of incidence along x and along y), ``haze``, ``peak_deg``,
        ``highlight`` (RMS radius, anisotropy, azimuth) and ``fit`` (parameters and
        relative error).
    """
    heights_mm, pitch_x_mm, pitch_y_mm = field.heights_mm, field.pitch_x_mm, field.pitch_y_mm
    inc = np.asarray(incident_deg, dtype=np.float64).reshape(-1, 2)
    if np.any(inc[:, 0] < 0) or np.any(inc[:, 0] >= 90):
        raise ValueError("incident_deg: polar angles must lie in [0, 90) degrees")
    wi = direction_from_angles(np.radians(inc[:, 0]), np.radians(inc[:, 1]))
    if lobe_error_target is not None and not (0.0 < lobe_error_target < 1.0):
        raise ValueError(f"lobe_error_target: expected a fraction in (0, 1), got {lobe_error_target!r}")

    def trace(per_direction: int | np.ndarray) -> BrdfTable:
        return estimate_brdf(
            heights_mm,
            pitch_x_mm,
            pitch_y_mm,
            wi,
            rays=per_direction,
            ior=ior,
            body_albedo=body_albedo,
            n_theta=n_theta,
            n_phi=n_phi,
            seed=seed,
            periodic=periodic,
        )

    table = trace(rays)
    lobe_errors = table_lobe_errors(table)
    for _ in range(_BUDGET_ROUNDS if lobe_error_target is not None else 0):
        if not np.any(lobe_errors > lobe_error_target):
            break
        budget = rays_for_lobe_error(lobe_errors, table.rays, lobe_error_target, max_rays)
        if np.array_equal(budget, table.rays):
            break  # capped at max_rays
        # The same seed: the earlier run's rays are the first of the longer run's.
        table = trace(budget)
        lobe_errors = table_lobe_errors(table)
    # The glossmeter's rays (numba, releasing the GIL) run on a thread of their own while the
    # compact model's numpy runs here: the model's steps use one core, the tracer both.
    with ThreadPoolExecutor(1, thread_name_prefix="glossmeter") as pool:
        gloss_run = pool.submit(
            glossmeter,
            heights_mm,
            pitch_x_mm,
            pitch_y_mm,
            rays=rays,
            ior=ior,
            body_albedo=body_albedo,
            seed=seed,
            periodic=periodic,
        )
        normal = int(np.argmin(inc[:, 0]))
        # The compact model: the facets the tracer saw (on a patch, those of the window it lit
        # at the most normal incidence), the resin's index and the body's albedo.
        window = (
            None
            if periodic
            else lit_window(heights_mm, pitch_x_mm, pitch_y_mm, wi[normal : normal + 1], False)[0]
        )
        ndf = tabulate_ndf(heights_mm, pitch_x_mm, pitch_y_mm, periodic=periodic, window=window)
        compact = tabulated_model(ndf, body_albedo, ior)
        omega = table.projected_solid_angle
        noise = table_noise(table.f, omega, table.stderr)
        # The model's bins at the table's incident directions: its error here, and the report's maps.
        model_f = model_bins(compact, wi, table.theta_o_edges, table.phi_o_edges)
        error, used = table_error(
            compact, wi, table.f, table.stderr, table.theta_o_edges, table.phi_o_edges, f_model=model_f
        )
        gloss_table, gloss, gloss_y = gloss_run.result()
    haze, haze_reason = haze_index(gloss)
    fit = FitResult(compact, error, used, noise)
    representation, warnings = model_or_table(fit)
    # The highlight's shape from the surface-reflection lobe at the most normal incidence.
    alpha_long, alpha_short, azimuth = lobe_alpha(
        table.f_specular[normal], table.theta_o_edges, table.phi_o_edges
    )
    metrics: dict[str, Any] = {
        "incident_deg": inc.tolist(),
        "albedo": [round(float(a), 5) for a in table.albedo],
        "albedo_stderr": [float(f"{a:.3g}") for a in table.albedo_stderr],
        "gloss_gu": gloss,
        "gloss_gu_plane_yz": gloss_y,
        "haze": haze,
        "haze_reason": haze_reason,
        "peak_deg": [[round(v, 2) for v in peak_direction(table, k)] for k in range(len(inc))],
        "highlight": {
            "at_incidence_deg": inc[normal].tolist(),
            "alpha_long": round(alpha_long, 5),
            "alpha_short": round(alpha_short, 5),
            "anisotropy": round(alpha_long / alpha_short, 4),
            "azimuth_deg": round(math.degrees(azimuth), 3),
        },
        "fit": {
            **{k: (round(v, 6) if isinstance(v, float) else v) for k, v in fit.model.as_dict().items()},
            "relative_error": _finite(fit.relative_error),
            "table_noise": _finite(fit.table_noise),
            "bins": fit.bins_used,
        },
        "fit_analytic": None,
        "representation": representation,
        "warnings": warnings,
        "rays_per_direction": [int(r) for r in table.rays],
        "lobe_error": [_finite(float(e)) for e in lobe_errors],
        "lost_fraction": float(np.max(np.concatenate([table.lost, gloss_table.lost]))),
    }
    predicted = Appearance(table=table, gloss_table=gloss_table, fit=fit, metrics=metrics, model_f=model_f)
    return with_analytic_fit(predicted, ior=ior, distribution=distribution) if analytic else predicted


def with_analytic_fit(appearance: Appearance, *, ior: float = 1.5, distribution: str = "auto") -> Appearance:
    """``appearance`` with the analytic GGX or Beckmann fit (:func:`render.brdf_fit.fit_microfacet`)
    to its traced table beside the compact model, in ``analytic`` and ``metrics["fit_analytic"]``."""
    table = appearance.table
    inc = np.asarray(appearance.metrics["incident_deg"], dtype=np.float64).reshape(-1, 2)
    # The directions as the table was asked for them (its own are renormalised, and the fit
    # moves with their last bits; tests/test_brdf.py holds the two ways equal).
    wi = direction_from_angles(np.radians(inc[:, 0]), np.radians(inc[:, 1]))
    analytic = fit_microfacet(
        wi,
        table.f,
        table.f_specular,
        table.stderr_specular,
        table.theta_o_edges,
        table.phi_o_edges,
        ior=ior,
        distribution=distribution,
        stderr=table.stderr,
    )
    metrics = dict(appearance.metrics)  # (the key keeps its place: the manifest's order is fixed)
    metrics["fit_analytic"] = {
        **analytic.model.as_dict(),
        "relative_error": _finite(analytic.relative_error),
        "table_noise": _finite(analytic.table_noise),
        "bins": analytic.bins_used,
    }
    return replace(appearance, analytic=analytic, metrics=metrics)


def model_or_table(fit: FitResult) -> tuple[dict[str, Any], list[str]]:
    """Whether the compact model may stand in for the traced table, why, and the warnings."""
    tolerance = tolerance_for(fit.table_noise)
    error = fit.relative_error
    noise = "n/a" if not math.isfinite(fit.table_noise) else f"{fit.table_noise:.1%}"
    rule = f"max(10 %, 3 x the table's noise {noise}) = {tolerance:.1%}"
    if math.isfinite(error) and error <= tolerance:
        use = "model"
        reason = f"the compact model fits the traced table to {error:.1%}, within {rule}"
        warnings: list[str] = []
    else:
        use = "table"
        missed = (
            "an error that cannot be measured (too few rays)" if not math.isfinite(error) else f"{error:.1%}"
        )
        reason = f"the compact model misses the traced table by {missed}, more than {rule}: the table is used"
        warnings = [
            f"the compact BRDF model misses the traced table by {missed} (more than {rule}); "
            "the traced table stands in for it in BRDF renders"
        ]
    return {"use": use, "tolerance": round(tolerance, 6), "reason": reason}, warnings
