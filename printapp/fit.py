"""``printapp fit``: a printable texture like a photo, how close it comes, and a design that prints it.

The photo is read (EXIF orientation applied, 16-bit and palette images converted,
opaque alpha dropped), downsampled to at most ``max_side`` pixels and reduced to its
luminance (Rec. 709 weights on the stored sRGB values). Each model of
:mod:`printapp.fit_models` is fitted to the luminance: fBm and turbulence on their
expected spectrum (:mod:`printapp.fit_spectral`), marble and branching veins on
syntheses, coarse to fine, by a global search (:mod:`printapp.fit_search`). The fitted
texture is then evaluated exactly, as a design evaluates it; its values are mapped to
the photo's colours by a palette that matches the photo's luminance distribution
quantile by quantile, and compared with the photo by the measures of
:mod:`printapp.fit_measures` (spectrum, orientation, values, lines, layout) beside the
random-phase texture with the photo's exact Fourier moduli (Galerne et al. 2011; the
closest any stationary Gaussian texture comes on the spectrum).

Each measure is a ratio to the photo's own variation (its left half against its
right half; 1 = as close to the photo as the photo is to itself). The score is the
geometric mean over the measures of ``min(1, 1 / ratio)``, times ``min(1, (side / 128)^2)``
for images too small to show their statistics; below :data:`LOW_SCORE`, or with a measure
more than :data:`FAR_RATIO` times the photo's own variation, the fit comes with a warning
that the model does not explain the image. ``auto`` keeps the model whose
worst measure is closest (a texture is as far from the photo as its worst measure),
then the best score.
Pixel-by-pixel measures (SSIM, PSNR) are not used: two samples of the same stochastic
texture differ at every pixel.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from printapp.design import Texture
from printapp.errors import PrintappError
from printapp.fit_measures import (
    MEASURES,
    Distances,
    Stats,
    half_stats,
    halves_distance,
    line_maps,
    own_distance,
    ratios,
)
from printapp.fit_models import MODELS, SYNTHESISED, Hints, Model, make_model
from printapp.photo import LUMA, MIN_SIDE_PX, Photo, hex_colour, luminance_palette, read_photo

STEP = math.log(1.02)
PARSIMONY = 1.10
"""How much worse (worst measure's ratio) a simpler model may be and still be chosen over a richer one."""
"""Worst measures within 2 % of each other tie when ``auto`` chooses a model."""
RELIABLE_SIDE_PX = 128
"""Images smaller than this have their score scaled down by the area ratio."""
LOW_SCORE = 0.5
"""Scores below this come with a warning that the model does not explain the image."""
FAR_RATIO = 3.5
"""... and so does a measure more than this many times further from the photo than its halves are."""
DEFAULT_BUDGET = 90
"""Objective evaluations of the veins' search (the marble's gets a share by its parameters)."""
TABLE_PERIOD = 32.0
"""Period (noise cells) of the noise tables the search reads."""
QUANTILE_KNOTS = 64
"""Colours in a fitted palette (each at a quantile of the texture's values)."""
METHOD = {
    "spectrum": "RMS over half-octave bins (1 cycle per image to Nyquist, equal weight per octave) of the "
    "log10 ratio of the radially averaged Hann-windowed periodograms (decades)",
    "orientation": "RMS over octave bands x 8 angles of the log10 power less each band's mean (decades)",
    "values": "1-Wasserstein distance of each sRGB channel's distribution, averaged (0..1)",
    "lines": "RMS of per scale (1, 2, 4, 8 px) and polarity: log10 mean, 90th and 99th percentile of the "
    "Hessian line strength, and the correlation of strengths across neighbouring scales",
    "layout": "RMS of the half-octave log spectra of the three finest line-strength maps, each over its mean",
    "continuity": "RMS over the finest two scales and both polarities of log10(chance / 1 %) that a pixel in "
    "the top 1 % of line strength has one 4, 8, 16, 32 px along its line's direction too",
    "ratio": "each measure over the photo's own (left half against right, bottom against top; the fit's "
    "halves against the photo's other halves), both floored at what is too small to see",
    "score": "geometric mean over the measures of min(1, 1 / ratio), times min(1, (side / 128)^2)",
    "random_phase": "the photo's Fourier moduli with random phases (Galerne, Gousseau & Morel 2011)",
    "fit": "fbm, turbulence: expected spectrum in quarter-octave bins (no synthesis), grid + Nelder-Mead; "
    "marble, veined: R_d scan at 128 px, then CMA-ES at 128 px and on 128 px windows at full resolution, "
    "noise from tables with its spectrum; veined: the five best points measured on the texture itself, "
    "the best kept; values matched to the photo quantile by quantile",
}


@dataclass
class ModelReport:
    """One fitted model: its parameters, the texture that prints it, and how close it comes."""

    name: str
    values: dict[str, Any]
    texture: Texture
    params: dict[str, Any]
    halves: Distances
    """The measures between the fit and the photo, half against half (:func:`halves_distance`)."""
    ratios: dict[str, float]
    score: float
    objective: float
    evaluations: int
    trace: list[tuple[int, float]]
    seconds: float
    lum: np.ndarray
    rgb: np.ndarray


@dataclass
class FitResult:
    """Everything ``printapp fit`` writes."""

    photo: Photo
    chosen: ModelReport
    reports: dict[str, ModelReport]
    random_phase_halves: Distances
    random_phase_rgb: np.ndarray
    photo_halves: Distances
    score: float
    warnings: list[str]
    scale_mm_per_px: float
    seed: int
    budget: int
    seconds: float

    def metrics(self) -> dict[str, Any]:
        """The content of ``metrics.json``."""
        chosen = self.chosen
        return {
            "image": self.photo.path,
            "image_px": list(self.photo.original_px),
            "analysed_px": list(self.photo.analysed_px),
            "image_notes": self.photo.notes,
            "scale_mm_per_px": self.scale_mm_per_px,
            "seed": self.seed,
            "model": chosen.name,
            "params": chosen.params,
            "score": round(self.score, 4),
            "warnings": self.warnings,
            "ratios": {
                "fit": _rounded(chosen.ratios),
                "random_phase": _rounded(ratios(self.random_phase_halves, self.photo_halves)),
            },
            "measures": {
                "fit": _rounded(chosen.halves.as_dict()),
                "random_phase": _rounded(self.random_phase_halves.as_dict()),
                "photo_halves": _rounded(self.photo_halves.as_dict()),
            },
            "models": {
                name: {
                    "score": round(r.score, 4),
                    "ratios": _rounded(r.ratios),
                    "objective": round(r.objective, 5) if math.isfinite(r.objective) else None,
                    "evaluations": r.evaluations,
                    "seconds": round(r.seconds, 3),
                    "measures": _rounded(r.halves.as_dict()),
                    "params": r.params,
                }
                for name, r in self.reports.items()
            },
            "budget_per_model": self.budget,
            "fit_seconds": round(self.seconds, 3),
            "method": METHOD,
        }


def _rounded(values: dict[str, float]) -> dict[str, float]:
    return {k: float(f"{v:.5g}") for k, v in values.items()}


def _round6(value: float) -> float:
    return float(f"{float(value):.6g}")


def score_of(r: dict[str, float], side: int) -> float:
    """Geometric mean over the measures of ``min(1, 1 / ratio)``, scaled down for small images."""
    geometric = math.prod(min(1.0, 1.0 / v) for v in r.values()) ** (1.0 / len(r))
    return geometric * min(1.0, (side / RELIABLE_SIDE_PX) ** 2)


def fitted_texture(
    model: Model, values: dict[str, Any], scale_mm: float, seed: int, palette: dict[str, Any] | None = None
) -> Texture:
    """The design texture of fitted ``values`` (lengths in analysed px), ``scale_mm`` mm per analysed px.

    Numbers are rounded to 6 significant digits here, so the file holds exactly the
    texture that was measured.
    """
    fields: dict[str, Any] = {}
    for key, value in model.texture_fields(values).items():
        if key.endswith("_mm"):
            value = value * scale_mm
        fields[key] = _round6(value) if isinstance(value, float) else value
    return Texture.model_validate({**fields, "seed": seed, **(palette or {})})


def quantile_palette(s: np.ndarray, sign: float, photo: Photo) -> dict[str, Any]:
    """A palette that maps the texture's values onto the photo's colours quantile by quantile.

    :data:`QUANTILE_KNOTS` knots sit at quantiles of the values (denser in the tails, where
    veins are: probabilities spaced evenly in ``Phi^-1``, the normal quantile function,
    from 0.1 % to 99.9 %, and the extremes); knot ``v`` at probability ``q`` gets the
    photo's mean colour at its luminance quantile ``q`` (``1 - q`` for ``sign < 0``, low
    values bright). Matching the photo's luminance distribution this way is exact up to the
    palette's linear interpolation between knots.
    """
    from scipy.special import ndtr

    order = np.sort(s, axis=None)
    probabilities = np.concatenate([[0.0], ndtr(np.linspace(-3.09, 3.09, QUANTILE_KNOTS - 2)), [1.0]])
    knots = np.array([_round6(v) for v in np.quantile(order, probabilities)])
    keep = np.concatenate([[True], np.diff(knots) > 0])
    knots, probabilities = knots[keep], probabilities[keep]
    if knots.size < 2:
        knots, probabilities = np.array([knots[0], knots[0] + 1.0]), np.array([0.0, 1.0])
    lum_sorted = np.sort(photo.lum, axis=None)
    fraction = probabilities if sign > 0 else 1.0 - probabilities
    lum = np.quantile(lum_sorted, fraction)
    lum_knots, colours = luminance_palette(photo)
    rgb = np.stack([np.interp(lum, lum_knots, colours[:, c]) for c in range(3)], axis=-1)
    return {
        "palette": tuple(hex_colour(c) for c in rgb),
        "palette_values": tuple(float(v) for v in knots),
    }


def synthesise(texture: Texture, shape: tuple[int, int], scale_mm: float) -> np.ndarray:
    """The texture's values at the pixel centres of a ``shape`` image, ``scale_mm`` mm per pixel (rows up).

    The same evaluation as ``printapp texture --from``: a design's (with the veins
    raised or sunk as ``veins`` says), every octave the pixels resolve.
    """
    from printapp.texture import evaluate_texture_grid

    x_mm = (np.arange(shape[1]) + 0.5) * scale_mm
    y_mm = (np.arange(shape[0]) + 0.5) * scale_mm
    return evaluate_texture_grid(x_mm, y_mm, texture, scale_mm)


def reported_params(model: Model, values: dict[str, Any], texture: Texture, photo: Photo) -> dict[str, Any]:
    """Parameters in the photo's own pixels (before downsampling), mm and degrees: metrics.json's."""
    px = photo.downscale
    out: dict[str, Any] = {"sign": values["sign"]}
    feature_px = values["feature_px"] * px
    if model.name in ("fbm", "turbulence", "veined"):
        out |= {
            "octaves": values.get("octaves", texture.octaves),
            "H": round(values.get("H", 1.0), 5),
            "lacunarity": round(values.get("lacunarity", 2.0), 5),
            "frequency": float(f"{1.0 / feature_px:.6g}"),
            "feature_size_px": round(feature_px, 4),
        }
    if model.name == "marble":
        period_px = values["period_px"] * px
        out |= {
            "vein_angle_deg": round(math.degrees(texture.vein_angle_rad), 3),
            "vein_period_px": round(period_px, 4),
            "vein_frequency": float(f"{1.0 / period_px:.6g}"),
            "vein_period_mm": texture.vein_period_mm,
            "turbulence_strength": round(texture.turbulence_strength, 5),
            "turbulence_feature_size_px": round(feature_px, 4),
            "octaves": texture.high - texture.low + 1,
            "vein_sharpness": round(texture.vein_sharpness, 5),
        }
    if model.name == "veined":
        vein_px = values["vein_px"] * px
        out |= {
            "vein_network": texture.vein_network,
            "vein_period_px": round(vein_px, 4),
            "vein_scale_mm": texture.vein_scale_mm,
            "vein_angle_deg": round(math.degrees(texture.angle_rad), 3),
            "vein_stretch": round(texture.stretch, 5),
            "vein_width": round(texture.vein_width, 5),
            "vein_sharpness": round(texture.vein_sharpness, 5),
            "vein_gain": round(texture.vein_gain, 5),
            "vein_H": round(texture.vein_H, 5),
            "vein_warp": round(texture.vein_warp, 5),
            "vein_fade": round(texture.vein_fade, 5),
            "ground_weight": round(texture.ground_weight, 5),
            "ground_H": round(texture.ground_H, 5),
        }
    out |= {
        "feature_size_mm": texture.feature_size_mm,
        "seed": texture.seed,
        "palette": list(texture.palette or ()),
        "palette_values": list(texture.palette_values or ()),
    }
    return out


def _check(
    model: str, budget: int, max_side: int, scale_mm_per_px: float | None, seed: int, workers: int
) -> None:
    if model not in ("auto", *MODELS):
        raise PrintappError(f"--model: expected auto, {', '.join(MODELS)}; got '{model}'")
    if not (isinstance(budget, int) and budget >= 8):
        raise PrintappError(f"--budget: expected an integer of at least 8 evaluations, got {budget}")
    if not (isinstance(max_side, int) and max_side >= MIN_SIDE_PX):
        raise PrintappError(f"--size: expected at least {MIN_SIDE_PX} px, got {max_side}")
    if scale_mm_per_px is not None and not (math.isfinite(scale_mm_per_px) and scale_mm_per_px > 0):
        raise PrintappError(f"--scale-mm-per-px: expected a positive number, got {scale_mm_per_px}")
    if not (isinstance(seed, int) and 0 <= seed < 2**63):
        raise PrintappError(f"--seed: expected an integer in [0, 2^63), got {seed}")
    if not (isinstance(workers, int) and 1 <= workers <= 64):
        raise PrintappError(f"--workers: expected an integer in 1..64, got {workers}")


def default_workers() -> int:
    """The cores this process may use (at most 8)."""
    try:
        return max(1, min(8, len(os.sched_getaffinity(0))))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, min(8, os.cpu_count() or 1))


