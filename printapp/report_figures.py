"""The report's BRDF figure: hemispherical maps of the traced table, the compact model and their ratio."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
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


_COLORMAPS: dict[str, np.ndarray] = {}


def colormap(name: str) -> np.ndarray:
    """A colour map of the report (``magma`` or ``RdBu_r``): ``(256, 3)`` uint8 sRGB, matplotlib's
    colours as ``printapp/data/colormaps.toml`` keeps them (``scripts/make-colormaps.py``)."""
    if not _COLORMAPS:
        import tomllib
        from importlib.resources import files

        data = tomllib.loads(files("printapp").joinpath("data/colormaps.toml").read_text())
        for key, value in data.items():
            _COLORMAPS[key] = np.frombuffer(bytes.fromhex(value), dtype=np.uint8).reshape(256, 3)
    return _COLORMAPS[name]


def log_colours(values: np.ndarray, vmin: float, vmax: float, name: str) -> np.ndarray:
    """``values`` through a logarithmic scale from ``vmin`` to ``vmax`` into colour map ``name``:
    uint8 RGB, ``values.shape + (3,)``. Values off the scale take its end colours; as matplotlib's
    ``LogNorm`` and ``Colormap`` do (index ``floor(256 t)``, at most 255)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.log(values) - math.log(vmin)) / (math.log(vmax) - math.log(vmin))
    index = np.clip(np.floor(np.nan_to_num(t, nan=0.0, neginf=0.0, posinf=1.0) * 256.0), 0, 255)
    return colormap(name)[index.astype(np.intp)]


def _log_ticks(vmin: float, vmax: float) -> list[float]:
    """1, 2 and 5 times the powers of ten within [vmin, vmax] (the colour bar's labels)."""
    ticks = []
    for power in range(math.floor(math.log10(vmin)), math.ceil(math.log10(vmax)) + 1):
        for sub in (1.0, 2.0, 5.0):
            value = sub * 10.0**power
            if vmin <= value <= vmax:
                ticks.append(value)
    return ticks


def _font(size: int) -> Any:
    """DejaVu Sans (matplotlib's own font, found without importing matplotlib), else Pillow's."""
    from importlib.util import find_spec

    from PIL import ImageFont

    spec = find_spec("matplotlib")
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if path.is_file():
            return ImageFont.truetype(str(path), size)
    return ImageFont.load_default(size=size)


