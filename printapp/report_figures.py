"""The report's BRDF figure: hemispherical maps of the traced table, the compact model and their ratio."""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

BRDF_DIRECTIONS_DEG = ((0.0, 0.0), (40.0, 0.0), (60.0, 90.0))
"""Incident (theta, phi) in degrees whose BRDF the report maps: the table's nearest directions."""
RATIO_RANGE = 4.0
"""The difference map's colour scale spans model/traced from 1/RATIO_RANGE to RATIO_RANGE."""


def _nearest_directions(wi: np.ndarray, wanted_deg: Sequence[tuple[float, float]]) -> list[int]:
    """Indices of the table's incident directions closest to ``wanted_deg``, without repeats."""
    chosen: list[int] = []
    for theta, phi in wanted_deg:
        t, p = math.radians(theta), math.radians(phi)
        target = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])
        order = np.argsort(-(wi @ target), kind="stable")
        for k in order:
            if int(k) not in chosen:
                chosen.append(int(k))
                break
    return sorted(chosen, key=lambda k: (-wi[k, 2], k))


def brdf_figure_png(
    appearance: Any, directions_deg: Sequence[tuple[float, float]] = BRDF_DIRECTIONS_DEG
) -> bytes:
    """Hemispherical maps of the traced BRDF table, the compact model and their ratio, as PNG bytes.

    One row per incident direction (the table's nearest to each of ``directions_deg``);
    each map looks down on the hemisphere of outgoing directions (polar angle 0 to 90
    degrees outwards, azimuth around). The table and the model share one logarithmic
    colour scale; the third map is model / traced on a logarithmic scale from
    ``1/RATIO_RANGE`` to ``RATIO_RANGE``, labelled as a relative difference. Bins the
    tracer left empty are grey in the difference map.

    Parameters
    ----------
    appearance : render.appearance.Appearance
        Its ``table`` (:class:`render.gonio.BrdfTable`) and ``fit.model``.
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure
    from matplotlib.ticker import FixedFormatter, FixedLocator, FuncFormatter, LogLocator, NullFormatter

    from render.tabulated_bins import model_bins

    table = appearance.table
    rows = _nearest_directions(np.asarray(table.wi), directions_deg)
    wi = np.asarray(table.wi)[rows]
    traced = np.asarray(table.f)[rows]
    model_f = getattr(appearance, "model_f", None)
    if model_f is not None:
        fitted = np.asarray(model_f)[rows]
    else:
        fitted = model_bins(appearance.fit.model, wi, table.theta_o_edges, table.phi_o_edges)
    # The scale follows the traced table (what is predicted) where its bins are reliable (under 50 %
    # standard error: the tiny bins round the zenith catch few rays). A mirror spike fills a bin or
    # two at hundreds per steradian: it saturates, so that the glossy lobe keeps its shades.
    positive = traced[traced > 0]
    reliable = traced[(traced > 0) & (np.asarray(table.stderr)[rows] < 0.5 * traced)]
    vmin = float(np.percentile(positive, 2)) if positive.size else 1e-3
    top = reliable if reliable.size else positive
    vmax = max(float(np.percentile(top, 99.5)) if top.size else 1.0, 10.0 * vmin)
    f_norm = LogNorm(vmin=vmin, vmax=vmax)
    r_norm = LogNorm(vmin=1.0 / RATIO_RANGE, vmax=RATIO_RANGE)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(traced > 0, fitted / traced, np.nan)
    ratio = np.clip(ratio, 1.0 / RATIO_RANGE, RATIO_RANGE)

    # Placed by hand (inches): a constrained layout spent half the figure's time on text.
    width_in, height_in = 9.0, 3.0 * len(rows) + 1.0
    fig = Figure(figsize=(width_in, height_in), dpi=80)

    def box(left_in: float, bottom_in: float, w_in: float, h_in: float) -> tuple[float, float, float, float]:
        return left_in / width_in, bottom_in / height_in, w_in / width_in, h_in / height_in

    # Each map is the bins looked up on a disc of pixels (radius = polar angle), drawn as an
    # image: polar pcolormesh of nine maps of 20,000 bins took a second to save.
    size = 161
    axis = np.linspace(-90.0, 90.0, size)
    xx, yy = np.meshgrid(axis, axis[::-1])
    radius_deg = np.hypot(xx, yy)
    inside = radius_deg < 90.0
    theta_bin = np.clip(
        np.searchsorted(np.degrees(table.theta_o_edges), radius_deg, side="right") - 1, 0, None
    )
    phi = np.arctan2(yy, xx) % (2.0 * math.pi)
    phi_bin = np.clip(np.searchsorted(table.phi_o_edges, phi, side="right") - 1, 0, None)
    theta_bin = np.minimum(theta_bin, len(table.theta_o_edges) - 2)
    phi_bin = np.minimum(phi_bin, len(table.phi_o_edges) - 2)
    circle = np.linspace(0.0, 2.0 * math.pi, 181)
    f_mesh = r_mesh = None
    for i in range(len(rows)):
        theta_i = math.degrees(math.acos(float(np.clip(wi[i, 2], -1.0, 1.0))))
        phi_i = math.degrees(math.atan2(wi[i, 1], wi[i, 0])) % 360.0
        label = f"light from {theta_i:.0f}° polar, {phi_i:.0f}° azimuth"
        panels = (
            (traced[i], f_norm, "magma", "traced table f"),
            (fitted[i], f_norm, "magma", "compact model f"),
            (ratio[i], r_norm, "RdBu_r", "model vs traced"),
        )
        for j, (values, norm, cmap, name) in enumerate(panels):
            ax = fig.add_axes(box(3.0 * j + 0.2, height_in - 3.0 * (i + 1) + 0.05, 2.6, 2.5))
            shown = np.clip(values, vmin, None) if norm is f_norm else values
            disc = shown[theta_bin, phi_bin]
            mappable = ScalarMappable(norm=norm, cmap=cmap)
            rgba = mappable.to_rgba(np.where(np.isnan(disc), 1.0, disc))
            rgba[inside & np.isnan(disc)] = (0.733, 0.733, 0.733, 1.0)  # bins the tracer left empty
            rgba[~inside] = (1.0, 1.0, 1.0, 0.0)
            ax.imshow(rgba, extent=(-90, 90, -90, 90), interpolation="nearest")
            if norm is f_norm:
                f_mesh = mappable
            else:
                r_mesh = mappable
            for ring in (30.0, 60.0, 90.0):
                ax.plot(ring * np.cos(circle), ring * np.sin(circle), color="0.6", linewidth=0.5)
            for angle in (0, 90, 180, 270):
                ax.text(
                    (104 if angle % 180 == 0 else 98) * math.cos(math.radians(angle)),
                    98 * math.sin(math.radians(angle)),
                    f"{angle}°",
                    fontsize=7,
                    ha="center",
                    va="center",
                )
            ax.set_xlim(-116, 116)
            ax.set_ylim(-106, 106)
            ax.set_aspect("equal")
            ax.axis("off")
            ax.set_title(f"{name}\n{label}", fontsize=8)
    f_bar = fig.colorbar(
        f_mesh,
        cax=fig.add_axes(box(0.8, 0.55, 4.4, 0.18)),
        orientation="horizontal",
        extend="max",
        label="BRDF f (1/sr), log scale",
    )
    f_bar.ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    f_bar.ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    f_bar.ax.xaxis.set_minor_formatter(NullFormatter())
    bar = fig.colorbar(
        r_mesh,
        cax=fig.add_axes(box(6.3, 0.55, 2.4, 0.18)),
        orientation="horizontal",
        label="model vs traced, log scale",
    )
    bar.ax.xaxis.set_major_locator(FixedLocator([0.25, 0.5, 1.0, 2.0, 4.0]))
    bar.ax.xaxis.set_major_formatter(FixedFormatter(["-75%", "-50%", "0", "+100%", "+300%"]))
    bar.ax.xaxis.set_minor_locator(FixedLocator([]))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", metadata={"Software": None})
    return buffer.getvalue()
