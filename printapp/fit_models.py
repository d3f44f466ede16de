"""The noise models that ``printapp fit`` fits, the statistics they are matched on, and the optimiser.

Every model gives a scalar field ``s`` on the photo's pixel grid, built from the
project's sparse convolution noise (``noise``); the photo's luminance is modelled as
``L = offset + A s`` (clipped to the photo's range), and a 1-D palette of the photo's
colours, ordered along ``L``, colours it.

* ``fbm``: ``s = sum_{i<octaves} lacunarity^(-H i) noise(p lacunarity^i / F)``;
* ``turbulence``: ``s = sum_{i<octaves} 2^-i |noise(2^i p / F)|`` (octaves 0 .. octaves - 1:
  a first octave ``low > 0`` is the same texture with ``F / 2^low``, so ``low`` is 0);
* ``marble``: ``s = ((1 + sin(2 pi (n . p) / period + k T(p))) / 2)^sharpness`` with ``T``
  the turbulence above (:mod:`noise.veins`).

``p`` is in pixels (pixel centres at ``i + 1/2``), ``F`` the base feature size in pixels.

What is matched (the objective, summed with equal weights):

1. the power spectrum in polar bins (radius x angle): RMS distance of the log10 spectra
   (:func:`noise.spectra.log_spectrum_distance`), which carries roughness (the slope),
   frequencies (where power sits) and orientation (the angular split);
2. the 1-Wasserstein distance between the luminance distributions, in units of the
   photo's standard deviation;
3. grey-level co-occurrence statistics (scikit-image's ``graycomatrix`` on 16 levels
   equalised on the photo, at several offsets and four directions): contrast,
   homogeneity and correlation, which carry what the sine and the turbulence control
   in a veined marble, the width and continuity of the veins.

``offset`` and ``A`` follow in closed form from the photo's mean and standard deviation
(moment matching; the sign of ``A`` is searched), the rest is searched: a fixed
quasi-random scan of the box, then Nelder-Mead (SciPy) from the best starts. The
objective is evaluated on the photo downsampled to about 128 px, where each octave is
read from a precomputed, spline-interpolated noise field (:class:`NoiseLookup`, about 1 %
from the exact noise); the octave count and the final statistics are computed at the
analysed resolution with the exact noise. Everything is seeded: a fit is deterministic.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import noise
from noise.spectra import (
    PolarBins,
    dominant_orientation,
    expected_spectrum_operator,
    interpolate_psd,
    log_spectrum_distance,
    polar_bins,
    polar_spectrum,
    scn_slice_psd,
    wasserstein_1d,
)

MODELS = ("fbm", "turbulence", "marble")
GLCM_LEVELS = 16
GLCM_ANGLES = (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)
OBJECTIVE_SIDE = 128
"""Longer side (px) of the image the optimiser's objective is evaluated on."""
MAX_OCTAVES = 8
_LOOKUP_STEP = 1.0 / 16.0  # noise units between samples of the precomputed field


# ---------------------------------------------------------------------------------------------
# Statistics of one image, and distances between two


def glcm_features(lum: np.ndarray, edges: np.ndarray, distances: tuple[int, ...]) -> np.ndarray:
    """Contrast, homogeneity and correlation of the grey-level co-occurrence matrix.

    ``lum`` is quantised to ``len(edges) + 1`` levels at ``edges`` (the photo's
    luminance quantiles, so the photo's levels are equally frequent); the symmetric,
    normalised GLCM (scikit-image) is taken at ``distances`` (px) and four directions.
    Contrast is divided by ``(levels^2 - 1) / 6``, its value for independent uniform
    levels, so all three are of order one.

    Returns
    -------
    (3, len(distances), 4) float array
    """
    from skimage.feature import graycomatrix, graycoprops

    levels = len(edges) + 1
    q = np.searchsorted(edges, lum, side="right").astype(np.uint8)
    # Rows run upwards here; scikit-image's angles are measured with rows running
    # downwards, which only relabels 45 and 135 degrees: the same set of offsets.
    matrix = graycomatrix(q, list(distances), list(GLCM_ANGLES), levels=levels, symmetric=True, normed=True)
    contrast = graycoprops(matrix, "contrast") / ((levels * levels - 1) / 6.0)
    return np.stack([contrast, graycoprops(matrix, "homogeneity"), graycoprops(matrix, "correlation")])


