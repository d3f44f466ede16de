"""Reference: fractional Brownian surfaces by spectral synthesis, written from the textbook.

Saupe's ``SpectralSynthesisFM2D`` (D. Saupe, "Algorithms for random fractals", in
Peitgen & Saupe (eds.), *The Science of Fractal Images*, Springer 1988, section 2.5):
the Fourier coefficients of an ``n x n`` surface are drawn with random phases and
amplitudes ``|a_kl| ~ gauss * (k^2 + l^2)^(-(H + 1) / 2)``, kept Hermitian so that the
inverse transform is real. Its power spectrum is then ``S(f) ~ f^-(2H + 2)`` at every
frequency from ``1/n`` to the Nyquist frequency: a power law with no scale of its own
(unlike printapp's fBm, whose octaves start at a base feature size). Nothing here
uses printapp's noise.
"""

from __future__ import annotations

import numpy as np


def spectral_fbm(n: int, H: float, seed: int = 0) -> np.ndarray:
    """An ``n x n`` fBm surface with Hurst exponent ``H`` (0 < H < 1), zero mean, unit variance.

    Coefficient ``(k, l)`` (numpy's FFT layout, frequencies ``k / n`` cycles per pixel)
    gets amplitude ``rad = g (k^2 + l^2)^(-(H + 1) / 2)`` with ``g`` standard normal and
    a uniform phase; the coefficient at ``(-k, -l)`` is its conjugate (Saupe's
    ``A[N-i][N-j] = conj(A[i][j])``), the mean is zero, and self-conjugate coefficients
    (Nyquist rows and columns) are real. The surface is the real inverse FFT.
    """
    if not (0.0 < H < 1.0 and n >= 8):
        raise ValueError("expected 0 < H < 1 and n >= 8")
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(n) * n
    radius = np.hypot(k[:, None], k[None, :])
    radius[0, 0] = 1.0
    amplitude = rng.standard_normal((n, n)) * radius ** (-(H + 1.0))
    phase = rng.uniform(0.0, 2.0 * np.pi, (n, n))
    coefficients = amplitude * np.exp(1j * phase)
    coefficients[0, 0] = 0.0
    # Hermitian symmetry: A(-k, -l) = conj(A(k, l)); indices (-i) mod n.
    flipped = np.conj(coefficients[(-np.arange(n)) % n][:, (-np.arange(n)) % n])
    coefficients = 0.5 * (coefficients + flipped)
    surface = np.fft.ifft2(coefficients).real
    surface -= surface.mean()
    return surface / surface.std()
