"""``printapp fit``: noise parameters from a photo, how close they come, and a design that prints them.

The photo is read (EXIF orientation applied, 16-bit and palette images converted,
opaque alpha dropped), downsampled to at most ``max_side`` pixels and reduced to its
luminance (Rec. 709 weights on the stored sRGB values). Each model of
:mod:`printapp.fit_models` is fitted to the luminance; the fitted field, mapped to
luminance and through a 1-D palette of the photo's colours ordered along luminance,
is compared with the photo by three measures (spectrum, value distribution, GLCM) beside
two baselines computed in the same run:

* random parameters of the same model (every searched parameter drawn from the box
  the optimiser searches; the median of five draws, per measure), and
* the random-phase texture with the photo's exact Fourier moduli (Galerne et al. 2011):
  the closest any stationary Gaussian texture comes on the spectrum.

The score compares the fit with the photo's own variability: the same measures
between the photo's left and right halves, over those between each half and the
synthesis's other half, capped at one per measure and combined by their geometric mean,
times ``min(1, (side / 128)^2)`` for images too small to show their statistics. A score
near 1 means the fit is as close to the photo as the photo is to itself; below
:data:`LOW_SCORE` the fit comes with a warning that the model does not explain the image.
Pixel-by-pixel measures (SSIM, PSNR) are not used: two samples of the same stochastic
texture differ at every pixel.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from printapp.design import Texture
from printapp.errors import PrintappError
from printapp.fit_measures import Distances, Target, ValueMap, distances
from printapp.fit_models import MODELS, Grid, NoiseLookup, exact_noise
from printapp.fit_search import ModelFit, fit_model, lookup_extent, random_values, unfitted
from printapp.photo import LUMA, MIN_SIDE_PX, PALETTE_SIZE, Photo, hex_colour, luminance_palette, read_photo

RELIABLE_SIDE_PX = 128
"""Images smaller than this have their score scaled down by the area ratio."""
LOW_SCORE = 0.5
"""Scores below this come with a warning that the model does not explain the image."""
DEFAULT_BUDGET = 160
"""Objective evaluations per model."""
METHOD = {
    "log_spectrum_distance": "RMS, over the frequency samples from 2/N to 0.4 cycles/px, of log10 of the "
    "ratio of the Hann-windowed periodograms averaged in polar bins (half an octave x 30 degrees)",
    "wasserstein": "1-Wasserstein distance between the luminance distributions (luminance 0..1)",
    "glcm_difference": "RMS difference of GLCM contrast/((L^2-1)/6), homogeneity and correlation at "
    "1, 2, 4, 8, 16 px x 4 directions, 16 levels equalised on the photo (scikit-image)",
    "random_parameters": "median over 5 draws of every searched parameter from the optimiser's box",
    "random_phase": "the photo's Fourier moduli with random phases (Galerne, Gousseau & Morel 2011)",
    "score": "geometric mean over the measures of min(1, max(photo halves, invisible) / fit halves), "
    "times min(1, (side / 128)^2); invisible = 0.05 decades, 1/255, 0.03",
    "fit": "fbm, turbulence: expected radial spectrum (no synthesis) by grid + Nelder-Mead, then sign and "
    "skew of the value map by bounded Brent on Wasserstein + GLCM; marble: vein direction from the "
    "structure tensor, the rest by a Sobol scan + Nelder-Mead on syntheses at two scales (SciPy)",
}
INVISIBLE = {"spectrum": 0.05, "histogram": 1.0 / 255.0, "glcm": 0.03}
"""Differences too small to see: 0.05 decades of power (12 %), one grey level, 0.03 of a GLCM statistic."""
RANDOM_DRAWS = 5
REPORT_GLCM_DISTANCES = (1, 2, 4, 8, 16)


@dataclass
class ModelReport:
    """One fitted model: its parameters, the texture that reproduces it, and its measures."""

    name: str
    fit: ModelFit
    texture: Texture
    params: dict[str, Any]
    measures: Distances
    halves: Distances
    score: float
    lum: np.ndarray
    rgb: np.ndarray


@dataclass
class FitResult:
    """Everything ``printapp fit`` writes."""

    photo: Photo
    chosen: ModelReport
    reports: dict[str, ModelReport]
    random_parameters: Distances
    random_phase: Distances
    photo_halves: Distances
    random_phase_rgb: np.ndarray
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
            "measures": {
                "fit": _rounded(chosen.measures.as_dict()),
                "random_parameters": _rounded(self.random_parameters.as_dict()),
                "random_phase": _rounded(self.random_phase.as_dict()),
                "photo_halves": _rounded(self.photo_halves.as_dict()),
                "fit_halves": _rounded(chosen.halves.as_dict()),
            },
            "models": {
                name: {
                    "score": round(r.score, 4),
                    "objective": round(r.fit.objective, 5) if math.isfinite(r.fit.objective) else None,
                    "evaluations": r.fit.evaluations,
                    "measures": _rounded(r.measures.as_dict()),
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


def _halves(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left and right halves (along the longer axis), of equal size."""
    if image.shape[1] >= image.shape[0]:
        half = image.shape[1] // 2
        return image[:, :half], image[:, half : 2 * half]
    half = image.shape[0] // 2
    return image[:half], image[half : 2 * half]


