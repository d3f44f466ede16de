"""How ``printapp fit`` searches a model's parameters (see :mod:`printapp.fit_models` for the
objective): a fixed quasi-random scan of the box, then Nelder-Mead from the best starts,
on the photo downsampled to about 128 px; fBm and turbulence are first matched on their
expected spectra without synthesis. Everything is seeded: a fit is deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from noise.spectra import (
    expected_spectrum_operator,
    interpolate_psd,
    polar_bins,
    polar_spectrum,
    scn_slice_psd,
)
from printapp.fit_measures import Target, ValueMap, distances, glcm_features, objective_value
from printapp.fit_models import (
    FBM,
    MAX_OCTAVES,
    OBJECTIVE_SIDE,
    SKEW,
    Grid,
    Marble,
    Model,
    NoiseLookup,
    OctaveModel,
    exact_noise,
    kept_octaves,
    make_model,
)

# ---------------------------------------------------------------------------------------------
# The optimiser


@dataclass
class ModelFit:
    """What the optimiser found for one model."""

    model: Model
    values: dict[str, Any]
    objective: float
    evaluations: int
    trace: list[tuple[int, float]] = field(default_factory=list)
    """(evaluations so far, best objective so far) after each improvement."""


def _downsample(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Lanczos resampling to ``shape`` (Pillow, float32): anti-aliased, flat almost to Nyquist."""
    from PIL import Image

    if image.shape == shape:
        return image.astype(np.float64)
    im = Image.fromarray(image.astype(np.float32), mode="F")
    return np.asarray(im.resize((shape[1], shape[0]), Image.Resampling.LANCZOS), dtype=np.float64)


def objective_shape(shape: tuple[int, int]) -> tuple[int, int]:
    factor = max(1.0, max(shape) / OBJECTIVE_SIDE)
    return max(8, round(shape[0] / factor)), max(8, round(shape[1] / factor))


@dataclass(frozen=True)
class Scale:
    """One resolution the objective looks at: the photo's statistics there and the synthesis grid."""

    target: Target
    grid: Grid


def objective_scales(lum: np.ndarray, isotropic: bool) -> list[Scale]:
    """The objective's two views of a photo: all of it at about 128 px, and 128 px patches at full size.

    The first holds the large features (base frequency, vein period and direction),
    the second the fine ones (roughness, octaves, the veins' width), each with the
    frequency band its pixels resolve; an image of at most 128 px is one view.
    """
    n_angular = 1 if isotropic else 6
    scales = []
    small_shape = objective_shape(lum.shape)
    if small_shape != lum.shape:
        small = _downsample(lum, small_shape)
        target = Target.of(small, f_max=0.25, glcm_distances=(1, 2, 4), n_angular=n_angular)
        scales.append(Scale(target, Grid.of(small_shape, lum.shape)))
    tile = (min(lum.shape[0], OBJECTIVE_SIDE), min(lum.shape[1], OBJECTIVE_SIDE))
    target = Target.of(lum, f_max=0.4, glcm_distances=(1, 2, 4), n_angular=n_angular, tile=tile)
    grid = Grid((np.arange(tile[1]) + 0.5), (np.arange(tile[0]) + 0.5), 1.0)
    scales.append(Scale(target, grid))
    return scales


def lookup_extent(lum_shape: tuple[int, int]) -> float:
    """Noise units the objective's grids reach: cells of at least two pixels over at most 128 px."""
    return max(objective_shape(lum_shape)) / 2.0 + 2.0


