"""A height map as a closed, printable slab: ``printapp emboss`` (the talk's Blender step, as one command)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from noise.heightfield import HeightField
from printapp.errors import DesignError
from printapp.memory import BASE_BYTES, EMBOSS_BYTES_PER_SAMPLE, fits, require
from slicing import UnknownPrinterError, find_printer

MAX_SAMPLES = 16_000_000
"""Most samples of a resampled map (about 128 MB of float64 heights, a few GB of mesh)."""


@dataclass(frozen=True)
class Embossed:
    """A slab made from a height map."""

    field: HeightField
    """The relief as resampled (mm, lifted to start at zero)."""
    base_mm: float
    triangles: int
    worst_error_mm: float | None
    """With an adaptive top: the largest distance of a sample from the triangles."""
    written: list[Path]


def grid_for_pitch(width_mm: float, depth_mm: float, pitch_mm: float) -> tuple[int, int]:
    """Samples (nx, ny) covering ``width_mm`` x ``depth_mm`` at about ``pitch_mm``.

    Raises
    ------
    DesignError
        If the grid would hold more than :data:`MAX_SAMPLES` samples.
    """
    nx_f, ny_f = width_mm / pitch_mm + 1, depth_mm / pitch_mm + 1
    if not (math.isfinite(nx_f) and math.isfinite(ny_f)) or nx_f * ny_f > 4 * MAX_SAMPLES:
        raise DesignError(
            f"--pitch-mm: {pitch_mm:g} mm over {width_mm:g} x {depth_mm:g} mm is far more than "
            f"{MAX_SAMPLES:,} samples"
        )
    nx, ny = max(2, round(width_mm / pitch_mm) + 1), max(2, round(depth_mm / pitch_mm) + 1)
    if nx * ny > MAX_SAMPLES:
        raise DesignError(
            f"--pitch-mm: {pitch_mm:g} mm gives {nx} x {ny} samples; expected at most {MAX_SAMPLES:,}"
        )
    return nx, ny


def resample(
    heights_mm: np.ndarray, pitch_x_mm: float, pitch_y_mm: float, nx: int, ny: int, target_mm: float
) -> np.ndarray:
    """The map on ``ny`` x ``nx`` samples spanning the same extent, anti-aliased first.

    A Gaussian whose sigma is half the target pitch ``target_mm`` in samples takes out
    what the coarser grid cannot hold; then bilinear interpolation. A map already of
    that size is copied.
    """
    if (ny, nx) == heights_mm.shape:
        return heights_mm.copy()
    from scipy.ndimage import gaussian_filter, map_coordinates

    sigma = (max(0.0, 0.5 * (target_mm / pitch_x_mm - 1)), max(0.0, 0.5 * (target_mm / pitch_y_mm - 1)))
    smooth = gaussian_filter(heights_mm, sigma=(sigma[1], sigma[0]), mode="nearest")
    rows = np.linspace(0, heights_mm.shape[0] - 1, ny)
    cols = np.linspace(0, heights_mm.shape[1] - 1, nx)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    return map_coordinates(smooth, [rr, cc], order=1, mode="nearest")


def emboss_heightmap(
    source: Path,
    out: Path,
    *,
    width_mm: float | None = None,
    depth_mm: float | None = None,
    base_mm: float = 2.0,
    pitch_mm: float | None = None,
    printer: str = "prusa-sl1",
    flatten: str | None = None,
    max_error_um: float | None = None,
) -> Embossed:
    """Read a height map, resample it to the printer's pixel, close it into a slab and write it.

    The map is low-pass filtered and resampled to ``pitch_mm`` (default: the printer's
    pixel pitch; no more triangles than the printer can print), lifted to start at zero,
    and closed with walls and a floor ``base_mm`` thick. With ``max_error_um``, the top is
    an adaptive triangulation with as few triangles as keep every sample within that.
    The slab is closed and consistently oriented by construction (see
    :func:`printapp.slab.slab_arrays` and its invariant tests), so the costly solid
    checks of ``printapp design`` are not run.
    """
    from printapp.exporters import check_mesh_output, write_mesh
    from printapp.slab import slab_arrays
    from printapp.topography import load_corrected

    try:
        profile = find_printer(printer)
    except UnknownPrinterError as exc:
        raise DesignError(f"--printer: {exc}") from None
    check_mesh_output(out)
    if not (math.isfinite(base_mm) and base_mm > 0):
        raise DesignError(f"--base-mm: expected a positive, finite thickness, got {base_mm}")
    target = profile.pitch_mm if pitch_mm is None else pitch_mm
    if not (math.isfinite(target) and target > 0):
        raise DesignError(f"--pitch-mm: expected a positive, finite pitch, got {pitch_mm}")
    if max_error_um is not None and not (math.isfinite(max_error_um) and max_error_um >= 0):
        raise DesignError(f"--max-error-um: expected a finite number >= 0, got {max_error_um}")
    if source.suffix.lower() == ".npy":
        raise DesignError(f"{source}: give an image or a measured map to emboss (a .npy has no depth scale)")
    corrected = load_corrected(source, width_mm=width_mm, depth_mm=depth_mm, flatten=flatten)
    heights, px, py = corrected.heights_mm, corrected.pitch_x_mm, corrected.pitch_y_mm
    width, depth = (heights.shape[1] - 1) * px, (heights.shape[0] - 1) * py
    fits_display = (width <= profile.display_width_mm and depth <= profile.display_height_mm) or (
        width <= profile.display_height_mm and depth <= profile.display_width_mm
    )
    if not fits_display:
        scale = "--width-mm" if source.suffix.lower() in (".png", ".tif", ".tiff") else "its pixel size"
        raise DesignError(
            f"{source}: the map spans {width:.6g} x {depth:.6g} mm ({scale}), larger than the "
            f"{profile.label}'s {profile.display_width_mm:g} x {profile.display_height_mm:g} mm display; "
            "expected a map that fits the printer"
        )
    if target > min(width, depth) / 2.0:
        raise DesignError(
            f"--pitch-mm: {target:g} mm leaves fewer than 3 samples across the {width:.6g} x {depth:.6g} mm "
            f"map; expected at most {min(width, depth) / 2.0:.6g} mm"
        )
    nx, ny = grid_for_pitch(width, depth, target)
    finest = math.sqrt(width * depth / max(fits(EMBOSS_BYTES_PER_SAMPLE), 1.0))
    require(
        BASE_BYTES + float(nx) * ny * EMBOSS_BYTES_PER_SAMPLE,
        what=f"a slab of {nx} x {ny} samples",
        setting="--pitch-mm",
        fitting=f"--pitch-mm {finest:.4g} fits",
    )
    resampled = resample(heights, px, py, nx, ny, target)
    resampled -= resampled.min()
    field = HeightField(resampled, width / (nx - 1), depth / (ny - 1))
    worst = None
    if max_error_um is None:
        vertices, faces = slab_arrays(field, base_mm)
    else:
        from printapp.adaptive_slab import adaptive_slab_arrays  # scipy and numba: only when asked

        vertices, faces, worst = adaptive_slab_arrays(resampled, width, depth, base_mm, max_error_um / 1000)
    written = write_mesh(out, vertices, faces)
    return Embossed(field, base_mm, len(faces), worst, written)
