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
from dataclasses import dataclass
from typing import Any

import numpy as np

import noise
from noise.spectra import (
    dominant_orientation,
)

MODELS = ("fbm", "turbulence", "marble")
OBJECTIVE_SIDE = 128
"""Longer side (px) of the image the optimiser's objective is evaluated on."""
MAX_OCTAVES = 8
_LOOKUP_STEP = 1.0 / 16.0  # noise units between samples of the precomputed field


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


class OctaveModel(Model):
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


class FBM(OctaveModel):
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


class Turbulence(OctaveModel):
    name = "turbulence"
    absolute = True

    def params(self) -> list[Param]:
        return [self.feature, SKEW]

    def choices(self) -> list[dict[str, Any]]:
        counts: list[dict[str, Any]] = [{"drop": 0}, {"drop": 2}, {"octaves": 1}]
        return [{**n, "sign": s} for n in counts for s in (1.0, -1.0)]

    def finish(self, total, values, grid) -> np.ndarray:
        return total.copy()


class Marble(OctaveModel):
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
