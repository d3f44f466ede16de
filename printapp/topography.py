"""Measured and image height maps (read by :mod:`printapp.heightmap_readers`): corrected the
way Gwyddion does, and their ISO 25178 areal roughness parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from noise.heightfield import HeightField
from printapp.errors import DesignError
from printapp.heightmap_readers import read_heightmap

# ---------------------------------------------------------------------------------------------
# Corrections (Gwyddion's "mask outliers", "remove data under mask", "level")


def mask_outliers(heights: np.ndarray, threshold: float = 5.0) -> np.ndarray:
    """Samples farther than ``threshold`` robust standard deviations (1.4826 MAD) from the median."""
    finite = np.isfinite(heights)
    median = np.median(heights[finite])
    mad = 1.4826 * np.median(np.abs(heights[finite] - median))
    if mad == 0:
        return ~finite
    return ~finite | (np.abs(heights - median) > threshold * mad)


def fill_masked(heights: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Replace masked samples by linear interpolation from the valid ones (nearest at the border)."""
    if not mask.any():
        return heights.copy()
    from scipy.interpolate import griddata

    rows, cols = np.indices(heights.shape)
    known = ~mask
    points = np.column_stack([rows[known], cols[known]])
    wanted = np.column_stack([rows[mask], cols[mask]])
    filled = heights.copy()
    linear = griddata(points, heights[known], wanted, method="linear")
    missing = ~np.isfinite(linear)
    if missing.any():
        linear[missing] = griddata(points, heights[known], wanted[missing], method="nearest")
    filled[mask] = linear
    return filled


def level(heights: np.ndarray, order: int = 1, mask: np.ndarray | None = None) -> np.ndarray:
    """Subtract the least-squares polynomial of total degree ``order`` (1: a plane), fitted where valid."""
    if order < 0:
        raise ValueError("order: expected a degree >= 0")
    rows, cols = heights.shape
    y, x = np.indices((rows, cols), dtype=np.float64)
    x = (x - (cols - 1) / 2) / max(cols - 1, 1)
    y = (y - (rows - 1) / 2) / max(rows - 1, 1)
    terms = [x**i * y**j for i in range(order + 1) for j in range(order + 1 - i)]
    valid = np.isfinite(heights) if mask is None else (~mask & np.isfinite(heights))
    basis = np.stack([t[valid] for t in terms], axis=1)
    coefficients, *_ = np.linalg.lstsq(basis, heights[valid], rcond=None)
    surface = sum(c * t for c, t in zip(coefficients, terms, strict=True))
    return heights - surface


# ---------------------------------------------------------------------------------------------
# ISO 25178 areal parameters (on the mean-removed surface; no S- or L-filter)


@dataclass(frozen=True)
class Roughness:
    """ISO 25178-2 areal parameters. Heights in µm; Sdq dimensionless; Sdr in %."""

    sa_um: float
    sq_um: float
    sz_um: float
    ssk: float
    sku: float
    sdq: float
    sdr_percent: float


def roughness(heights_mm: np.ndarray, pitch_x_mm: float, pitch_y_mm: float) -> Roughness:
    """Sa, Sq, Sz (max peak to max pit), Ssk, Sku, Sdq (rms gradient), Sdr (developed area ratio).

    The mean is removed first; missing (NaN) samples are skipped. Gradients are central
    differences (one-sided at the border), Sdr from the gradient at each sample:
    mean(sqrt(1 + |grad|^2)) - 1.
    """
    z = np.asarray(heights_mm, dtype=np.float64)
    valid = np.isfinite(z)
    if valid.sum() < 4:
        raise ValueError("heights: expected at least four valid samples")
    z = z - z[valid].mean()
    v = z[valid]
    sq = math.sqrt(float(np.mean(v**2)))
    gy, gx = np.gradient(z, pitch_y_mm, pitch_x_mm)
    g2 = gx**2 + gy**2
    gvalid = np.isfinite(g2)
    return Roughness(
        sa_um=float(np.mean(np.abs(v))) * 1000.0,
        sq_um=sq * 1000.0,
        sz_um=float(v.max() - v.min()) * 1000.0,
        # Moments of the normalised heights: the same values, no overflow of sq**4.
        ssk=float(np.mean((v / sq) ** 3)) if sq > 0 else 0.0,
        sku=float(np.mean((v / sq) ** 4)) if sq > 0 else 0.0,
        sdq=math.sqrt(float(np.mean(g2[gvalid]))),
        sdr_percent=float(np.mean(np.sqrt(1.0 + g2[gvalid])) - 1.0) * 100.0,
    )


@dataclass(frozen=True)
class Lateral:
    """ISO 25178-2 spatial parameters from the autocorrelation function and the angular spectrum."""

    sal_um: float
    """Autocorrelation length: the shortest distance at which the ACF falls to 0.2 (µm)."""
    str_ratio: float
    """Texture aspect ratio: that distance over the longest one (1 isotropic, near 0 a strong lay)."""
    std_deg: float
    """Texture direction: the direction of the lay, along which features run, in [0, 180) from +x."""
    reached: bool
    """Whether the ACF fell to 0.2 in every direction within the map (else Str is an upper bound)."""
    lay_deg: float = 0.0
    """Direction in which the ACF decays slowest (the long axis of Str's region), [0, 180) from +x."""