def _half_targets(lum: np.ndarray) -> tuple[Target, Target]:
    return tuple(  # type: ignore[return-value]
        Target.of(h, f_max=0.4, glcm_distances=REPORT_GLCM_DISTANCES) for h in _halves(lum)
    )


def score_ratios(fit_halves: Distances, photo_halves: Distances) -> dict[str, float]:
    """Per measure, ``min(1, max(photo halves, floor) / fit halves)``: 1 where the fit is as close
    as the photo is to itself, or closer than the eye could tell (:data:`INVISIBLE`)."""
    ratios = {}
    for name, floor in INVISIBLE.items():
        own = max(getattr(photo_halves, name), floor)
        theirs = getattr(fit_halves, name)
        ratios[name] = min(1.0, own / theirs) if theirs > 0 else 1.0
    return ratios


def _score(fit_halves: Distances, photo_halves: Distances, side: int) -> float:
    ratios = score_ratios(fit_halves, photo_halves)
    geometric = math.prod(ratios.values()) ** (1.0 / len(ratios))
    return geometric * min(1.0, (side / RELIABLE_SIDE_PX) ** 2)


def fitted_texture(
    name: str,
    values: dict[str, Any],
    photo: Photo,
    scale_mm: float,
    seed: int,
    value_map: ValueMap | None = None,
    value_range: tuple[float, float] = (0.0, 1.0),
) -> Texture:
    """The design texture that reproduces a fitted model, ``scale_mm`` mm per analysed pixel.

    The palette spans ``value_range`` with :data:`PALETTE_SIZE` colours: the photo's
    mean colour at the luminance that ``value_map`` gives each value, so the palette
    carries the whole value-to-colour map. Numbers are rounded to 6 significant digits
    here, so the file holds exactly the texture that was measured.
    """
    common: dict[str, Any] = {
        "kind": name,
        "feature_size_mm": _round6(values["feature_px"] * scale_mm),
        "seed": seed,
    }
    if value_map is not None:
        lo, hi = value_range if value_range[1] > value_range[0] else (value_range[0], value_range[0] + 1.0)
        knots = np.linspace(_round6(lo), _round6(hi), PALETTE_SIZE)
        lum_knots, colours = luminance_palette(photo)
        lum = value_map(knots)
        palette = np.stack([np.interp(lum, lum_knots, colours[:, c]) for c in range(3)], axis=-1)
        common["palette"] = tuple(hex_colour(c) for c in palette)
        common["palette_range"] = (float(knots[0]), float(knots[-1]))
    if name == "fbm":
        extra = {
            "octaves": values["octaves"],
            "lacunarity": _round6(values["lacunarity"]),
            "H": _round6(values["H"]),
        }
    elif name == "turbulence":
        extra = {"low": 0, "high": values["octaves"] - 1}
    else:
        extra = {
            "low": 0,
            "high": values["octaves"] - 1,
            "vein_angle_rad": _round6(np.mod(values["angle"], math.pi)),
            "vein_period_mm": _round6(values["period_px"] * scale_mm),
            "turbulence_strength": _round6(values["strength"]),
            "vein_sharpness": _round6(values["sharpness"]),
        }
    return Texture.model_validate({**common, **extra})


def _round6(value: float) -> float:
    return float(f"{float(value):.6g}")


def _palette_span(s: np.ndarray, value_map: ValueMap) -> tuple[float, float]:
    """The values between which the luminance map is not clipped (the palette needs no more)."""
    order = np.sort(s.ravel())
    lum = value_map(order)
    inside = np.flatnonzero((lum > value_map.lo) & (lum < value_map.hi))
    if inside.size < 2:
        return float(order[0]), float(order[-1])
    first, last = max(inside[0] - 1, 0), min(inside[-1] + 1, order.size - 1)
    return float(order[first]), float(order[last])


