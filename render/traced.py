"""The traced glossmeter alone: gloss, haze and the highlight of a relief, as
:func:`render.appearance.predict_appearance` reports them, without the table's other directions
or the compact model's fit.

``predict_appearance`` traces seven incident directions for its table, six for the glossmeter,
and fits the compact model (seconds, whatever the rays). Its gloss and haze come from the
glossmeter's table alone, and its highlight from the table's direction at normal incidence
alone; every direction's rays are keyed by its index (:func:`render.gonio.primary_origin`),
so tracing that one direction with the same index, seed and ray budget gives the same numbers,
bit for bit (``tests/test_solve.py`` checks it). ``printapp solve`` and ``printapp sweep``
confirm candidates with these.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from noise.heightfield import HeightField
from render.appearance import DEFAULT_INCIDENT_DEG, glossmeter, haze_index
from render.brdf_fit import lobe_alpha
from render.gonio import direction_from_angles, estimate_brdf


def traced_gloss(
    field: HeightField,
    *,
    ior: float = 1.5,
    body_albedo: float = 0.8,
    rays: int = 200_000,
    n_theta: int = 45,
    n_phi: int = 90,
    seed: int = 0,
) -> dict[str, Any]:
    """``gloss_gu``, ``haze`` and ``highlight`` of :func:`render.appearance.predict_appearance` (same
    arguments, default incident directions, a patch: ``periodic=False``, a fixed ray budget).

    (With a lobe error target, ``predict_appearance`` sets every direction's rays from all of
    them; that has no one-direction equivalent, so callers trace the whole table then.)
    """
    inc = np.asarray(DEFAULT_INCIDENT_DEG, dtype=np.float64)
    normal = int(np.argmin(inc[:, 0]))
    wi_all = direction_from_angles(np.radians(inc[:, 0]), np.radians(inc[:, 1]))

    def trace(per_direction: int) -> Any:
        # Only the normal direction, under its own index: the table's row, bit for bit.
        counts = np.zeros(len(inc), dtype=np.int64)
        counts[normal] = per_direction
        return estimate_brdf(
            field.heights_mm,
            field.pitch_x_mm,
            field.pitch_y_mm,
            wi_all,
            rays=np.maximum(counts, 2),
            ior=ior,
            body_albedo=body_albedo,
            n_theta=n_theta,
            n_phi=n_phi,
            seed=seed,
            periodic=False,
        )

    table = trace(rays)
    _, gloss, _ = glossmeter(
        field.heights_mm,
        field.pitch_x_mm,
        field.pitch_y_mm,
        rays=rays,
        ior=ior,
        body_albedo=body_albedo,
        seed=seed,
        periodic=False,
    )
    haze, haze_reason = haze_index(gloss)
    alpha_long, alpha_short, azimuth = lobe_alpha(
        table.f_specular[normal], table.theta_o_edges, table.phi_o_edges
    )
    return {
        "gloss_gu": gloss,
        "haze": haze,
        "haze_reason": haze_reason,
        "highlight": {
            "alpha_long": round(alpha_long, 5),
            "alpha_short": round(alpha_short, 5),
            "anisotropy": round(alpha_long / alpha_short, 4),
            "azimuth_deg": round(math.degrees(azimuth), 3),
        },
    }