def fit_photo(
    source: str | Path | Photo,
    *,
    model: str = "auto",
    scale_mm_per_px: float | None = None,
    seed: int = 0,
    budget: int = DEFAULT_BUDGET,
    max_side: int = 512,
    workers: int | None = None,
    timer=None,
) -> FitResult:
    """Fit texture models to a photo and measure each fit beside the random-phase baseline.

    Parameters
    ----------
    source : path or :class:`Photo`
    model : {"auto", "fbm", "turbulence", "marble", "veined"}
        ``"auto"`` fits all and keeps the simplest (fbm, turbulence, marble, veined) whose worst
        measure's ratio is within :data:`PARSIMONY` of the smallest (then the best score).
    scale_mm_per_px : float, optional
        Millimetres per pixel of the original image, for the design fragment's lengths;
        default: the image's width spans a 20 mm tile.
    seed : int
        Seed of the noise (the synthesis and the baseline). The optimiser has its own fixed seed.
    budget : int
        Coarse objective evaluations per synthesised model.
    max_side : int
        The photo is analysed at most this many pixels on its longer side.
    workers : int, optional
        Threads that evaluate the optimiser's populations (default: the cores available);
        results do not depend on it.
    timer : printapp.progress.StageTimer, optional
        Shows and times the stages.

    Raises
    ------
    PrintappError
        For unreadable or unusable images, or out-of-range options.
    """
    workers = default_workers() if workers is None else workers
    _check(model, budget, max_side, scale_mm_per_px, seed, workers)

    def stage(name: str, label: str):
        return timer.stage(name, label) if timer is not None else contextlib.nullcontext()

    start = time.perf_counter()
    with stage("read", "reading the photo"):
        photo = source if isinstance(source, Photo) else read_photo(source, max_side)
        lum = photo.lum
        original_scale = scale_mm_per_px if scale_mm_per_px is not None else 20.0 / photo.original_px[0]
        scale_mm = original_scale * photo.downscale  # mm per analysed pixel
        constant = float(lum.std()) < 0.5 / 255.0
        maps = line_maps(lum)
        photo_halves_stats = half_stats(lum, photo.rgb, maps)
        photo_halves = own_distance(photo_halves_stats)
        hints = Hints.of(lum, maps.strengths)
        search_state: dict[str, Any] = {"maps": maps}
    names = list(MODELS) if model == "auto" else [model]
    reports: dict[str, ModelReport] = {}
    spectral: dict[str, tuple[dict[str, Any], float, int]] = {}
    for name in names:
        with stage(f"fit_{name}", f"fitting {name}"):
            t0 = time.perf_counter()
            if name == "veined" and not constant:
                # The veins' ground starts from the photo's own fBm (its spectrum).
                from printapp.fit_spectral import fit_spectral

                ground = spectral["fbm"][0] if "fbm" in spectral else fit_spectral("fbm", lum)[0]
                hints = dataclasses.replace(hints, ground=ground)
            m = make_model(name, hints)
            if constant:
                values, objective, evaluations, trace = m.neutral(), math.nan, 0, []
            elif name in SYNTHESISED:
                values, objective, evaluations, trace, finalists = _fit_synthesised(
                    m, lum, seed, budget, workers, search_state
                )
            else:
                from printapp.fit_spectral import fit_spectral

                spectral[name] = fit_spectral(name, lum)
                values, objective, evaluations = spectral[name]
                values, trace = _with_sign(m, values, lum, seed, search_state), []
            if constant or name not in SYNTHESISED:
                report = _report(m, values, photo, photo_halves_stats, photo_halves, scale_mm, seed)
            else:
                # The finalists measured on the texture itself: the one whose worst measure is best.
                photo_stats = (photo_halves_stats, photo_halves)
                candidates = [_report(m, v, photo, *photo_stats, scale_mm, seed) for _, v in finalists]
                best = min(range(len(candidates)), key=lambda k: (max(candidates[k].ratios.values()), k))
                report, objective = candidates[best], finalists[best][0]
            report.objective, report.evaluations, report.trace = objective, evaluations, trace
            report.seconds = time.perf_counter() - t0
            if constant:
                report.score = 0.0
            reports[name] = report
    # A texture is as far from the photo as its worst measure: a noise that misses the veins
    # is wrong however close its spectrum. A richer model must earn its place: the simplest
    # model whose worst measure is within PARSIMONY of the best is kept (veins drawn through
    # gravel scored 1.82 against turbulence's 1.83; a person sees cracks that are not there).
    # Ties (the worst measure within 2 %) go to the score.
    best_worst = min(max(r.ratios.values()) for r in reports.values())
    plausible = [r for r in reports.values() if max(r.ratios.values()) <= PARSIMONY * best_worst]
    chosen = min(
        plausible,
        key=lambda r: (names.index(r.name), round(math.log(max(r.ratios.values())) / STEP), -r.score),
    )
    with stage("baseline", "random-phase baseline"):
        from noise.spectra import random_phase

        phase_rgb = np.clip(random_phase(photo.rgb, seed), 0.0, 1.0)
        phase_halves = halves_distance(half_stats(phase_rgb @ LUMA, phase_rgb), photo_halves_stats)
    warnings = _warnings(photo, chosen, constant, lum)
    return FitResult(
        photo=photo,
        chosen=chosen,
        reports=reports,
        random_phase_halves=phase_halves,
        random_phase_rgb=phase_rgb,
        photo_halves=photo_halves,
        score=chosen.score,
        warnings=warnings,
        scale_mm_per_px=original_scale,
        seed=seed,
        budget=budget,
        seconds=time.perf_counter() - start,
    )