def synthesise(texture: Texture, shape: tuple[int, int], scale_mm: float) -> np.ndarray:
    """The texture's values at the pixel centres of a ``shape`` image, ``scale_mm`` mm per pixel (rows up).

    The same evaluation as the design's tile relief and ``printapp texture --from``;
    marble gives its [0, 1] value whatever ``veins`` says.
    """
    from printapp.texture import evaluate_texture_grid
    from printapp.texture_kinds import vein_sign

    x_mm = (np.arange(shape[1]) + 0.5) * scale_mm
    y_mm = (np.arange(shape[0]) + 0.5) * scale_mm
    values = evaluate_texture_grid(x_mm, y_mm, texture, scale_mm)
    return vein_sign(texture) * values


def _reported_params(
    name: str, texture: Texture, values: dict[str, Any], value_map: ValueMap, photo: Photo
) -> dict[str, Any]:
    """Parameters in the photo's own pixels (before downsampling) and in mm, as metrics.json gives them."""
    px = photo.downscale
    feature_px = values["feature_px"] * px
    out: dict[str, Any] = {}
    if name == "fbm":
        out |= {
            "octaves": texture.octaves,
            "lacunarity": round(texture.lacunarity, 5),
            "H": round(texture.H, 5),
            "frequency": float(f"{1.0 / feature_px:.6g}"),
            "feature_size_px": round(feature_px, 4),
        }
    else:
        out |= {
            "octaves_low": texture.low,
            "octaves_high": texture.high,
            "octaves": texture.high - texture.low + 1,
        }
        if name == "turbulence":
            out |= {"frequency": float(f"{1.0 / feature_px:.6g}"), "feature_size_px": round(feature_px, 4)}
        else:
            period_px = values["period_px"] * px
            out |= {
                "vein_angle_deg": round(math.degrees(texture.vein_angle_rad), 3),
                "vein_frequency": float(f"{1.0 / period_px:.6g}"),
                "vein_period_px": round(period_px, 4),
                "vein_period_mm": float(f"{texture.vein_period_mm:.6g}"),
                "turbulence_strength": round(texture.turbulence_strength, 5),
                "turbulence_frequency": float(f"{1.0 / feature_px:.6g}"),
                "turbulence_feature_size_px": round(feature_px, 4),
                "vein_sharpness": round(texture.vein_sharpness, 5),
            }
    out |= {
        "feature_size_mm": float(f"{texture.feature_size_mm:.6g}"),
        "amplitude": float(f"{value_map.amplitude:.6g}"),
        "offset": float(f"{value_map.offset:.6g}"),
        "skew": round(value_map.skew, 5),
        "sign": value_map.sign,
        "seed": texture.seed,
        "palette": list(texture.palette or ()),
        "palette_range": [float(f"{v:.6g}") for v in texture.palette_range or ()],
    }
    return out


def _report_model(
    fit: ModelFit, photo: Photo, target: Target, halves: tuple[Target, Target], scale_mm: float, seed: int
) -> ModelReport:
    from printapp.texture import palette_colours

    name = fit.model.name
    # The values through the design's own evaluation; the palette then maps them to colour.
    s = synthesise(fitted_texture(name, fit.values, photo, scale_mm, seed), photo.lum.shape, scale_mm)
    value_map = ValueMap.fit(s, target, fit.values["sign"], fit.values.get("skew", 0.0))
    texture = fitted_texture(name, fit.values, photo, scale_mm, seed, value_map, _palette_span(s, value_map))

    rgb = palette_colours(s, texture)
    lum = rgb @ LUMA
    measures = distances(lum, target)
    left, right = _halves(lum)
    fit_halves = _mean_distances([distances(left, halves[1]), distances(right, halves[0])])
    return ModelReport(
        name=name,
        fit=fit,
        texture=texture,
        params=_reported_params(name, texture, fit.values, value_map, photo),
        measures=measures,
        halves=fit_halves,
        score=0.0,
        lum=lum,
        rgb=rgb,
    )


def _mean_distances(items: list[Distances]) -> Distances:
    return Distances(
        spectrum=float(np.mean([d.spectrum for d in items])),
        histogram=float(np.mean([d.histogram for d in items])),
        glcm=float(np.mean([d.glcm for d in items])),
    )


def _median_distances(items: list[Distances]) -> Distances:
    return Distances(
        spectrum=float(np.median([d.spectrum for d in items])),
        histogram=float(np.median([d.histogram for d in items])),
        glcm=float(np.median([d.glcm for d in items])),
    )


