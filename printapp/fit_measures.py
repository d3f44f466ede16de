"""What ``printapp fit`` matches: an image's statistics, the distances between two, the value map.

See :mod:`printapp.fit_models` for the measures' roles in the objective: the polar power
spectrum (log distance), the 1-Wasserstein distance of the luminance distributions, and
grey-level co-occurrence (GLCM) statistics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from noise.spectra import (
    PolarBins,
    log_spectrum_distance,
    polar_bins,
    polar_spectrum,
    wasserstein_1d,
)

GLCM_LEVELS = 16
GLCM_ANGLES = (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)


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