def _warnings(photo: Photo, chosen: ModelReport, constant: bool, lum: np.ndarray) -> list[str]:
    if constant:
        return [
            f"the image is constant (luminance standard deviation {lum.std():.2g}): there is no "
            "texture to fit, and the fitted parameters mean nothing"
        ]
    out = []
    if min(photo.analysed_px) < RELIABLE_SIDE_PX:
        out.append(
            f"the image is only {photo.analysed_px[0]} x {photo.analysed_px[1]} px: too few features "
            f"for reliable statistics (the score is scaled by the area against {RELIABLE_SIDE_PX}^2 px)"
        )
    worst = max(chosen.ratios, key=chosen.ratios.get)
    if chosen.score < LOW_SCORE or chosen.ratios[worst] > FAR_RATIO:
        out.append(
            f"the {chosen.name} model does not explain this image (score {chosen.score:.2f}; worst on "
            f"{worst}, {chosen.ratios[worst]:.1f} times the photo's own variation): the image may not be "
            "noise-like (regular patterns, edges, tiles), so treat the parameters as a rough guess"
        )
    return out


def _search_setup(lum: np.ndarray, seed: int, state: dict[str, Any]) -> tuple[list, Any]:
    """The search's levels and noise tables, made once per photo and shared by the models."""
    if "levels" not in state:
        from noise.tables import NoiseTable
        from printapp.fit_search import coarse_level, window_level

        levels = [coarse_level(lum)]
        window = window_level(lum, state.get("maps"))
        if window is not None:
            levels.append(window)
        state["levels"], state["table"] = levels, NoiseTable(TABLE_PERIOD, seed)
    return state["levels"], state["table"]


