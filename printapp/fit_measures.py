"""What ``printapp fit`` compares: six measures of how a texture looks, each against the photo's own.

Two samples of one stochastic texture differ at every pixel, so a fit is judged by
statistics, the ones that carry what a person sees in a texture:

1. **spectrum**: the radially averaged power spectrum (Hann-windowed periodogram,
   :func:`noise.spectra.periodogram`) in bins half an octave wide from one cycle per image
   (the image's largest scale) to the Nyquist frequency, compared as the RMS of the
   log10 ratio with equal weight per bin, i.e. per octave (decades). Roughness (the slope;
   fBm's ``P ~ f^-(2H+2)``, Voss 1988), the scale of features and the balance of coarse and
   fine detail are all in it; averaging over linear frequency instead lets the many fine
   samples drown the coarse ones.
2. **orientation**: the power spectrum's angular distribution in each octave band (eight
   bins over 180 degrees, log10 power less the band's mean): directions of veins, grain and
   stretch, scale by scale (decades, RMS).
3. **values**: the 1-Wasserstein distance of the value distributions, per colour channel and
   averaged (sRGB units, 0..1), the first-order statistics of Portilla & Simoncelli 2000.
4. **lines**: thin-structure statistics from multi-scale Hessian line filters of both
   polarities (:mod:`noise.line_filters`; Sato et al. 1998, Frangi et al. 1998): per scale
   (1, 2, 4, 8 px) and polarity, log10 of the mean line strength and of its 90th and 99th
   percentiles (how sparse and strong the lines are), and the correlation of the strengths
   across neighbouring scales (the magnitude correlations across scale of Portilla &
   Simoncelli 2000, "A parametric texture model based on joint statistics of complex
   wavelet coefficients", IJCV 40(1)). Veins and cracks are sparse, strong, continuous
   across scales; clouds of noise are none of these.
5. **layout**: how the lines are laid out, the spectra of the finest three line-strength
   maps (each over its mean) in half-octave bins: the magnitude autocorrelations of
   Portilla & Simoncelli, over the whole image instead of a 7 x 7 neighbourhood. A network
   of long veins puts the maps' power at the network's scale; specks spread it evenly.
6. **continuity**: how far the lines run unbroken: the chance that a pixel on a line (in
   the top 1 % of line strength, at the finest two scales) is still on one 4, 8, 16 and
   32 px along the line's own direction, in decades above chance (:func:`continuity`).
   Veins and cracks run on; specks and grain, which the other line statistics cannot
   tell from thin veins, stop at once.

Each distance is reported as a **ratio** to the photo's own variation: the same measure
between the photo's left and right halves, and between its bottom and top halves,
averaged (two splits instead of one: a vein network puts few veins in a half, and one
split alone scatters by a third). A synthesis is compared half against the other half
(its left half with the photo's right, right with left, bottom with top, top with
bottom, averaged), so 1.0 means "as close to the photo as the photo is to itself".
Differences below :data:`FLOORS` (too small to see) count as that floor.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from noise.line_filters import line_field
from noise.spectra import PolarBins, periodogram, polar_bins, wasserstein_1d

N_ANGLES = 8
QUANTILES = (0.9, 0.99)


def line_scales(shape: tuple[int, int]) -> tuple[float, ...]:
    """Scales (px) of the line filters for an image of ``shape``: 1, 2, 4 (and 8 from 256 px on)."""
    return (1.0, 2.0, 4.0, 8.0) if min(shape) >= 256 else (1.0, 2.0, 4.0)


class _Bins(NamedTuple):
    bins: PolarBins
    keep: np.ndarray
    """The frequency samples inside the bins (flat indices) ..."""
    which: np.ndarray
    """... and their bins."""


def _with_kept(bins: PolarBins) -> _Bins:
    keep = np.flatnonzero(bins.index >= 0)
    return _Bins(bins, keep, bins.index[keep])


@functools.lru_cache(maxsize=32)
def _radial_bins(shape: tuple[int, int]) -> _Bins:
    return _with_kept(polar_bins(shape, f_min=1.0 / min(shape), f_max=0.5, bins_per_octave=2.0, n_angular=1))


@functools.lru_cache(maxsize=32)
def _band_bins(shape: tuple[int, int]) -> _Bins:
    return _with_kept(
        polar_bins(shape, f_min=2.0 / min(shape), f_max=0.5, bins_per_octave=1.0, n_angular=N_ANGLES)
    )


def _binned_log(power: np.ndarray, binned: _Bins) -> np.ndarray:
    bins = binned.bins
    sums = np.bincount(binned.which, weights=power.ravel()[binned.keep], minlength=bins.counts.size)
    counts = bins.counts.ravel()
    floor = 1e-12 * max(float(power.mean()), 1e-300)
    mean = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    return np.log10(np.maximum(mean, floor)).reshape(bins.counts.shape)


def spectra(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The radial log spectrum (half-octave bins) and the orientation spectrum (octave bands x 8 angles).

    Returns
    -------
    radial : (n_bins,) log10 mean power (NaN for an empty bin)
    orientation : (n_bands, 8) log10 mean power less each band's mean over angles
    """
    return spectra_of_power(periodogram(image))