def fit_photo(
    source: str | Path | Photo,
    *,
    model: str = "auto",
    scale_mm_per_px: float | None = None,
    seed: int = 0,
    budget: int = DEFAULT_BUDGET,
    max_side: int = 512,
    timer=None,
) -> FitResult:
    """Fit noise models to a photo and measure the fit beside the two baselines.

    Parameters
    ----------
    source : path or :class:`Photo`
    model : {"auto", "fbm", "turbulence", "marble"}
        ``"auto"`` fits all three and keeps the best score (ties: the simpler model).
    scale_mm_per_px : float, optional
        Millimetres per pixel of the original image, for the design fragment's lengths;
        default: the image's width spans a 20 mm tile.
    seed : int
        Seed of the synthesis (the noise), of the optimiser's scan and of the baselines.
    budget : int
        Objective evaluations per model.
    max_side : int
        The photo is analysed at most this many pixels on its longer side.
    timer : printapp.progress.StageTimer, optional
        Shows and times the stages.

    Raises
    ------
    PrintappError
        For unreadable or unusable images, or out-of-range options.
    """
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

    def stage(name: str, label: str):
        return timer.stage(name, label) if timer is not None else contextlib.nullcontext()

    start = time.perf_counter()
    with stage("read", "reading the photo"):
        photo = source if isinstance(source, Photo) else read_photo(source, max_side)
    lum = photo.lum
    side = min(lum.shape)
    original_scale = scale_mm_per_px if scale_mm_per_px is not None else 20.0 / photo.original_px[0]
    scale_mm = original_scale * photo.downscale  # mm per analysed pixel
    warnings: list[str] = []
    constant = float(lum.std()) < 0.5 / 255.0
    if constant:
        warnings.append(
            f"the image is constant (luminance standard deviation {lum.std():.2g}): there is no "
            "texture to fit, and the fitted parameters mean nothing"
        )
    target = Target.of(lum, f_max=0.4, glcm_distances=REPORT_GLCM_DISTANCES)
    halves = _half_targets(lum)
    left, right = _halves(lum)
    photo_halves = _mean_distances([distances(left, halves[1]), distances(right, halves[0])])
    names = list(MODELS) if model == "auto" else [model]
    lookup = NoiseLookup(lookup_extent(lum.shape), seed)
    reports: dict[str, ModelReport] = {}
    for name in names:
        with stage(f"fit_{name}", f"fitting {name}"):
            if constant:
                fit = unfitted(name, lum)  # nothing to match: the middle of the box, said so
            else:
                fit = fit_model(name, lum, target, seed=seed, budget=budget, lookup=lookup)
            report = _report_model(fit, photo, target, halves, scale_mm, seed)
            report.score = 0.0 if constant else _score(report.halves, photo_halves, side)
            reports[name] = report
    chosen = max(reports.values(), key=lambda r: (round(r.score, 6), -names.index(r.name)))
    with stage("baselines", "baselines (random parameters, random phase)"):
        rng = np.random.default_rng(seed + 1)
        grid = Grid.of(lum.shape, lum.shape)
        draws = []
        for _ in range(RANDOM_DRAWS):
            values = random_values(chosen.fit.model, rng, grid.pitch_px)
            s = chosen.fit.model.field(values, grid, exact_noise(seed))
            lum_random = ValueMap.fit(s, target, values["sign"], values.get("skew", 0.0))(s)
            draws.append(distances(lum_random, target))
        random_parameters = _median_distances(draws)
        from noise.spectra import random_phase

        phase_rgb = np.clip(random_phase(photo.rgb, seed), 0.0, 1.0)
        phase_distances = distances(phase_rgb @ LUMA, target)
    if not constant:
        if min(photo.analysed_px) < RELIABLE_SIDE_PX:
            warnings.append(
                f"the image is only {photo.analysed_px[0]} x {photo.analysed_px[1]} px: too few features "
                f"for reliable statistics (the score is scaled by the area against {RELIABLE_SIDE_PX}^2 px)"
            )
        if chosen.score < LOW_SCORE:
            warnings.append(
                f"the {chosen.name} model does not explain this image (score {chosen.score:.2f} "
                f"< {LOW_SCORE}): its statistics are further from the photo's than the photo's halves "
                "are from each other; the image may not be noise-like (regular patterns, edges, "
                "tiles), so treat the parameters as a rough guess"
            )
        worse = [
            measure
            for measure in ("spectrum", "histogram", "glcm")
            if getattr(chosen.measures, measure) >= getattr(random_parameters, measure)
        ]
        if worse:
            warnings.append(
                f"the fit is no closer than random {chosen.name} parameters on: {', '.join(worse)}"
            )
    return FitResult(
        photo=photo,
        chosen=chosen,
        reports=reports,
        random_parameters=random_parameters,
        random_phase=phase_distances,
        photo_halves=photo_halves,
        random_phase_rgb=phase_rgb,
        score=chosen.score,
        warnings=warnings,
        scale_mm_per_px=original_scale,
        seed=seed,
        budget=budget,
        seconds=time.perf_counter() - start,
    )