DISC_PX = 169
"""Diameter of each hemispherical map (pixels): one pixel a little over a degree of polar angle."""
EMPTY_RGB = (187, 187, 187)
"""Where the tracer left a bin empty (the difference map)."""


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

    Drawn with Pillow (the maps are arrays of colours; the rings, labels and colour bars are
    placed by hand): matplotlib's import and figure cost a design run about a second.

    Parameters
    ----------
    appearance : render.appearance.Appearance
        Its ``table`` (:class:`render.gonio.BrdfTable`) and ``fit.model``.
    """
    from PIL import Image, ImageDraw

    from printapp.exporters import png_bytes
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
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(traced > 0, fitted / traced, np.nan)
    ratio = np.clip(ratio, 1.0 / RATIO_RANGE, RATIO_RANGE)

    # Each map is the bins looked up on a disc of pixels (radius = polar angle).
    axis = np.linspace(-90.0, 90.0, DISC_PX)
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

    column_px, row_px, bars_px = 240, 240, 80
    width, height = 3 * column_px, row_px * len(rows) + bars_px
    canvas = np.full((height, width, 3), 255, dtype=np.uint8)
    scale = DISC_PX / 180.0  # pixels per degree
    centres = []
    for i in range(len(rows)):
        panels = (
            log_colours(np.clip(traced[i], vmin, None), vmin, vmax, "magma"),
            log_colours(np.clip(fitted[i], vmin, None), vmin, vmax, "magma"),
            log_colours(ratio[i], 1.0 / RATIO_RANGE, RATIO_RANGE, "RdBu_r"),
        )
        for j, colours in enumerate(panels):
            disc = colours[theta_bin, phi_bin]
            if j == 2:
                disc[np.isnan(ratio[i])[theta_bin, phi_bin]] = EMPTY_RGB
            cx, cy = column_px * j + column_px // 2, row_px * i + 50 + DISC_PX // 2
            window = canvas[
                cy - DISC_PX // 2 : cy - DISC_PX // 2 + DISC_PX,
                cx - DISC_PX // 2 : cx - DISC_PX // 2 + DISC_PX,
            ]
            window[inside] = disc[inside]
            centres.append((i, j, cx, cy))
    image = Image.fromarray(canvas)
    draw = ImageDraw.Draw(image)
    font, small = _font(11), _font(10)
    names = ("traced table f", "compact model f", "model vs traced")
    for i, j, cx, cy in centres:
        theta_i = math.degrees(math.acos(float(np.clip(wi[i, 2], -1.0, 1.0))))
        phi_i = math.degrees(math.atan2(wi[i, 1], wi[i, 0])) % 360.0
        title = f"{names[j]}\nlight from {theta_i:.0f}° polar, {phi_i:.0f}° azimuth"
        draw.multiline_text(
            (cx, cy - DISC_PX // 2 - 46), title, fill=(0, 0, 0), font=font, anchor="ma", align="center"
        )
        for ring_deg in (30.0, 60.0, 90.0):
            r = ring_deg * scale
            draw.ellipse((cx - r, cy - r, cx + r, cy + r), outline=(153, 153, 153), width=1)
        for angle, (dx, dy, anchor) in {
            0: (90 * scale + 4, 0, "lm"),
            90: (0, -90 * scale - 3, "mb"),
            180: (-90 * scale - 4, 0, "rm"),
            270: (0, 90 * scale + 3, "mt"),
        }.items():
            draw.text((cx + dx, cy + dy), f"{angle}°", fill=(0, 0, 0), font=small, anchor=anchor)

    def colour_bar(
        left: int, right: int, lo: float, hi: float, name: str, ticks: list[tuple[float, str]], label: str
    ) -> tuple[int, int]:
        """A horizontal bar of colour map ``name`` on a log scale from ``lo`` to ``hi``, with its
        ticks and label below; returns its top and height (pixels)."""
        top_px, bar_h = row_px * len(rows) + 12, 14
        span = right - left
        t = np.linspace(0.0, 1.0, span, endpoint=False) + 0.5 / span
        values = np.exp(math.log(lo) + t * (math.log(hi) - math.log(lo)))
        image.paste(
            Image.fromarray(np.repeat(log_colours(values, lo, hi, name)[None], bar_h, axis=0)), (left, top_px)
        )
        draw.rectangle((left, top_px, right - 1, top_px + bar_h - 1), outline=(0, 0, 0))
        for value, text in ticks:
            x = left + span * (math.log(value) - math.log(lo)) / (math.log(hi) - math.log(lo))
            draw.line((x, top_px + bar_h, x, top_px + bar_h + 3), fill=(0, 0, 0))
            draw.text((x, top_px + bar_h + 4), text, fill=(0, 0, 0), font=small, anchor="ma")
        middle = ((left + right) / 2, top_px + bar_h + 20)
        draw.text(middle, label, fill=(0, 0, 0), font=font, anchor="ma")
        return top_px, bar_h

    left, right = 64, 400
    ticks = [(value, f"{value:g}") for value in _log_ticks(vmin, vmax)]
    top_px, bar_h = colour_bar(left, right, vmin, vmax, "magma", ticks, "BRDF f (1/sr), log scale")
    # (An arrow at the right end: the brightest bins saturate the scale.)
    draw.polygon(
        [(right, top_px), (right + 12, top_px + bar_h // 2), (right, top_px + bar_h - 1)],
        fill=tuple(int(c) for c in colormap("magma")[255]),
        outline=(0, 0, 0),
    )
    ratio_ticks = list(zip((0.25, 0.5, 1.0, 2.0, 4.0), ("-75%", "-50%", "0", "+100%", "+300%"), strict=True))
    colour_bar(488, 680, 1.0 / RATIO_RANGE, RATIO_RANGE, "RdBu_r", ratio_ticks, "model vs traced, log scale")
    return png_bytes(np.asarray(image))