ACF_THRESHOLD = 0.2
"""ISO 25178-2's default ``s`` for Sal and Str."""


def lateral(heights_mm: np.ndarray, pitch_x_mm: float, pitch_y_mm: float, directions: int = 180) -> Lateral:
    """Sal, Str and Std of a height map (mean removed, missing samples as the mean).

    The areal autocorrelation function is taken by FFT with zero padding (no wrap-around),
    each lag divided by its number of overlapping pairs, and normalised to 1 at zero lag.
    Along ``directions`` rays from the origin (bilinear, steps of half a pitch, out to half
    the map) the first distance at which it falls to 0.2 is found: Sal is the shortest,
    Str the shortest over the longest (ISO 25178-2, 4.2.1 and 4.2.2). Std (4.2.3) comes
    from the angular power spectrum, the periodogram summed over rays in each direction:
    its maximum lies across the lay, so the lay runs at that direction plus 90 degrees.
    ``lay_deg`` is the direction of the ACF's slowest decay to 0.2, the long axis of the
    region Str measures: the same lay seen at the scale of Sal rather than of the largest
    features (whose direction is that of few samples).
    """
    z = np.asarray(heights_mm, dtype=np.float64)
    valid = np.isfinite(z)
    z = np.where(valid, z - z[valid].mean(), 0.0)
    ny, nx = z.shape
    spectrum = np.fft.rfft2(z, s=(2 * ny, 2 * nx))
    acf = np.fft.irfft2(spectrum * np.conj(spectrum), s=(2 * ny, 2 * nx))
    counts_spec = np.fft.rfft2(valid.astype(np.float64), s=(2 * ny, 2 * nx))
    counts = np.fft.irfft2(counts_spec * np.conj(counts_spec), s=(2 * ny, 2 * nx))
    acf = np.where(counts > 0.5, acf / np.maximum(counts, 1.0), 0.0)
    acf = np.fft.fftshift(acf)
    acf /= acf[ny, nx] if acf[ny, nx] > 0 else 1.0
    limit = 0.5 * min(nx * pitch_x_mm, ny * pitch_y_mm)
    step = 0.5 * min(pitch_x_mm, pitch_y_mm)
    radii = np.arange(1, int(limit / step) + 1) * step
    angles = np.arange(directions) * (np.pi / directions)
    from scipy.ndimage import map_coordinates

    cols = nx + np.outer(np.cos(angles), radii) / pitch_x_mm
    rows = ny + np.outer(np.sin(angles), radii) / pitch_y_mm
    profile = map_coordinates(acf, [rows.ravel(), cols.ravel()], order=1).reshape(rows.shape)
    below = profile <= ACF_THRESHOLD
    reached = bool(np.all(below.any(axis=1)))
    first = np.where(below.any(axis=1), below.argmax(axis=1), radii.size - 1)
    # Interpolate the crossing between the last sample above and the first below.
    lengths = np.empty(directions)
    for k, i in enumerate(first):
        if i == 0 or not below[k, i]:
            lengths[k] = radii[i]
            continue
        a, b = profile[k, i - 1], profile[k, i]
        lengths[k] = radii[i - 1] + (a - ACF_THRESHOLD) / (a - b) * step if a != b else radii[i]
    fy = np.fft.fftshift(np.fft.fftfreq(ny, d=pitch_y_mm))[:, None]
    fx = np.fft.fftshift(np.fft.fftfreq(nx, d=pitch_x_mm))[None, :]
    power = np.abs(np.fft.fftshift(np.fft.fft2(z))) ** 2
    theta = np.mod(np.arctan2(fy, fx), np.pi)
    which = np.minimum((theta / (np.pi / directions)).astype(np.int64), directions - 1)
    keep = np.hypot(fx, fy) > 0
    angular = np.bincount(which[keep], weights=power[keep], minlength=directions)
    # A little smoothing: three neighbouring directions, circularly.
    angular = angular + np.roll(angular, 1) + np.roll(angular, -1)
    across = (np.argmax(angular) + 0.5) * 180.0 / directions
    return Lateral(
        sal_um=float(lengths.min()) * 1000.0,
        str_ratio=float(lengths.min() / lengths.max()),
        std_deg=float(np.mod(across + 90.0, 180.0)),
        reached=reached,
        lay_deg=float(np.degrees(angles[int(np.argmax(lengths))])),
    )


# ---------------------------------------------------------------------------------------------
# What the commands ask for: read, crop, correct, describe


def flatten_order(flatten: str | None) -> int | None:
    """Polynomial order of ``--flatten``: ``plane`` is 1, ``poly:K`` is K (0..8), None leaves the map.

    Raises
    ------
    DesignError
        For any other text.
    """
    if flatten is None:
        return None
    if flatten == "plane":
        return 1
    kind, _, degree = flatten.partition(":")
    if kind == "poly" and degree.isdigit() and 0 <= int(degree) <= 8:
        return int(degree)
    raise DesignError(f"--flatten: expected 'plane' or 'poly:K' with K in 0..8, got '{flatten}'")