def _fit_synthesised(
    m: Model, lum: np.ndarray, seed: int, budget: int, workers: int, state: dict[str, Any]
) -> tuple[dict[str, Any], float, int, list, list]:
    from printapp.fit_search import search

    levels, table = _search_setup(lum, seed, state)
    # The budget is the veins' (nine parameters); the marble searches three.
    share = budget if m.name == "veined" else max(8, budget * len(m.params()) // 18)
    found = search(m, levels, table, seed, share, workers, starts=m.starts())
    finalists = found.candidates if m.name == "veined" else found.candidates[:1]
    return found.values, found.objective, found.evaluations, found.trace, finalists


def _with_sign(
    m: Model, values: dict[str, Any], lum: np.ndarray, seed: int, state: dict[str, Any]
) -> dict[str, Any]:
    """The sign (high values bright or dark) that brings the coarse level closest."""
    from printapp.fit_measures import match_values

    levels, table = _search_setup(lum, seed, state)
    level = levels[0]
    s = level.synthesise(m, {**values, "sign": 1.0}, table, seed)
    costs = {sign: level.cost(match_values(s, level.sorted_lum, sign)) for sign in (1.0, -1.0)}
    return {**values, "sign": min(costs, key=costs.get)}


def _report(
    m: Model,
    values: dict[str, Any],
    photo: Photo,
    photo_halves_stats: tuple[Stats, ...],
    photo_halves: Distances,
    scale_mm: float,
    seed: int,
) -> ModelReport:
    from printapp.texture import palette_colours

    texture = fitted_texture(m, values, scale_mm, seed)
    s = synthesise(texture, photo.lum.shape, scale_mm)
    texture = fitted_texture(m, values, scale_mm, seed, quantile_palette(s, values["sign"], photo))
    rgb = palette_colours(s, texture)
    lum = rgb @ LUMA
    fit_halves = halves_distance(half_stats(lum, rgb), photo_halves_stats)
    r = ratios(fit_halves, photo_halves)
    return ModelReport(
        name=m.name,
        values=values,
        texture=texture,
        params=reported_params(m, values, texture, photo),
        halves=fit_halves,
        ratios=r,
        score=score_of(r, min(photo.lum.shape)),
        objective=math.nan,
        evaluations=0,
        trace=[],
        seconds=0.0,
        lum=lum,
        rgb=rgb,
    )


__all__ = ["LOW_SCORE", "MEASURES", "FitResult", "ModelReport", "fit_photo", "score_of"]
