"""Height fields: the one type that texture, processing, slicing and BRDF stages exchange."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class HeightField:
    """Heights on a regular grid.

    Attributes
    ----------
    heights_mm : (ny, nx) float64 array
        Height of each sample (mm); row ``r`` lies at ``y = origin_y_mm + r * pitch_y_mm``,
        column ``c`` at ``x = origin_x_mm + c * pitch_x_mm``.
    pitch_x_mm, pitch_y_mm : float
        Sample spacing along x and y (mm). Non-square pixels are kept as they are.
    origin_x_mm, origin_y_mm : float
        Position of sample (0, 0) (mm).
    """

    heights_mm: np.ndarray
    pitch_x_mm: float
    pitch_y_mm: float
    origin_x_mm: float = 0.0
    origin_y_mm: float = 0.0

    def __post_init__(self) -> None:
        h = self.heights_mm
        if h.ndim != 2 or min(h.shape) < 2:
            raise ValueError(f"heights_mm: expected a 2-D array of at least 2x2 samples, got shape {h.shape}")
        if not np.all(np.isfinite(h)):
            raise ValueError("heights_mm: expected finite heights, found NaN or infinity")
        if not (self.pitch_x_mm > 0 and self.pitch_y_mm > 0):
            raise ValueError("pitch: expected positive pixel pitches")

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights_mm.shape  # type: ignore[return-value]

    @property
    def width_mm(self) -> float:
        """Extent along x from the first to the last sample (mm)."""
        return (self.shape[1] - 1) * self.pitch_x_mm

    @property
    def depth_mm(self) -> float:
        """Extent along y from the first to the last sample (mm)."""
        return (self.shape[0] - 1) * self.pitch_y_mm

    def grid_points(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y (mm) of every sample, each shaped like ``heights_mm``."""
        ny, nx = self.shape
        x = self.origin_x_mm + np.arange(nx) * self.pitch_x_mm
        y = self.origin_y_mm + np.arange(ny) * self.pitch_y_mm
        return np.meshgrid(x, y)

    def integral_mm3(self) -> float:
        """Volume under the height field by the trapezoidal rule (mm^3)."""
        return float(
            np.trapezoid(np.trapezoid(self.heights_mm, dx=self.pitch_x_mm, axis=1), dx=self.pitch_y_mm)
        )

    def slopes(self) -> tuple[np.ndarray, np.ndarray]:
        """Slopes dh/dx and dh/dy (dimensionless) at the interior samples, by central differences.

        Both components are taken at the same sample. (Forward differences along x
        and y sit half a pixel apart, and the triangles of a fixed-diagonal split
        favour one diagonal; for detail a few pixels across at oblique angles, both
        mix the two directions and understate anisotropy.)
        """
        h = self.heights_mm
        if min(h.shape) < 3:
            raise ValueError(f"heights_mm: slopes need at least 3x3 samples, got shape {h.shape}")
        sx = (h[1:-1, 2:] - h[1:-1, :-2]) / (2.0 * self.pitch_x_mm)
        sy = (h[2:, 1:-1] - h[:-2, 1:-1]) / (2.0 * self.pitch_y_mm)
        return sx, sy