def crop_window(crop: str | None, shape: tuple[int, int]) -> tuple[slice, slice]:
    """Rows and columns kept by ``--crop C0:C1,R0:R1`` (samples) from a map of ``shape``.

    Raises
    ------
    DesignError
        If the text is malformed or the window is not at least 2 x 2 samples inside the map.
    """
    if crop is None:
        return slice(None), slice(None)
    try:
        cols, rows = crop.split(",")
        c0, c1 = (int(v) for v in cols.split(":"))
        r0, r1 = (int(v) for v in rows.split(":"))
    except ValueError:
        raise DesignError(f"--crop: expected 'C0:C1,R0:R1' in samples, got '{crop}'") from None
    if not (0 <= c0 < c1 <= shape[1] and 0 <= r0 < r1 <= shape[0] and c1 - c0 >= 2 and r1 - r0 >= 2):
        raise DesignError(
            f"--crop: '{crop}' is not a window of at least 2 x 2 samples inside {shape[1]} x {shape[0]}"
        )
    return slice(r0, r1), slice(c0, c1)


@dataclass(frozen=True)
class Corrected:
    """A height map after cropping, filling and levelling."""

    heights_mm: np.ndarray
    pitch_x_mm: float
    pitch_y_mm: float
    filled: int
    """Samples that were missing (or masked as outliers) and were filled in."""

    def field(self) -> HeightField:
        return HeightField(self.heights_mm, self.pitch_x_mm, self.pitch_y_mm)


def load_corrected(
    path: Path,
    *,
    width_mm: float | None = None,
    depth_mm: float | None = None,
    pitch_mm: float | None = None,
    remove_outliers: bool = False,
    flatten: str | None = None,
    crop: str | None = None,
) -> Corrected:
    """Read a height map (:func:`read_heightmap`), crop it, and apply the corrections.

    Missing data is always filled (:func:`fill_masked`); outliers are masked and filled
    only with ``remove_outliers``; ``flatten`` levels the base (:func:`flatten_order`).
    """
    order = flatten_order(flatten)
    topo = read_heightmap(path, width_mm=width_mm, depth_mm=depth_mm, pitch_mm=pitch_mm)
    heights = topo.heights_mm[crop_window(crop, topo.heights_mm.shape)]
    mask = mask_outliers(heights) if remove_outliers else ~np.isfinite(heights)
    heights = fill_masked(heights, mask)
    if order is not None:
        heights = level(heights, order)
    return Corrected(heights, topo.pitch_x_mm, topo.pitch_y_mm, int(mask.sum()))


def roughness_summary(source: Path, corrected: Corrected, flatten: str | None) -> dict[str, object]:
    """What ``printapp heightmap`` reports: the map's size and pitch and its ISO 25178 parameters."""
    r = roughness(corrected.heights_mm, corrected.pitch_x_mm, corrected.pitch_y_mm)
    return {
        "file": str(source),
        "samples": list(corrected.heights_mm.shape),
        "pitch_um": [corrected.pitch_x_mm * 1000, corrected.pitch_y_mm * 1000],
        "filled_samples": corrected.filled,
        "flatten": flatten,
        "parameters": {
            "Sa_um": r.sa_um,
            "Sq_um": r.sq_um,
            "Sz_um": r.sz_um,
            "Ssk": r.ssk,
            "Sku": r.sku,
            "Sdq": r.sdq,
            "Sdr_percent": r.sdr_percent,
        },
    }


def analyse_heightmap(
    source: Path,
    *,
    out: Path | None = None,
    json_out: Path | None = None,
    width_mm: float | None = None,
    depth_mm: float | None = None,
    pitch_mm: float | None = None,
    remove_outliers: bool = False,
    flatten: str | None = None,
    crop: str | None = None,
) -> dict[str, object]:
    """``printapp heightmap``: correct a map, describe it, and write the corrected map and the summary.

    ``out`` (``.npy``, heights in mm) and ``json_out`` are written together or not at all.
    Returns the summary (:func:`roughness_summary`).
    """
    import io
    import json

    from printapp.outputs import atomic_write_files

    if out is not None and out.suffix.lower() != ".npy":
        raise DesignError(f"{out}: expected an output file ending in .npy")
    corrected = load_corrected(
        source,
        width_mm=width_mm,
        depth_mm=depth_mm,
        pitch_mm=pitch_mm,
        remove_outliers=remove_outliers,
        flatten=flatten,
        crop=crop,
    )
    summary = roughness_summary(source, corrected, flatten)
    outputs: list[tuple[Path, bytes]] = []
    if json_out is not None:
        outputs.append((json_out, (json.dumps(summary, indent=2) + "\n").encode()))
    if out is not None:
        buffer = io.BytesIO()
        np.save(buffer, corrected.heights_mm)
        outputs.append((out, buffer.getvalue()))
    atomic_write_files(outputs)
    return summary