def _scan_then_simplex(
    evaluate: Callable[[np.ndarray, dict[str, Any]], float],
    n_params: int,
    choices: list[dict[str, Any]],
    n_scan: int,
    budget: int,
    seed: int,
    guess: int | None = None,
    n_starts: int = 2,
    per_choice: bool = False,
    grid: list[int] | None = None,
) -> None:
    """Scan the unit box (scrambled Sobol, seeded) for every choice, then Nelder-Mead from the best starts.

    ``budget`` Nelder-Mead evaluations are shared by the ``n_starts`` best scanned
    points (one start when the budget is under 40); with ``per_choice``, by the best
    point of each discrete choice instead, so that no choice is left unpolished.

    ``guess`` names a parameter whose scan is concentrated on half of the starts near
    the middle of its range (where a closed-form estimate put it). ``grid`` replaces
    the Sobol scan by a full grid with that many points per parameter (cell centres).
    """
    from scipy.optimize import minimize
    from scipy.stats import qmc

    if grid is not None:
        axes = [(np.arange(k) + 0.5) / k for k in grid]
        starts = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=-1)
    else:
        sobol = qmc.Sobol(n_params, scramble=True, seed=seed)
        starts = sobol.random(1 << max(2, math.ceil(math.log2(n_scan))))[:n_scan]
    if guess is not None:
        starts[::2, guess] = 0.5 + 0.15 * (starts[::2, guess] - 0.5)
    scanned = []
    for choice in choices:
        for u in starts:
            scanned.append((evaluate(u, choice), tuple(u), choice))
    scanned.sort(key=lambda item: item[0])
    if per_choice:
        firsts = {}
        for item in scanned:
            firsts.setdefault(repr(sorted(item[2].items())), item)
        starts_list = sorted(firsts.values(), key=lambda item: item[0])
        n_starts = len(starts_list)
    else:
        n_starts = n_starts if budget >= 40 else 1
        starts_list = scanned[:n_starts]
    for _, u0, choice in starts_list:
        if budget <= 0:
            break
        simplex = [np.array(u0)]
        for k in range(n_params):
            step = np.array(u0)
            step[k] += 0.12 if step[k] < 0.5 else -0.12
            simplex.append(step)
        minimize(
            evaluate,
            np.array(u0),
            args=(choice,),
            method="Nelder-Mead",
            bounds=[(0.0, 1.0)] * n_params,
            options={
                "maxfev": max(1, budget // n_starts),
                "initial_simplex": np.array(simplex),
                "xatol": 1e-3,
                "fatol": 1e-5,
            },
        )


def _fit_by_synthesis(
    name: str, lum: np.ndarray, *, seed: int, budget: int, lookup: NoiseLookup | None
) -> ModelFit:
    """Fit a model on syntheses: the objective sums :func:`objective_value` over :func:`objective_scales`.

    Half the budget scans the box for every discrete choice, half runs Nelder-Mead.
    """
    model = make_model(name, lum.shape, lum)
    scales = objective_scales(lum, isotropic=not isinstance(model, Marble))
    if lookup is None:
        lookup = NoiseLookup(lookup_extent(lum.shape), seed)
    params = model.params()

    def objective(u: np.ndarray, choice: dict[str, Any]) -> float:
        values = model.decode(u, choice)
        value = 0.0
        for scale in scales:
            s = model.field(values, scale.grid, lookup)
            lum_synth = ValueMap.fit(s, scale.target, values["sign"], values.get("skew", 0.0))(s)
            value += objective_value(distances(lum_synth, scale.target), scale.target)
        return value

    best = _BestSoFar(objective)
    choices = model.choices()
    n_scan = max(4, budget // (2 * len(choices)))
    _scan_then_simplex(best, len(params), choices, n_scan, budget - n_scan * len(choices), seed)
    return ModelFit(
        model=model,
        values=model.decode(best.u, best.choice),
        objective=best.value,
        evaluations=best.count,
        trace=best.trace,
    )


class _BestSoFar:
    """An objective ``f(u, choice)`` that counts its calls and keeps its best point and improvements."""

    def __init__(self, objective: Callable[[np.ndarray, dict[str, Any]], float]) -> None:
        self.objective = objective
        self.count = 0
        self.value = math.inf
        self.u: np.ndarray | None = None
        self.choice: dict[str, Any] = {}
        self.trace: list[tuple[int, float]] = []

    def __call__(self, u: np.ndarray, choice: dict[str, Any]) -> float:
        self.count += 1
        value = self.objective(u, choice)
        if value < self.value:
            self.value, self.u, self.choice = value, np.array(u, dtype=float), dict(choice)
            self.trace.append((self.count, value))
        return value


class SpectralFit:
    """The photo's radially averaged power spectrum against an isotropic octave model's expected one.

    Bins are a quarter octave wide from 2/N to 0.4 cycles per pixel; the model's
    expected binned periodogram (:func:`noise.spectra.expected_spectrum_operator`) is
    the sum over its octaves of the noise's PSD scaled to each octave's cell size ``c``
    (``c^2 S(f c)``, times the octave's weight squared): octaves are uncorrelated at every
    non-zero frequency. The distance ignores the overall level (the value map sets it):
    the weighted RMS of ``log10(photo / model)`` about its weighted mean.
    """

    def __init__(self, lum: np.ndarray) -> None:
        self.bins = polar_bins(lum.shape, f_max=0.4, bins_per_octave=4.0, n_angular=1)
        photo = polar_spectrum(lum, self.bins)[:, 0]
        self.weights = np.where(np.isfinite(photo) & (photo > 0), self.bins.counts[:, 0], 0).astype(float)
        self.log_photo = np.log10(np.where(self.weights > 0, photo, 1.0))
        self.operator = expected_spectrum_operator(self.bins)

    def model_psd(self, model: OctaveModel, values: dict[str, Any]) -> np.ndarray:
        rho, psd = scn_slice_psd(model.absolute)
        lac = model.lacunarity(values)
        weight = model.weight(values)
        n = kept_octaves(values["octaves"], lac, values["feature_px"], 1.0)
        total = np.zeros_like(self.operator.radii)
        for i in range(n):
            cell = values["feature_px"] / lac**i
            total += weight ** (2 * i) * cell * cell * interpolate_psd(rho, psd, self.operator.radii * cell)
        return total

    def distance(self, model: OctaveModel, values: dict[str, Any]) -> float:
        expected = self.operator(self.model_psd(model, values))
        ok = self.weights > 0
        diff = self.log_photo[ok] - np.log10(np.maximum(expected[ok], 1e-300))
        w = self.weights[ok]
        centred = diff - np.sum(w * diff) / np.sum(w)
        return float(np.sqrt(np.sum(w * centred * centred) / np.sum(w)))


def fit_value_map(s: np.ndarray, target: Target, skewed: bool) -> tuple[float, float, float]:
    """Sign and skew of the :class:`ValueMap` that bring ``s`` closest to the photo.

    Minimises the Wasserstein distance (in photo standard deviations) plus the GLCM
    difference, both at full resolution, over the sign and (when ``skewed``) the skew
    in [-3, 3] by SciPy's bounded scalar minimiser. Returns (sign, skew, objective).
    """
    from scipy.optimize import minimize_scalar

    order = np.sort(s.ravel())
    std = max(target.std, 1e-6)

    def cost(sign: float, skew: float) -> float:
        value_map = ValueMap.fit(s, target, sign, skew)
        ordered = value_map(order if sign > 0 else order[::-1])
        hist = float(np.mean(np.abs(ordered - target.sorted_values)))
        g = glcm_features(value_map(s), target.glcm_edges, target.glcm_distances)
        return hist / std + float(np.sqrt(np.mean((g - target.glcm) ** 2)))

    best = (math.inf, 1.0, 0.0)
    for sign in (1.0, -1.0):
        if skewed:
            found = minimize_scalar(
                lambda k, sign=sign: cost(sign, k),
                bounds=(-3.0, 3.0),
                method="bounded",
                options={"xatol": 0.02},
            )
            candidate = (float(found.fun), sign, float(found.x))
        else:
            candidate = (cost(sign, 0.0), sign, 0.0)
        best = min(best, candidate)
    return best[1], best[2], best[0]


def _fit_by_spectrum(name: str, lum: np.ndarray, target: Target, *, seed: int, budget: int) -> ModelFit:
    """fBm and turbulence: structure from the expected spectrum, then the value map from the values.

    The spectral objective (:class:`SpectralFit`) is cheap (no synthesis), so the scan
    covers every octave count; ``budget`` evaluations go to Nelder-Mead. The field is
    then synthesised once, exactly, and :func:`fit_value_map` fits its sign and skew.
    """
    model = make_model(name, lum.shape, lum)
    assert isinstance(model, OctaveModel)
    spectral = SpectralFit(lum)
    params = [p for p in model.params() if p is not SKEW]

    def objective(u: np.ndarray, choice: dict[str, Any]) -> float:
        values = {p.name: p.value(float(x)) for p, x in zip(params, u, strict=True)}
        values["octaves"] = max(1, model.max_octaves(values, 1.0) - choice["drop"])
        return spectral.distance(model, values)

    best = _BestSoFar(objective)

    # An evaluation costs about 50 us: a full grid over the box for every octave count
    # (features x H x lacunarity for fBm), then Nelder-Mead from each count's best point.
    if isinstance(model, FBM):
        choices, grid = [{"drop": d} for d in range(5)], [16, 10, 7]
    else:
        choices, grid = [{"drop": d} for d in range(MAX_OCTAVES)], [48]
    _scan_then_simplex(best, len(params), choices, 0, 4 * budget, seed, per_choice=True, grid=grid)
    values = {p.name: p.value(float(x)) for p, x in zip(params, best.u, strict=True)}
    values["octaves"] = max(1, model.max_octaves(values, 1.0) - best.choice["drop"])
    s = model.field({**values, "sign": 1.0}, Grid.of(lum.shape, lum.shape), exact_noise(seed))
    sign, skew, value_cost = fit_value_map(s, target, skewed=True)
    values |= {"sign": sign, "skew": skew}
    return ModelFit(model, values, best.value + value_cost, best.count, best.trace)


def fit_model(
    name: str,
    lum: np.ndarray,
    target: Target,
    *,
    seed: int = 0,
    budget: int = 160,
    lookup: NoiseLookup | None = None,
) -> ModelFit:
    """Fit one model to a luminance image (rows upward); ``target`` holds its full-resolution statistics.

    fBm and turbulence are fitted on their expected spectrum, then their value map
    (:func:`_fit_by_spectrum`); marble, which has no closed-form spectrum, on syntheses
    (:func:`_fit_by_synthesis`), then its octave count at full resolution
    (:func:`refine_octaves`). ``budget`` counts Nelder-Mead evaluations (and, for marble,
    as many again for the scan).
    """
    if name == "marble":
        fit = _fit_by_synthesis(name, lum, seed=seed, budget=budget, lookup=lookup)
        return refine_octaves(fit, lum, target, seed)
    return _fit_by_spectrum(name, lum, target, seed=seed, budget=budget)


def refine_octaves(fit: ModelFit, lum: np.ndarray, target: Target, seed: int) -> ModelFit:
    """Choose the octave count at full resolution, with the exact noise.

    The objective's image shows only octaves of at least two of its pixels, so finer
    octaves of the photo are invisible to it. Every count up to what the analysed image
    resolves is synthesised (octaves added one at a time) and the best objective wins.
    """
    values = dict(fit.values)
    grid = Grid.of(lum.shape, lum.shape)
    top = fit.model.max_octaves(values, grid.pitch_px)
    fields = fit.model.cumulative({**values, "octaves": top}, grid, exact_noise(seed))
    best_value, best_n = math.inf, values["octaves"]
    for n, s in enumerate(fields, start=1):
        lum_synth = ValueMap.fit(s, target, values["sign"], values.get("skew", 0.0))(s)
        value = objective_value(distances(lum_synth, target), target)
        if value < best_value:
            best_value, best_n = value, n
    values["octaves"] = best_n
    return ModelFit(fit.model, values, fit.objective, fit.evaluations, fit.trace)


def unfitted(name: str, lum: np.ndarray) -> ModelFit:
    """A model at the middle of its search box, for images with nothing to fit (constant ones)."""
    model = make_model(name, lum.shape, lum)
    values = model.decode(np.full(len(model.params()), 0.5), {"drop": 0, "sign": 1.0})
    values.setdefault("skew", 0.0)
    return ModelFit(model, values, math.nan, 0)


def random_values(model: Model, rng: np.random.Generator, pitch_px: float) -> dict[str, Any]:
    """Parameters drawn uniformly from the box the optimiser searches (log-uniform where it searches logs)."""
    values = model.decode(rng.random(len(model.params())), {"sign": float(rng.choice([1.0, -1.0]))})
    values["octaves"] = int(rng.integers(1, model.max_octaves(values, pitch_px) + 1))
    return values
