"""Spectra to linear sRGB: CIE 1931 colour matching functions and the sRGB primaries.

The colour matching functions are the multi-lobe Gaussian fit of Wyman, Sloan & Shirley 2013,
"Simple analytic approximations to the CIE XYZ color matching functions", JCGT 2(2), eq. 2
(within the CIE tables' own precision for rendering). XYZ to linear sRGB is IEC 61966-2-1's
matrix. A spectrum sampled at a few wavelengths is reduced to RGB with weights that map a
constant spectrum to equal R, G and B, so that a wavelength-independent coefficient or
reflectance keeps its value in every channel (how FCJ07 reduce their spectral coefficients).
"""

from __future__ import annotations

import numpy as np

XYZ_TO_LINEAR_SRGB = np.array(
    [
        [3.2406, -1.5372, -0.4986],
        [-0.9689, 1.8758, 0.0415],
        [0.0557, -0.2040, 1.0570],
    ]
)

_LOBES = {
    # (weight, centre nm, width below, width above), Wyman et al. 2013 eq. 2
    "x": ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
    "y": ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
    "z": ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),
}


def cie1931_cmf(wavelength_nm: np.ndarray | float) -> np.ndarray:
    """CIE 1931 2-degree colour matching functions x-bar, y-bar, z-bar at ``wavelength_nm``.

    Returns an array of shape ``wavelength_nm.shape + (3,)``.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    out = []
    for key in ("x", "y", "z"):
        total = np.zeros_like(lam)
        for weight, centre, below, above in _LOBES[key]:
            width = np.where(lam < centre, below, above)
            total = total + weight * np.exp(-0.5 * ((lam - centre) / width) ** 2)
        out.append(total)
    return np.stack(out, axis=-1)


def rgb_weights(wavelength_nm: np.ndarray) -> np.ndarray:
    """Weights ``W`` (shape ``(n, 3)``) with ``rgb = spectrum @ W`` and each column summing to 1.

    Trapezoidal quadrature of the sRGB channel sensitivities (XYZ_TO_LINEAR_SRGB applied to
    the colour matching functions) over the samples given; the spectrum is taken to be what
    it is at the samples and nothing outside them.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    if lam.ndim != 1 or lam.size < 1 or np.any(np.diff(lam) <= 0):
        raise ValueError("wavelength_nm: expected increasing wavelengths")
    sensitivity = cie1931_cmf(lam) @ XYZ_TO_LINEAR_SRGB.T
    if lam.size == 1:
        quad = np.ones(1)
    else:
        quad = np.zeros_like(lam)
        steps = np.diff(lam)
        quad[:-1] += steps / 2
        quad[1:] += steps / 2
    weights = sensitivity * quad[:, None]
    return weights / weights.sum(axis=0, keepdims=True)


def spectrum_to_rgb(values: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Reduce spectral samples (last axis over ``wavelength_nm``) to linear RGB, clipped at 0.

    The red channel's sensitivity is negative between about 440 and 540 nm, so a spectrum that
    rises steeply into the blue could come out slightly negative in red; it is clipped.
    """
    rgb = np.asarray(values, dtype=np.float64) @ rgb_weights(wavelength_nm)
    return np.clip(rgb, 0.0, None)
