"""Noise read from tables: a stand-in for sparse convolution noise, fast enough to fit textures with.

An optimiser that synthesises a texture hundreds of times cannot afford the exact
kernel sums at every (warped, rotated) sample. :class:`NoiseTable` holds, per noise
stream, a periodic table sampled every 1/16 cell: a stationary Gaussian field with the
power spectrum of the project's sparse convolution noise (:func:`noise.spectra.scn_slice_psd`,
measured from the noise itself), made by filtering seeded white noise in the Fourier
domain (spectral synthesis). It is read back by bilinear interpolation. Being periodic,
it is defined and seamless at any coordinate, negative or beyond its side; being
Gaussian with the noise's spectrum, it has the noise's second-order statistics (the
noise itself, a sum of 240 impulses per point, is close to Gaussian). It stands in for
the exact noise wherever a function of :mod:`noise` takes a ``sampler``: a callable
``sampler(points, stream)`` giving noise values at ``(n, 2)`` points for one of several
independent streams (:func:`stream_seed`). The fitted texture itself is always
evaluated with the exact noise.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_STEP = 1.0 / 16.0


def stream_seed(seed: int, stream: int) -> int:
    """The noise seed of an independent stream ``stream`` (0, 1, 2, ...) of a texture seeded ``seed``.

    Stream 0 is the seed itself; others are spread over [0, 2^63) by an odd multiplier.
    """
    if stream == 0:
        return int(seed)
    return (int(seed) + int(stream) * 0x632BE59BD9B4E019) % (1 << 63)


class Sampler:
    """Noise for the composite textures: ``sampler(points, stream, scale, shift)`` and octave sums.

    ``sampler(points, stream, scale=1, shift=(0, 0))`` is noise stream ``stream`` at the
    (n, 2) points ``scale * points + shift`` (noise units); :meth:`octave_sum` adds several
    such reads with weights. This base class reads the exact sparse convolution noise
    (:func:`noise.sparse_convolution`, seeded by :func:`stream_seed`).
    """

    def __init__(self, seed: int = 0, impulses: int = 30, cell_seed: str = "hash") -> None:
        self.seed, self.impulses, self.cell_seed = int(seed), int(impulses), cell_seed

    def __call__(
        self, points: np.ndarray, stream: int = 0, scale: float = 1.0, shift: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        from noise.scn import sparse_convolution

        at = points * scale + np.asarray(shift) if scale != 1.0 or tuple(shift) != (0.0, 0.0) else points
        return sparse_convolution(
            at, seed=stream_seed(self.seed, stream), impulses=self.impulses, cell_seed=self.cell_seed
        )

    def octave_sum(
        self,
        points: np.ndarray,
        stream: int,
        scales: np.ndarray,
        weights: np.ndarray,
        shifts: np.ndarray,
        absolute: bool = False,
    ) -> np.ndarray:
        """``sum_i weights[i] n(scales[i] points + shifts[i])`` (of ``|n|`` when ``absolute``)."""
        total = np.zeros(np.shape(points)[0])
        for scale, weight, shift in zip(scales, weights, shifts, strict=True):
            v = self(points, stream, float(scale), (float(shift[0]), float(shift[1])))
            total += weight * (np.abs(v) if absolute else v)
        return total


def exact_sampler(seed: int, impulses: int = 30, cell_seed: str = "hash") -> Sampler:
    """The exact sparse convolution noise (:func:`noise.sparse_convolution`) as a sampler."""
    return Sampler(seed, impulses, cell_seed)


@njit(cache=True, nogil=True, inline="always")
def _lookup(table: np.ndarray, mask: np.int64, fx: float, fy: float) -> float:
    """Bilinear value of the periodic table at (fx, fy) in table cells (the side a power of two)."""
    x0 = math.floor(fx)
    y0 = math.floor(fy)
    wx = fx - x0
    wy = fy - y0
    ix = np.int64(x0) & mask
    iy = np.int64(y0) & mask
    jx = (ix + 1) & mask
    jy = (iy + 1) & mask
    bottom = table[iy, ix] * (1.0 - wx) + table[iy, jx] * wx
    top = table[jy, ix] * (1.0 - wx) + table[jy, jx] * wx
    return bottom * (1.0 - wy) + top * wy


@njit(cache=True, nogil=True)
def _bilinear(
    table: np.ndarray,
    points: np.ndarray,
    inv_step: float,
    scale: float,
    sx: float,
    sy: float,
    out: np.ndarray,
) -> None:
    mask = np.int64(table.shape[0] - 1)  # the side is a power of two: wrapping is a mask
    for k in range(points.shape[0]):
        out[k] = _lookup(
            table, mask, (points[k, 0] * scale + sx) * inv_step, (points[k, 1] * scale + sy) * inv_step
        )


@njit(cache=True, nogil=True)
def _octave_sum(
    table: np.ndarray,
    points: np.ndarray,
    inv_step: float,
    scales: np.ndarray,
    weights: np.ndarray,
    shifts: np.ndarray,
    absolute: bool,
    out: np.ndarray,
) -> None:
    mask = np.int64(table.shape[0] - 1)
    for k in range(points.shape[0]):
        total = 0.0
        for i in range(scales.size):
            v = _lookup(
                table,
                mask,
                (points[k, 0] * scales[i] + shifts[i, 0]) * inv_step,
                (points[k, 1] * scales[i] + shifts[i, 1]) * inv_step,
            )
            total += weights[i] * (abs(v) if absolute else v)
        out[k] = total


class NoiseTable(Sampler):
    """Periodic stand-ins for sparse convolution noise on z = 0, sampled every 1/16 cell, one per stream.

    Parameters
    ----------
    extent : float
        The period (noise units), rounded up to a power of two samples: values repeat
        every ``extent`` cells. The octaves of a texture read one table at different
        scales, so a short period repeats only each octave's own pattern.
    seed : int
        The texture's seed; stream ``k``'s white noise is seeded by :func:`stream_seed` ``(seed, k)``.
    """

    def __init__(self, extent: float, seed: int) -> None:
        if not (math.isfinite(extent) and 1 <= extent <= 256):
            raise ValueError(f"extent: expected a period in [1, 256] noise units, got {extent!r}")
        self.m = 1 << int(math.ceil(math.log2(extent / _STEP)))
        self.extent = self.m * _STEP
        import threading

        super().__init__(seed)
        self._tables: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()
        self._filter: np.ndarray | None = None

    def _amplitude(self) -> np.ndarray:
        if self._filter is None:
            from noise.spectra import interpolate_psd, scn_slice_psd

            rho, psd = scn_slice_psd()
            f = np.fft.fftfreq(self.m, d=_STEP)
            radius = np.hypot(f[:, None], np.fft.rfftfreq(self.m, d=_STEP)[None, :])
            # White noise of unit variance has |FFT|^2 = m^2 on average; a field of PSD S
            # (variance x unit^2) has variance sum(S) df^2 with df = 1 / (m step).
            self._filter = np.sqrt(interpolate_psd(rho, psd, radius)) / _STEP
            self._filter[0, 0] = 0.0
        return self._filter

    def table(self, stream: int) -> np.ndarray:
        """The tabulated values of stream ``stream`` ((m, m), rows along y), computed on first use
        (by one thread: readers from several threads wait for it)."""
        table = self._tables.get(stream)
        if table is None:
            with self._lock:
                table = self._tables.get(stream)
                if table is None:
                    white = np.random.default_rng(stream_seed(self.seed, stream)).standard_normal(
                        (self.m, self.m)
                    )
                    spectrum = np.fft.rfft2(white) * self._amplitude()
                    values = np.fft.irfft2(spectrum, s=(self.m, self.m))
                    table = np.ascontiguousarray(values, dtype=np.float32)
                    self._tables[stream] = table
        return table

    def prepare(self, streams: tuple[int, ...]) -> None:
        """Compute the tables of ``streams`` now."""
        for stream in streams:
            self.table(stream)

    def __call__(
        self, points: np.ndarray, stream: int = 0, scale: float = 1.0, shift: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        """Noise of stream ``stream`` at ``scale * points + shift`` ((n, 2), noise units), bilinearly."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"points: expected an (n, 2) array, got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("points: expected finite coordinates, found NaN or infinity")
        out = np.empty(pts.shape[0])
        _bilinear(self.table(stream), pts, 1.0 / _STEP, float(scale), float(shift[0]), float(shift[1]), out)
        return out

    def octave_sum(self, points, stream, scales, weights, shifts, absolute=False) -> np.ndarray:
        """:meth:`Sampler.octave_sum` in one pass over the points."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        if pts.ndim != 2 or pts.shape[1] != 2 or not np.all(np.isfinite(pts)):
            raise ValueError(f"points: expected a finite (n, 2) array, got shape {pts.shape}")
        scales = np.ascontiguousarray(scales, dtype=np.float64)
        out = np.empty(pts.shape[0])
        _octave_sum(
            self.table(stream),
            pts,
            1.0 / _STEP,
            scales,
            np.ascontiguousarray(weights, dtype=np.float64),
            np.ascontiguousarray(np.reshape(shifts, (scales.size, 2)), dtype=np.float64),
            bool(absolute),
            out,
        )
        return out
