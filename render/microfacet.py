"""Microfacet statistics of a relief: what its slopes say about its gloss.

Geometric optics for a surface whose relief is much larger than the wavelength: the
distribution of microfacet normals is the distribution of the relief's slopes. For
a Gaussian slope distribution this is Beckmann's, whose roughness per direction is
``alpha = sqrt(2) * sigma_slope`` (Walter et al. 2007, "Microfacet models for
refraction through rough surfaces", eq. 25: slopes have variance alpha^2 / 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SlopeRoughness:
    """Anisotropic Beckmann roughness from slope statistics.

    Attributes
    ----------
    alpha_major, alpha_minor : float
        Roughness along the principal directions of the slope covariance (dimensionless).
    major_azimuth_rad : float
        Direction of ``alpha_major`` in the xy plane, in [0, pi), from +x towards +y.
        Highlights stretch along this direction.
    """

    alpha_major: float
    alpha_minor: float
    major_azimuth_rad: float

    @property
    def roughness(self) -> float:
        """Geometric mean of the principal roughnesses."""
        return math.sqrt(self.alpha_major * self.alpha_minor)

    @property
    def anisotropy(self) -> float:
        """Ratio of the larger to the smaller principal roughness (>= 1; inf for a 1-D relief)."""
        return self.alpha_major / self.alpha_minor if self.alpha_minor > 0 else math.inf


def slope_roughness(slope_x: np.ndarray, slope_y: np.ndarray) -> SlopeRoughness:
    """Beckmann roughness of a relief from its slopes ``dh/dx`` and ``dh/dy`` (dimensionless).

    The 2x2 covariance of the slopes is diagonalised; each principal standard
    deviation ``sigma`` gives ``alpha = sqrt(2) sigma``.
    """
    sx = np.asarray(slope_x, dtype=np.float64).ravel()
    sy = np.asarray(slope_y, dtype=np.float64).ravel()
    if sx.shape != sy.shape or sx.size < 2:
        raise ValueError("slopes: expected two arrays of the same size with at least two samples")
    if not (np.all(np.isfinite(sx)) and np.all(np.isfinite(sy))):
        raise ValueError("slopes: expected finite values")
    cov = np.cov(np.stack([sx, sy]))
    values, vectors = np.linalg.eigh(cov)
    values = np.clip(values, 0.0, None)
    major = vectors[:, 1]
    azimuth = math.atan2(major[1], major[0]) % math.pi
    return SlopeRoughness(
        alpha_major=math.sqrt(2.0 * values[1]),
        alpha_minor=math.sqrt(2.0 * values[0]),
        major_azimuth_rad=azimuth,
    )