def spectra_of_power(power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`spectra` from a periodogram (or a mean of periodograms, Welch's estimate)."""
    shape = (int(power.shape[0]), int(power.shape[1]))
    radial = _binned_log(power, _radial_bins(shape))[:, 0]
    bands = _binned_log(power, _band_bins(shape))
    orientation = bands - np.nanmean(bands, axis=1, keepdims=True)
    return radial, orientation


def line_statistics(strengths: np.ndarray, scale: float) -> np.ndarray:
    """The line measure's vector from line strengths ((scales, 2, ny, nx), :func:`line_maps`).

    Per scale and polarity: log10 of the mean and of the 90th and 99th percentiles; per
    polarity and pair of neighbouring scales: the correlation of the strengths. ``scale``
    (the image's standard deviation) sets the floor, 1e-3 of it, below which a strength
    counts as none.
    """
    n_scales = strengths.shape[0]
    flat = strengths.reshape(n_scales, 2, -1)
    floor = 1e-3 * max(scale, 1e-9)
    means = np.log10(flat.mean(axis=2) + floor)
    tails = np.log10(np.quantile(flat, QUANTILES, axis=2) + floor)
    correlations = []
    for s in range(n_scales - 1):
        for p in range(2):
            a, b = flat[s, p], flat[s + 1, p]
            sa, sb = a.std(), b.std()
            correlations.append(
                0.0 if sa <= 0 or sb <= 0 else float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb))
            )
    return np.concatenate([means.ravel(), tails.ravel(), np.asarray(correlations)])


class LineMaps(NamedTuple):
    """An image's line strengths ((scales, 2, ny, nx): bright, dark) and directions ((scales, ny, nx))."""

    strengths: np.ndarray
    along: np.ndarray

    def crop(self, rows: slice, cols: slice) -> LineMaps:
        return LineMaps(self.strengths[:, :, rows, cols], self.along[:, rows, cols])


def line_maps(lum: np.ndarray, scales: tuple[float, ...] | None = None) -> LineMaps:
    """Line strengths and directions of an image at ``scales`` (default :func:`line_scales`)."""
    return LineMaps(*line_field(lum, line_scales(lum.shape) if scales is None else scales))


CONTINUITY_LAGS = (4, 8, 16, 32)
"""Distances (px) along a line at which the continuity measure correlates its strength."""
CONTINUITY_SCALES = 2
_DIRECTIONS = ((1, 0), (1, 1), (0, 1), (-1, 1))
"""Steps (x, y) along lines running at 0, 45, 90 and 135 degrees."""


CONTINUITY_QUANTILE = 0.99
"""Pixels whose line strength is in the top 1 % of the image are on a line, for the continuity measure."""


