"""fBm and turbulence fitted on their expected power spectrum, without synthesising them.

The photo's radially averaged power spectrum is taken in log-spaced bins, a quarter
octave wide from 2 cycles per image (where the Hann window still resolves) to 0.45 cycles
per pixel, and every bin weighs the same: each octave counts equally, so the coarse
scales (few frequency samples, all of the visible structure) are not drowned by the
fine ones (most samples, little to see); only bins of fewer than 64 samples weigh in
proportion to their samples, since their log-power scatters by more than 0.05 decades. The
model's expected binned periodogram
(:func:`noise.spectra.expected_spectrum_operator`: window and aliasing included) is
the sum over its octaves of the noise's measured PSD scaled to each octave's cell
``c`` (``c^2 S(f c)``, times the octave's weight squared): octaves are uncorrelated at
every non-zero frequency. For fBm it falls as ``f^-(2H + 2)`` between its base
frequency and its finest octave (Voss 1988). The distance ignores the overall level
(the value mapping sets it): the RMS of ``log10(photo / model)`` about its mean.

The search: a full grid over (feature size, H, lacunarity) for fBm, or the feature size
for turbulence, at every octave count, then Nelder-Mead (SciPy) from each count's
best point. Base features may be up to four times the image: a power law that runs
down to the image's largest scale (spectral-synthesis fBm, most photos) needs a base
octave larger than the image.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from noise.spectra import (
    expected_spectrum_operator,
    interpolate_psd,
    polar_bins,
    polar_spectrum,
    scn_slice_psd,
)
from printapp.fit_models import MAX_OCTAVES, Param

RELIABLE_SAMPLES = 64
"""Bins of at least this many frequency samples weigh the same; sparser (coarse) bins in proportion."""


def _kept(octaves: int, lacunarity: float, feature_px: float) -> int:
    """Octaves whose cells are at least two pixels."""
    n = 1
    while n < octaves and feature_px / lacunarity**n >= 2.0:
        n += 1
    return n


class SpectralFit:
    """The photo's radial spectrum in quarter-octave bins against an octave model's expected one."""

    def __init__(self, lum: np.ndarray) -> None:
        side = min(lum.shape)
        self.bins = polar_bins(lum.shape, f_min=2.0 / side, f_max=0.45, bins_per_octave=4.0, n_angular=1)
        photo = polar_spectrum(lum, self.bins)[:, 0]
        self.ok = np.isfinite(photo) & (photo > 0) & (self.bins.counts[:, 0] > 0)
        self.log_photo = np.log10(np.where(self.ok, photo, 1.0))[self.ok]
        counts = self.bins.counts[:, 0][self.ok].astype(float)
        self.weights = np.minimum(counts, RELIABLE_SAMPLES) / np.sum(np.minimum(counts, RELIABLE_SAMPLES))
        self.operator = expected_spectrum_operator(self.bins)

    def model_psd(self, absolute: bool, values: dict[str, Any]) -> np.ndarray:
        rho, psd = scn_slice_psd(absolute)
        lac = values.get("lacunarity", 2.0)
        weight = lac ** (-values["H"]) if not absolute else 0.5
        total = np.zeros_like(self.operator.radii)
        for i in range(int(values["octaves"])):
            cell = values["feature_px"] / lac**i
            total += weight ** (2 * i) * cell * cell * interpolate_psd(rho, psd, self.operator.radii * cell)
        return total

    def distance(self, absolute: bool, values: dict[str, Any]) -> float:
        expected = self.operator(self.model_psd(absolute, values))[self.ok]
        diff = self.log_photo - np.log10(np.maximum(expected, 1e-300))
        centred = diff - np.sum(self.weights * diff)
        return float(np.sqrt(np.sum(self.weights * centred * centred)))


def fit_spectral(name: str, lum: np.ndarray) -> tuple[dict[str, Any], float, int]:
    """Fit fBm (``name == "fbm"``) or turbulence to a luminance image by its spectrum.

    Returns (values, distance in decades, evaluations); values hold ``feature_px``,
    ``octaves`` (and ``H``, ``lacunarity`` for fBm; turbulence has ``H = 1``, lacunarity 2).
    """
    from scipy.optimize import minimize

    side = float(max(lum.shape))
    fit = SpectralFit(lum)
    absolute = name == "turbulence"
    params = [Param("feature_px", 2.0, 4.0 * side, log=True)]
    if not absolute:
        params += [Param("H", 0.02, 1.0), Param("lacunarity", 1.6, 3.2, log=True)]
    grid_sizes = [40] if absolute else [12, 8, 4]
    count = 0

    def decode(u: np.ndarray, drop: int) -> dict[str, Any]:
        values = {p.name: p.value(float(x)) for p, x in zip(params, u, strict=True)}
        values.setdefault("H", 1.0)
        lac = values.setdefault("lacunarity", 2.0)
        values["octaves"] = max(1, _kept(MAX_OCTAVES + 4, lac, values["feature_px"]) - drop)
        return values

    def objective(u: np.ndarray, drop: int) -> float:
        nonlocal count
        count += 1
        return fit.distance(absolute, decode(np.clip(u, 0.0, 1.0), drop))

    axes = [(np.arange(k) + 0.5) / k for k in grid_sizes]
    starts = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=-1)
    best = (math.inf, starts[0], 0)
    for drop in range(5 if absolute else 3):
        scores = [objective(u, drop) for u in starts]
        k = int(np.argmin(scores))
        found = minimize(
            objective,
            starts[k],
            args=(drop,),
            method="Nelder-Mead",
            bounds=[(0.0, 1.0)] * len(params),
            options={"maxfev": 60 * len(params), "xatol": 1e-3, "fatol": 1e-5},
        )
        u, value = (found.x, float(found.fun)) if found.fun < scores[k] else (starts[k], scores[k])
        if value < best[0]:
            best = (value, np.clip(u, 0.0, 1.0), drop)
    return decode(best[1], best[2]), best[0], count
