"""Multi-scale line filters: how strongly an image holds thin bright and dark lines at each scale.

For fitting veins and cracks. At scale ``sigma`` (px) the image's Hessian is taken with
Gaussian derivatives, scale-normalised by ``sigma^2`` (Lindeberg 1998, "Edge and ridge
detection with automatic scale selection", IJCV 30(2)), and its eigenvalues ``l_1``,
``l_2`` ordered by magnitude, ``|l_1| >= |l_2|``. A thin bright line of width about
``2 sigma`` has a strongly negative ``l_1`` across it and ``l_2`` near 0 along it; a dark
line the same with ``l_1 > 0``; a round blob has ``l_1 ~ l_2``. The line strengths are

    bright = max(0, -l_1) - |l_2|  where l_1 < 0 (else 0),   dark = max(0, l_1) - |l_2|  where l_1 > 0,

clipped at zero: the eigenvalue magnitude across the line less the one along it, the
two-dimensional form of the line measures of Sato et al. 1998 ("Three-dimensional
multi-scale line filter for segmentation and visualization of curvilinear structures in
medical images", Medical Image Analysis 2(2)) and Frangi et al. 1998, without their
thresholds. scikit-image's ``hessian_matrix`` gives the same Hessian (tests compare).

The derivatives are products in the Fourier domain of the image mirrored at its edges
(numpy's ``"symmetric"`` padding, scipy.ndimage's ``"reflect"``), so a photo's borders
do not read as lines.
"""

from __future__ import annotations

import math

import numpy as np


def _fft_size(n: int) -> int:
    """The smallest 2^a 3^b 5^c at least n (fast FFT lengths)."""
    best = 1 << max(0, math.ceil(math.log2(max(n, 1))))
    f5 = 1
    while f5 < best:
        f3 = f5
        while f3 < best:
            f2 = f3
            while f2 < n:
                f2 *= 2
            best = min(best, f2)
            f3 *= 3
        f5 *= 5
    return best


def _hessian(
    image: np.ndarray, sigmas: tuple[float, ...], directions: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    arr = np.asarray(image, dtype=np.float64)
    if arr.ndim != 2 or min(arr.shape) < 4:
        raise ValueError(f"image: expected a 2-D array of at least 4 x 4, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("image: expected finite values, found NaN or infinity")
    if not sigmas or not all(math.isfinite(s) and s > 0 for s in sigmas):
        raise ValueError(f"sigmas: expected positive scales, got {sigmas!r}")
    from scipy import fft

    ny, nx = arr.shape
    pad = min(int(math.ceil(4.0 * max(sigmas))), min(ny, nx) - 1)
    my, mx = _fft_size(ny + 2 * pad), _fft_size(nx + 2 * pad)
    extra_y, extra_x = my - ny - 2 * pad, mx - nx - 2 * pad
    padded = np.pad(arr - arr.mean(), ((pad, pad + extra_y), (pad, pad + extra_x)), mode="symmetric")
    # Single precision: the strengths are statistics, 1e-7 of relative error is far below what they resolve.
    spectrum = fft.rfft2(padded.astype(np.float32))
    wy = (2.0 * math.pi * fft.fftfreq(my)[:, None]).astype(np.float32)
    wx = (2.0 * math.pi * fft.rfftfreq(mx)[None, :]).astype(np.float32)
    w2 = wy * wy + wx * wx
    out = np.empty((len(sigmas), 2, ny, nx))
    along = np.empty((len(sigmas), ny, nx)) if directions else None
    for k, sigma in enumerate(sigmas):
        smooth = spectrum * np.exp(np.float32(-0.5 * sigma * sigma) * w2)
        s2 = np.float32(sigma * sigma)
        hxx = fft.irfft2(-(wx * wx) * smooth, s=(my, mx))[pad : pad + ny, pad : pad + nx] * s2
        hyy = fft.irfft2(-(wy * wy) * smooth, s=(my, mx))[pad : pad + ny, pad : pad + nx] * s2
        hxy = fft.irfft2(-(wx * wy) * smooth, s=(my, mx))[pad : pad + ny, pad : pad + nx] * s2
        half_trace = 0.5 * (hxx + hyy)
        root = np.sqrt(0.25 * (hxx - hyy) ** 2 + hxy * hxy)
        a, b = half_trace + root, half_trace - root
        big = np.abs(a) >= np.abs(b)
        out[k, 0] = np.where(big, a, b)
        out[k, 1] = np.where(big, b, a)
        if along is not None:
            # The eigenvector of a lies at phi; a line runs across its big eigenvalue's eigenvector.
            phi = 0.5 * np.arctan2(2.0 * hxy, hxx - hyy)
            along[k] = np.mod(np.where(big, phi + 0.5 * math.pi, phi), math.pi)
    return out, along


def hessian_eigenvalues(image: np.ndarray, sigmas: tuple[float, ...]) -> np.ndarray:
    """Scale-normalised Hessian eigenvalues ``(l_1, l_2)``, ``|l_1| >= |l_2|``, at each scale.

    Parameters
    ----------
    image : (ny, nx) float array
    sigmas : tuple of float
        Gaussian scales (px), each > 0.

    Returns
    -------
    (len(sigmas), 2, ny, nx) float64 array: ``sigma^2`` times the eigenvalues of the
    Hessian of the Gaussian-smoothed image (rows are the y axis, columns x).
    """
    return _hessian(image, sigmas, False)[0]


def _strengths(eig: np.ndarray) -> np.ndarray:
    l1, l2 = eig[:, 0], eig[:, 1]
    across = np.abs(l1) - np.abs(l2)
    out = np.empty_like(eig)
    out[:, 0] = np.where(l1 < 0, across, 0.0)
    out[:, 1] = np.where(l1 > 0, across, 0.0)
    return out


def line_strengths(image: np.ndarray, sigmas: tuple[float, ...]) -> np.ndarray:
    """Bright and dark line strengths at each scale (module docstring), >= 0.

    Returns
    -------
    (len(sigmas), 2, ny, nx) float64 array: ``[:, 0]`` bright lines, ``[:, 1]`` dark lines.
    """
    return _strengths(hessian_eigenvalues(image, sigmas))


def line_field(image: np.ndarray, sigmas: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`line_strengths` and the direction a line at each pixel runs along.

    Returns
    -------
    strengths : (len(sigmas), 2, ny, nx) float64 array
    along : (len(sigmas), ny, nx) float64 array
        Angle (rad, [0, pi), from +x towards +y) of the Hessian's eigenvector of the
        smaller eigenvalue: the direction along a line (across it lies the larger one's).
    """
    eig, along = _hessian(image, sigmas, True)
    assert along is not None
    return _strengths(eig), along