def continuity(maps: LineMaps) -> np.ndarray:
    """How far lines run: the chance that a pixel on a line is still on a line ``d`` px along it.

    Per scale (the finest two) and polarity, a pixel is on a line where its strength is
    in the image's top 1 %; each such pixel looks ``d`` px (:data:`CONTINUITY_LAGS`) along
    the direction its line runs (nearest of 0, 45, 90, 135 degrees) and counts whether
    that pixel is on a line too. Veins and cracks run on (high chances out to their
    length); specks and grain, which the other line statistics cannot tell from thin
    veins, stop at once (chances near 1 %, the share of line pixels). Returned as
    ``log10`` of the chance over that share (decades above chance, 0 at chance). A form
    of the magnitude correlations across position of Portilla & Simoncelli 2000, taken
    along each line.
    """
    rows = []
    for s in range(min(CONTINUITY_SCALES, maps.strengths.shape[0])):
        channel = np.round(maps.along[s] / (np.pi / 4)).astype(np.int64) % 4
        for p in range(2):
            r = maps.strengths[s, p]
            on = r > np.quantile(r, CONTINUITY_QUANTILE)
            starts = [on & (channel == k) for k in range(4)]
            row = []
            for d in CONTINUITY_LAGS:
                hits, count = 0, 0
                for k, (sx, sy) in enumerate(_DIRECTIONS):
                    step = d / math.hypot(sx, sy)
                    dx, dy = int(round(sx * step)), int(round(sy * step))
                    start = _overlap(starts[k], dx, dy, 0)
                    hits += int(np.count_nonzero(start & _overlap(on, dx, dy, 1)))
                    count += int(np.count_nonzero(start))
                row.append(hits / count if count else 0.0)
            rows.append(row)
    chance = 1.0 - CONTINUITY_QUANTILE
    return np.log10(np.maximum(np.array(rows), chance) / chance)


def _overlap(a: np.ndarray, dx: int, dy: int, which: int) -> np.ndarray:
    """The part of ``a`` that overlaps ``a`` shifted by (dx, dy): the unshifted (0) or shifted (1) view."""
    ny, nx = a.shape
    if abs(dx) >= nx or abs(dy) >= ny:
        return a[:0, :0]
    y0, y1 = max(0, -dy), min(ny, ny - dy)
    x0, x1 = max(0, -dx), min(nx, nx - dx)
    if which == 0:
        return a[y0:y1, x0:x1]
    return a[y0 + dy : y1 + dy, x0 + dx : x1 + dx]


LAYOUT_SCALES = 3
"""The layout measure looks at the line strengths of the finest three scales."""


def layout_spectra(strengths: np.ndarray) -> np.ndarray:
    """How the lines are laid out: the radial log spectrum of each fine line-strength map over its mean.

    Returns
    -------
    (2 * LAYOUT_SCALES, n_bins) float array: per scale and polarity, log10 of the power of
    ``strength / mean(strength)`` in half-octave bins (:func:`spectra`). Long, connected
    veins put power at the scale of their network; scattered specks spread it evenly.
    """
    rows = []
    for s in range(min(LAYOUT_SCALES, strengths.shape[0])):
        for p in range(2):
            m = strengths[s, p]
            mean = float(m.mean())
            rows.append(spectra_of_power(periodogram(m / mean if mean > 0 else m))[0])
    return np.array(rows)


@dataclass(frozen=True)
class Stats:
    """The statistics of one image that the measures compare."""

    shape: tuple[int, int]
    spectrum: np.ndarray
    orientation: np.ndarray
    values: tuple[np.ndarray, ...]
    """Sorted values of each colour channel (one for grey)."""
    lines: np.ndarray
    layout: np.ndarray
    continuity: np.ndarray

    @classmethod
    def of(cls, lum: np.ndarray, rgb: np.ndarray | None = None, lines: LineMaps | None = None) -> Stats:
        """Statistics of a luminance image (and its colours); ``lines`` are its line maps if known."""
        lum = np.asarray(lum, dtype=np.float64)
        radial, orientation = spectra(lum)
        channels = (lum,) if rgb is None else tuple(rgb[..., c] for c in range(rgb.shape[-1]))
        maps = line_maps(lum) if lines is None else lines
        return cls(
            shape=(int(lum.shape[0]), int(lum.shape[1])),
            spectrum=radial,
            orientation=orientation,
            values=tuple(np.sort(c, axis=None) for c in channels),
            lines=line_statistics(maps.strengths, float(lum.std())),
            layout=layout_spectra(maps.strengths),
            continuity=continuity(maps),
        )


@dataclass(frozen=True)
class Distances:
    """How far apart two images are, by each measure (see the module docstring for units)."""

    spectrum: float
    orientation: float
    values: float
    lines: float
    layout: float
    continuity: float

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def mean(cls, items: list[Distances]) -> Distances:
        return cls(**{f.name: float(np.mean([getattr(d, f.name) for d in items])) for f in fields(cls)})

    @classmethod
    def median(cls, items: list[Distances]) -> Distances:
        return cls(**{f.name: float(np.median([getattr(d, f.name) for d in items])) for f in fields(cls)})


