"""A small light's highlight on a flat rough tile: where it falls, which way it stretches, and its moments.

An anisotropic relief's slopes are spread much wider along one azimuth than across it
(the brushed tile's strokes are steep across, nearly flat along). At a point ``p`` of the
tile, a camera at ``e`` sees a small light at ``q`` reflected by the facets whose normal is
the half vector ``h = normalize(l + v)`` (``l``, ``v`` the unit directions from ``p`` to
``q`` and ``e``), that is the facets of slope ``s = -(h_x, h_y) / h_z``. The reflected
radiance is proportional to the slope density there (microfacet theory, Walter et al.
2007, eq. 20 with ``D(h) = P22(s) / h_z^4``; Fresnel and masking vary slowly across a
highlight and are left out): ``L(p) ~ P22(s(p)) / (h_z^4 v_z)``. Moving ``p`` moves
``h``, so the highlight on the tile is the slope density mapped back through ``s(p)``:
it is stretched along the slopes' long axis, which for grooves is **across the grooves**
(a brushed highlight runs perpendicular to the brushing). With the light at the camera's
mirror image (same elevation, opposite azimuth) the streak is centred on the tile. To
first order in the offset from the mirror point, ``ds`` is ``dx sin(e) / d`` in the plane
of incidence and ``dy / (d sin(e))`` across it (``e`` the elevation, ``d`` the distance),
and the camera foreshortens the plane of incidence by ``sin(e)``: on the screen a slope
spread ``sigma`` becomes ``sigma d`` along the view's vertical and ``sigma d sin(e)``
across it. :func:`predicted_highlight` evaluates the exact mapping, pixel by pixel, with
the perspective camera the previews use, and :func:`highlight_shape` reads the same
second moments off any image, rendered or predicted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """The previews' perspective camera: Mitsuba's ``perspective`` sensor with ``look_at(eye, target, up=z)``.

    ``fov_deg`` spans the image's shorter side. Image x runs right, image y down; pixel
    ``(row, col)`` has its centre at ``(col + 1/2, row + 1/2)``.
    """

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    fov_deg: float
    width_px: int
    height_px: int

    def _basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        eye, target = np.asarray(self.eye, float), np.asarray(self.target, float)
        forward = (target - eye) / np.linalg.norm(target - eye)
        left = np.cross([0.0, 0.0, 1.0], forward)
        left /= np.linalg.norm(left)
        up = np.cross(forward, left)
        half = math.tan(math.radians(self.fov_deg) / 2.0)
        aspect = self.width_px / self.height_px
        tan_x, tan_y = (half * aspect, half) if aspect >= 1.0 else (half, half / aspect)
        return forward, left, up, tan_x, tan_y

    def pixel_rays(self) -> np.ndarray:
        """Unit directions ``(height_px, width_px, 3)`` through the pixels' centres (world frame)."""
        forward, left, up, tan_x, tan_y = self._basis()
        col = (np.arange(self.width_px) + 0.5) / self.width_px
        row = (np.arange(self.height_px) + 0.5) / self.height_px
        x = (1.0 - 2.0 * col)[None, :, None] * tan_x
        y = (1.0 - 2.0 * row)[:, None, None] * tan_y
        d = forward + x * left + y * up
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Image ``(col, row)`` coordinates (pixels, continuous) of world points ``(..., 3)``."""
        forward, left, up, tan_x, tan_y = self._basis()
        rel = np.asarray(points, float) - np.asarray(self.eye, float)
        z = rel @ forward
        x, y = (rel @ left) / z, (rel @ up) / z
        col = 0.5 * self.width_px * (1.0 - x / tan_x)
        row = 0.5 * self.height_px * (1.0 - y / tan_y)
        return np.stack([col, row], axis=-1)


@dataclass(frozen=True)
class SlopeLobe:
    """An anisotropic Beckmann slope distribution: roughness along and across its long axis.

    ``azimuth_rad`` is the long axis's azimuth in the tile's plane (from +x towards +y);
    the slope variance is ``alpha^2 / 2`` along each principal axis.
    """

    alpha_long: float
    alpha_short: float
    azimuth_rad: float

    def density(self, sx: np.ndarray, sy: np.ndarray) -> np.ndarray:
        """``P22(s)``: the slope density (per unit slope squared) at slopes ``(sx, sy)``."""
        c, s = math.cos(self.azimuth_rad), math.sin(self.azimuth_rad)
        u, w = c * sx + s * sy, -s * sx + c * sy
        al2, as2 = self.alpha_long**2, self.alpha_short**2
        return np.exp(-(u * u) / al2 - (w * w) / as2) / (math.pi * self.alpha_long * self.alpha_short)


@dataclass(frozen=True)
class HighlightShape:
    """Second moments of a highlight in an image.

    ``angle_deg`` is the long axis's direction on the screen, in [0, 180): degrees
    counter-clockwise from the image's +x (right), with image up as +90. ``elongation``
    is the ratio of the standard deviations along and across it (1: round).
    """

    angle_deg: float
    elongation: float
    centroid_px: tuple[float, float]
    pixels: int


def predicted_highlight(
    camera: PinholeCamera,
    light_centre: tuple[float, float, float],
    light_half_size: float,
    lobe: SlopeLobe,
    plane_z: float,
    rect: tuple[float, float, float, float],
    *,
    light_samples: int = 4,
) -> tuple[np.ndarray, np.ndarray]:
    """The highlight a small square light makes on a flat rough tile, as the camera sees it.

    Parameters
    ----------
    camera : PinholeCamera
        The preview's camera.
    light_centre : (3,) mm
        The light's centre; it is a square of half side ``light_half_size`` (mm) facing
        the camera's target (Mitsuba's ``rectangle`` under ``look_at(..., up=z)``).
    lobe : SlopeLobe
        The relief's slope distribution (from the predicted BRDF's lobe).
    plane_z : float
        Height (mm) of the tile's mean surface.
    rect : (x0, x1, y0, y1) mm
        The tile's top face.
    light_samples : int
        Points per side of the light (the light's own size widens the highlight).

    Returns
    -------
    image : (height_px, width_px) array
        Relative radiance ``P22(s) / (h_z^4 v_z)`` averaged over the light (module
        docstring), zero off the tile.
    mask : (height_px, width_px) bool array
        Pixels whose ray meets the tile's top face.
    """
    eye = np.asarray(camera.eye, float)
    rays = camera.pixel_rays()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (plane_z - eye[2]) / rays[..., 2]
    p = eye + np.where(t[..., None] > 0, t[..., None], np.nan) * rays
    x0, x1, y0, y1 = rect
    mask = (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)
    pts = p[mask]
    v = eye - pts
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    centre = np.asarray(light_centre, float)
    to_target = np.asarray(camera.target, float) - centre
    forward = to_target / np.linalg.norm(to_target)
    left = np.cross([0.0, 0.0, 1.0], forward)
    left /= np.linalg.norm(left)
    up = np.cross(forward, left)
    offsets = (np.arange(light_samples) + 0.5) / light_samples * 2.0 - 1.0
    total = np.zeros(len(pts))
    for a in offsets:
        for b in offsets:
            q = centre + light_half_size * (a * left + b * up)
            ell = q - pts
            ell /= np.linalg.norm(ell, axis=-1, keepdims=True)
            h = ell + v
            h /= np.linalg.norm(h, axis=-1, keepdims=True)
            sx, sy = -h[:, 0] / h[:, 2], -h[:, 1] / h[:, 2]
            total += lobe.density(sx, sy) / (h[:, 2] ** 4 * v[:, 2])
    image = np.zeros(mask.shape)
    image[mask] = total / light_samples**2
    return image, mask


def highlight_shape(luminance: np.ndarray, mask: np.ndarray, quantile: float = 0.95) -> HighlightShape | None:
    """The highlight's direction and elongation from the image's second moments.

    Over the pixels inside ``mask``, those brighter than the ``quantile`` of the mask's
    luminance are the highlight; each weighs by its luminance above that level, and the
    weighted covariance of their positions gives the principal axes (the long one's
    direction, and the ratio of the standard deviations along and across it). None when
    the mask is empty or no pixel stands above the level.
    """
    lum = np.asarray(luminance, float)
    inside = lum[mask]
    if inside.size == 0:
        return None
    level = float(np.quantile(inside, quantile))
    weight = np.where(mask, np.clip(lum - level, 0.0, None), 0.0)
    total = float(weight.sum())
    if not total > 0.0:
        return None
    rows, cols = np.indices(lum.shape, dtype=float)
    x, y = cols + 0.5, -(rows + 0.5)  # y up, so that angles read as on paper
    mx, my = float((weight * x).sum() / total), float((weight * y).sum() / total)
    cxx = float((weight * (x - mx) ** 2).sum() / total)
    cyy = float((weight * (y - my) ** 2).sum() / total)
    cxy = float((weight * (x - mx) * (y - my)).sum() / total)
    values, vectors = np.linalg.eigh(np.array([[cxx, cxy], [cxy, cyy]]))
    small, big = max(float(values[0]), 1e-12), max(float(values[1]), 1e-12)
    angle = math.degrees(math.atan2(vectors[1, 1], vectors[0, 1])) % 180.0
    return HighlightShape(angle, math.sqrt(big / small), (mx, -my), int(np.count_nonzero(weight)))


def axis_difference_deg(a_deg: float, b_deg: float) -> float:
    """Angle (degrees, 0 to 90) between two undirected axes."""
    d = abs(a_deg - b_deg) % 180.0
    return min(d, 180.0 - d)