@dataclass
class Target:
    """The statistics of the photo's luminance at one resolution, computed once."""

    lum: np.ndarray
    bins: PolarBins
    spectrum: np.ndarray
    sorted_values: np.ndarray
    mean: float
    std: float
    lo: float
    hi: float
    glcm_edges: np.ndarray
    glcm_distances: tuple[int, ...]
    glcm: np.ndarray

    @classmethod
    def of(
        cls,
        lum: np.ndarray,
        *,
        f_max: float,
        glcm_distances: tuple[int, ...],
        n_angular: int = 6,
        tile: tuple[int, int] | None = None,
    ) -> Target:
        """Statistics of ``lum``, for comparison with syntheses of shape ``tile`` (default: its own).

        With a smaller tile, the spectrum is the mean over the image's non-overlapping
        tiles (Welch's averaging) and the value distribution is given by as many
        quantiles as a tile has pixels; the GLCM is the whole image's.
        """
        lum = np.asarray(lum, dtype=np.float64)
        ty, tx = lum.shape if tile is None else tile
        bins = polar_bins((ty, tx), f_max=f_max, n_angular=n_angular)
        edges = np.quantile(lum, np.arange(1, GLCM_LEVELS) / GLCM_LEVELS)
        distances = tuple(d for d in glcm_distances if d < min(ty, tx) // 2) or (1,)
        spectra = [
            polar_spectrum(lum[r : r + ty, c : c + tx], bins)
            for r in range(0, lum.shape[0] - ty + 1, ty)
            for c in range(0, lum.shape[1] - tx + 1, tx)
        ]
        if (ty, tx) == lum.shape:
            values = np.sort(lum.ravel())
        else:
            # Quantiles by interpolating the order statistics (np.quantile with this many
            # probabilities partitions once per probability: seconds instead of milliseconds).
            order = np.sort(lum.ravel())
            positions = (np.arange(ty * tx) + 0.5) / (ty * tx) * order.size - 0.5
            values = np.interp(positions, np.arange(order.size), order)
        return cls(
            lum=lum,
            bins=bins,
            spectrum=np.mean(spectra, axis=0),
            sorted_values=values,
            mean=float(lum.mean()),
            std=float(lum.std()),
            lo=float(lum.min()),
            hi=float(lum.max()),
            glcm_edges=edges,
            glcm_distances=distances,
            glcm=glcm_features(lum, edges, distances),
        )


@dataclass(frozen=True)
class Distances:
    """How far a synthesis is from the photo, by each measure."""

    spectrum: float
    """RMS distance of the log10 polar power spectra (decades)."""
    histogram: float
    """1-Wasserstein distance of the luminance distributions (luminance units, 0..1)."""
    glcm: float
    """RMS difference of the GLCM statistics (contrast, homogeneity, correlation)."""

    def as_dict(self) -> dict[str, float]:
        return {
            "log_spectrum_distance": self.spectrum,
            "wasserstein": self.histogram,
            "glcm_difference": self.glcm,
        }


def distances(lum: np.ndarray, target: Target) -> Distances:
    """The three measures between a synthesised luminance image and the photo's statistics."""
    spectrum = polar_spectrum(lum, target.bins)
    if lum.size == target.sorted_values.size:
        hist = float(np.mean(np.abs(np.sort(lum.ravel()) - target.sorted_values)))
    else:
        hist = wasserstein_1d(lum, target.sorted_values)
    g = glcm_features(lum, target.glcm_edges, target.glcm_distances)
    return Distances(
        spectrum=log_spectrum_distance(spectrum, target.spectrum, target.bins.counts),
        histogram=hist,
        glcm=float(np.sqrt(np.mean((g - target.glcm) ** 2))),
    )


def objective_value(d: Distances, target: Target) -> float:
    """The scalar the optimiser minimises: the three measures, each of order one, summed."""
    return d.spectrum + d.histogram / max(target.std, 1e-6) + d.glcm


@dataclass(frozen=True)
class ValueMap:
    """Luminance from a model's values: a monotone curve, then the photo's mean and spread.

    ``z = sign (s - mean s) / std s``, ``g = expm1(skew z) / skew`` (``g = z`` for skew 0:
    a positive skew stretches the bright tail into sparse highlights, a negative one the
    dark tail), ``L = mu + sigma (g - mean g) / std g`` clipped to the photo's range
    [lo, hi]. ``mu`` and ``sigma`` are the photo's luminance mean and standard deviation
    (moment matching); ``sign`` and ``skew`` are searched with the model.
    """

    s_mean: float
    s_std: float
    sign: float
    skew: float
    g_mean: float
    g_std: float
    mu: float
    sigma: float
    lo: float
    hi: float

    @classmethod
    def fit(cls, s: np.ndarray, target: Target, sign: float, skew: float = 0.0) -> ValueMap:
        s_mean, s_std = float(s.mean()), float(s.std())
        probe = cls(s_mean, s_std, sign, skew, 0.0, 1.0, 0.0, 1.0, -np.inf, np.inf)
        g = probe.curve(s)
        return cls(
            s_mean,
            s_std,
            sign,
            skew,
            float(g.mean()),
            float(g.std()),
            target.mean,
            target.std,
            target.lo,
            target.hi,
        )

    def curve(self, s: np.ndarray) -> np.ndarray:
        if self.s_std <= 0.0:
            return np.zeros_like(s, dtype=np.float64)
        z = self.sign * (np.asarray(s, dtype=np.float64) - self.s_mean) / self.s_std
        return z if abs(self.skew) < 1e-9 else np.expm1(self.skew * z) / self.skew

    def __call__(self, s: np.ndarray) -> np.ndarray:
        g = self.curve(s)
        if self.g_std <= 0.0:
            return np.full(np.shape(s), self.mu)
        return np.clip(self.mu + self.sigma * (g - self.g_mean) / self.g_std, self.lo, self.hi)

    @property
    def amplitude(self) -> float:
        """Luminance per unit of ``s`` at the mean (the slope of the map there)."""
        if self.s_std <= 0.0 or self.g_std <= 0.0:
            return 0.0
        return self.sign * self.sigma / (self.g_std * self.s_std)  # dg/dz = 1 at z = 0, any skew

    @property
    def offset(self) -> float:
        """Luminance at ``s = 0`` of the map's tangent at the mean: ``L ~ offset + amplitude s``."""
        at_mean = self.mu + self.sigma * (0.0 - self.g_mean) / self.g_std if self.g_std > 0 else self.mu
        return at_mean - self.amplitude * self.s_mean


# ---------------------------------------------------------------------------------------------
# Noise on grids: exact, or from a precomputed field


class NoiseLookup:
    """Sparse convolution noise on z = 0 read from a precomputed, finely sampled field.

    The field is sampled every 1/16 noise unit over ``[0, extent]^2`` once; each octave
    of a model is then one bilinear interpolation, several times cheaper than evaluating
    the kernel sums at coarse sampling. The error against the exact noise is about 2 %
    of its standard deviation (tests check it), below what the objective resolves.
    """

    def __init__(self, extent: float, seed: int) -> None:
        m = int(math.ceil(extent / _LOOKUP_STEP)) + 4
        axis = np.arange(m) * _LOOKUP_STEP
        self.extent = (m - 2) * _LOOKUP_STEP
        self.values = noise.sparse_convolution_grid(axis, axis, seed=seed)

    def __call__(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        if max(float(xs.max()), float(ys.max())) > self.extent or min(float(xs.min()), float(ys.min())) < 0:
            raise ValueError("coordinates beyond the precomputed noise field")
        # Bilinear on a grid: separable weights, four gathers.
        fx, fy = xs / _LOOKUP_STEP, ys / _LOOKUP_STEP
        ix, iy = fx.astype(np.int64), fy.astype(np.int64)
        wx, wy = (fx - ix)[None, :], (fy - iy)[:, None]
        v = self.values
        top = v[np.ix_(iy, ix)] * (1 - wx) + v[np.ix_(iy, ix + 1)] * wx
        bottom = v[np.ix_(iy + 1, ix)] * (1 - wx) + v[np.ix_(iy + 1, ix + 1)] * wx
        return top * (1 - wy) + bottom * wy


def exact_noise(seed: int) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Sparse convolution noise on the grid xs by ys, evaluated exactly (the grid fast path)."""

    def evaluate(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return noise.sparse_convolution_grid(xs, ys, seed=seed)

    return evaluate


@dataclass(frozen=True)
class Grid:
    """Pixel centres of an image in the analysed image's pixels: ``xs`` (columns), ``ys`` (rows, y up)."""

    xs: np.ndarray
    ys: np.ndarray
    pitch_px: float

    @classmethod
    def of(cls, shape: tuple[int, int], analysed_shape: tuple[int, int]) -> Grid:
        ny, nx = shape
        sy, sx = analysed_shape[0] / ny, analysed_shape[1] / nx
        return cls((np.arange(nx) + 0.5) * sx, (np.arange(ny) + 0.5) * sy, max(sx, sy))


def kept_octaves(octaves: int, lacunarity: float, feature_px: float, pitch_px: float) -> int:
    """Octaves of a sum kept at a sampling pitch: those whose cells span at least two samples."""
    return noise.octaves_for_pitch(octaves, lacunarity, pitch_px / feature_px)


# ---------------------------------------------------------------------------------------------
# The models


@dataclass(frozen=True)
class Param:
    """One searched parameter: a box, searched on a log scale when ``log``."""

    name: str
    lo: float
    hi: float
    log: bool = False

    def value(self, u: float) -> float:
        u = min(max(u, 0.0), 1.0)
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))

    def unit(self, value: float) -> float:
        if self.log:
            return (math.log(value) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (value - self.lo) / (self.hi - self.lo)


SKEW = Param("skew", -3.0, 3.0)
"""The luminance curve's skew (:class:`ValueMap`), searched with every model."""


class Model(ABC):
    """A noise model: its searched parameters, its discrete choices and its scalar field."""

    name = ""

    def __init__(self, shape: tuple[int, int], lum: np.ndarray) -> None:
        self.shape = shape
        side = max(shape)
        # Base features up to a quarter of the image: larger ones put the spectrum's knee
        # (about 0.3 / F cycles per pixel) below the lowest frequency the image resolves.
        self.feature = Param("feature_px", 2.0 * max(1.0, side / OBJECTIVE_SIDE), side / 4.0, log=True)

    @abstractmethod
    def params(self) -> list[Param]:
        """The continuous parameters the optimiser searches, each mapped to [0, 1]."""

    def decode(self, u: np.ndarray, choice: dict[str, Any]) -> dict[str, Any]:
        """Parameter values from unit-box coordinates ``u`` and a discrete choice.

        ``choice["drop"]`` asks for that many octaves fewer than the analysed image
        resolves at this feature size (octaves of less than two pixels are never kept).
        """
        values = {p.name: p.value(float(x)) for p, x in zip(self.params(), u, strict=True)}
        values |= {k: v for k, v in choice.items() if k != "drop"}
        if "drop" in choice:
            values["octaves"] = max(1, self.max_octaves(values, 1.0) - choice["drop"])
        return values

    def encode(self, values: dict[str, Any]) -> np.ndarray:
        return np.array([p.unit(values[p.name]) for p in self.params()])

    @abstractmethod
    def choices(self) -> list[dict[str, Any]]:
        """The discrete settings the scan tries (octave counts, signs)."""

    @abstractmethod
    def field(self, values: dict[str, Any], grid: Grid, octave_noise) -> np.ndarray:
        """The model's scalar field on ``grid`` for parameter ``values``."""

    def max_octaves(self, values: dict[str, Any], pitch_px: float) -> int:
        return kept_octaves(MAX_OCTAVES, values.get("lacunarity", 2.0), values["feature_px"], pitch_px)


class _OctaveModel(Model):
    """A model whose field is a finishing step applied to a sum of octaves of noise."""

    absolute = False

    def lacunarity(self, values: dict[str, Any]) -> float:
        return 2.0

    def weight(self, values: dict[str, Any]) -> float:
        return 0.5

    def finish(self, total: np.ndarray, values: dict[str, Any], grid: Grid) -> np.ndarray:
        return total

    def field(self, values, grid, octave_noise) -> np.ndarray:
        return self.cumulative(values, grid, octave_noise, every=False)[-1]

    def cumulative(self, values, grid, octave_noise, every: bool = True) -> list[np.ndarray]:
        """The field with 1, 2, ... octaves (as many as ``values`` asks and ``grid`` resolves).

        With ``every`` false, only the field with all of them.
        """
        lac = self.lacunarity(values)
        n = kept_octaves(values["octaves"], lac, values["feature_px"], grid.pitch_px)
        weight = self.weight(values)
        total = np.zeros((grid.ys.size, grid.xs.size))
        out = []
        for i in range(n):
            scale = lac**i / values["feature_px"]
            term = octave_noise(grid.xs * scale, grid.ys * scale)
            total += weight**i * (np.abs(term) if self.absolute else term)
            if every or i == n - 1:
                out.append(self.finish(total, values, grid))
        return out


class FBM(_OctaveModel):
    name = "fbm"

    def params(self) -> list[Param]:
        return [self.feature, Param("H", 0.05, 1.0), Param("lacunarity", 1.6, 3.2, log=True), SKEW]

    def choices(self) -> list[dict[str, Any]]:
        return [{"drop": d, "sign": s} for d in (0, 2) for s in (1.0, -1.0)]

    def lacunarity(self, values: dict[str, Any]) -> float:
        return values["lacunarity"]

    def weight(self, values: dict[str, Any]) -> float:
        return values["lacunarity"] ** (-values["H"])

    def finish(self, total, values, grid) -> np.ndarray:
        return total.copy()


class Turbulence(_OctaveModel):
    name = "turbulence"
    absolute = True

    def params(self) -> list[Param]:
        return [self.feature, SKEW]

    def choices(self) -> list[dict[str, Any]]:
        counts: list[dict[str, Any]] = [{"drop": 0}, {"drop": 2}, {"octaves": 1}]
        return [{**n, "sign": s} for n in counts for s in (1.0, -1.0)]

    def finish(self, total, values, grid) -> np.ndarray:
        return total.copy()


class Marble(_OctaveModel):
    name = "marble"
    absolute = True

    def __init__(self, shape: tuple[int, int], lum: np.ndarray) -> None:
        super().__init__(shape, lum)
        side = max(shape)
        # The veins' direction in closed form: the structure tensor's dominant gradient
        # runs across them (Bigun & Granlund 1987). It is within a few degrees on veined
        # textures, where the binned spectra and GLCM directions could not tell 10 degrees
        # apart; on isotropic ones (coherence near 0) the direction does not matter.
        gradient_angle, self.coherence = dominant_orientation(lum)
        self.angle = float(np.mod(gradient_angle + math.pi / 2, math.pi))
        self.period = Param("period_px", side / 16.0, 4.0 * side, log=True)
        self.strength = Param("strength", 0.05, 60.0, log=True)
        self.sharpness = Param("sharpness", 1.0, 40.0, log=True)
        self.feature = Param("feature_px", self.feature.lo, 2.0 * side, log=True)

    def params(self) -> list[Param]:
        return [self.period, self.strength, self.feature, self.sharpness, SKEW]

    def decode(self, u: np.ndarray, choice: dict[str, Any]) -> dict[str, Any]:
        return {**super().decode(u, choice), "angle": self.angle}

    def choices(self) -> list[dict[str, Any]]:
        return [{"drop": d, "sign": s} for d in (0, 3) for s in (1.0, -1.0)]

    def finish(self, total, values, grid) -> np.ndarray:
        a = values["angle"]
        along = -math.sin(a) * grid.xs[None, :] + math.cos(a) * grid.ys[:, None]
        v = 0.5 * (1.0 + np.sin(2.0 * math.pi * along / values["period_px"] + values["strength"] * total))
        return v ** values["sharpness"]


def make_model(name: str, shape: tuple[int, int], lum: np.ndarray) -> Model:
    return {"fbm": FBM, "turbulence": Turbulence, "marble": Marble}[name](shape, lum)


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

    def model_psd(self, model: _OctaveModel, values: dict[str, Any]) -> np.ndarray:
        rho, psd = scn_slice_psd(model.absolute)
        lac = model.lacunarity(values)
        weight = model.weight(values)
        n = kept_octaves(values["octaves"], lac, values["feature_px"], 1.0)
        total = np.zeros_like(self.operator.radii)
        for i in range(n):
            cell = values["feature_px"] / lac**i
            total += weight ** (2 * i) * cell * cell * interpolate_psd(rho, psd, self.operator.radii * cell)
        return total

    def distance(self, model: _OctaveModel, values: dict[str, Any]) -> float:
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
    assert isinstance(model, _OctaveModel)
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