MEASURES = tuple(f.name for f in fields(Distances))
FLOORS = Distances(spectrum=0.1, orientation=0.1, values=2.0 / 255.0, lines=0.05, layout=0.1, continuity=0.1)
"""Differences too small to see: 12 % in amplitude (0.1 decades of power, 0.05 decades of line
strength; about the contrast increment at which a difference between textures becomes
visible, Legge & Foley 1980), two 8-bit grey levels in the values (about one just noticeable
difference: sRGB's steps are about half of one), 0.1 decades (26 %) in a chance of continuing."""


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if not np.any(ok):
        return 0.0
    d = a[ok] - b[ok]
    return float(np.sqrt(np.mean(d * d)))


def distances(a: Stats, b: Stats) -> Distances:
    """The four measures between two images of the same shape."""
    if a.shape != b.shape:
        raise ValueError(f"expected statistics of images of the same shape, got {a.shape} and {b.shape}")
    na, nb = len(a.values), len(b.values)
    channels = max(na, nb)
    values = np.mean(
        [wasserstein_1d(a.values[min(c, na - 1)], b.values[min(c, nb - 1)]) for c in range(channels)]
    )
    return Distances(
        spectrum=_rms(a.spectrum, b.spectrum),
        orientation=_rms(a.orientation, b.orientation),
        values=float(values),
        lines=_rms(a.lines, b.lines),
        layout=_rms(a.layout, b.layout),
        continuity=_rms(a.continuity, b.continuity),
    )


def ratios(fit: Distances, photo: Distances) -> dict[str, float]:
    """Per measure, the fit's distance over the photo's halves' distance (both floored at :data:`FLOORS`)."""
    return {
        name: max(getattr(fit, name), getattr(FLOORS, name))
        / max(getattr(photo, name), getattr(FLOORS, name))
        for name in MEASURES
    }


def halves(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The left, right, bottom and top halves of an image (each pair of equal size)."""
    h, w = image.shape[0] // 2, image.shape[1] // 2
    return image[:, :w], image[:, w : 2 * w], image[:h], image[h : 2 * h]


def half_stats(
    lum: np.ndarray, rgb: np.ndarray | None = None, maps: LineMaps | None = None
) -> tuple[Stats, ...]:
    """Statistics of the left, right, bottom and top halves; the line maps are filtered once
    over the whole image (``maps``, :func:`line_maps`, if already known)."""
    maps = line_maps(lum) if maps is None else maps
    h, w = lum.shape[0] // 2, lum.shape[1] // 2
    cuts = [
        (slice(None), slice(0, w)),
        (slice(None), slice(w, 2 * w)),
        (slice(0, h), slice(None)),
        (slice(h, 2 * h), slice(None)),
    ]
    return tuple(
        Stats.of(lum[rows, cols], None if rgb is None else rgb[rows, cols], lines=maps.crop(rows, cols))
        for rows, cols in cuts
    )


def own_distance(halves_stats: tuple[Stats, ...]) -> Distances:
    """The photo's own variation: left half against right, bottom against top, averaged."""
    a = halves_stats
    return Distances.mean([distances(a[0], a[1]), distances(a[2], a[3])])


def halves_distance(a: tuple[Stats, ...], b: tuple[Stats, ...]) -> Distances:
    """Image A against image B, half against the other half: A's left against B's right, right against
    left, bottom against top and top against bottom, averaged."""
    return Distances.mean(
        [distances(a[0], b[1]), distances(a[1], b[0]), distances(a[2], b[3]), distances(a[3], b[2])]
    )


def match_values(s: np.ndarray, sorted_target: np.ndarray, sign: float = 1.0) -> np.ndarray:
    """``s`` mapped monotonically onto a target distribution (rank by rank): exact histogram matching.

    The ``k``-th smallest of ``sign * s`` takes the target's quantile at ``(k + 1/2) / n``.
    """
    flat = (sign * np.asarray(s, dtype=np.float64)).ravel()
    order = np.argsort(flat, kind="stable")
    n, m = flat.size, sorted_target.size
    if n == m:
        quantiles = sorted_target
    else:
        positions = (np.arange(n) + 0.5) / n * m - 0.5
        quantiles = np.interp(positions, np.arange(m), sorted_target)
    out = np.empty(n)
    out[order] = quantiles
    return out.reshape(np.shape(s))
