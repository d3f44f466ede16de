"""What the printer makes of the layers: the as-printed height field of a relief tile.

A pixel of grey level ``g`` (0 dark, 255 fully lit) in a layer of thickness ``t`` cures a
slab of resin on top of what is below it; how thick depends on the cure model
(:class:`CureModel`):

* **working curve** (the default of a design): Jacobs' working curve (P. F. Jacobs 1992,
  *Rapid Prototyping & Manufacturing: Fundamentals of Stereolithography*, ch. 4): light
  falls off in the resin as ``exp(-z / Dp)`` (Beer-Lambert), and resin gels where its dose
  reaches the critical dose ``Ec``, so a dose ``E`` at the vat floor cures to the depth
  ``Cd = Dp ln(E / Ec)``. The dose of a pixel is its grey level's share of the full dose,
  ``E = E_full g / 255`` (PrusaSlicer's ``gamma_correction = 1`` writes grey levels meant
  to be proportional to the light; exposure reciprocity assumed), so the pixel cures
  ``min(t, max(0, Dp ln(g E_full / (255 Ec))))`` of its layer: nothing below the
  threshold grey ``255 Ec / E_full``, the whole layer from the saturation grey
  ``255 exp(-(Cd_full - t) / Dp)`` up, and in between a depth that grows with the
  logarithm of the grey level.
* **linear**: the cured thickness grows linearly with the grey level, ``t g / 255`` (the
  model printapp used first; Luongo et al. 2019, "Microstructure control in 3D printing
  with digital light processing", grow sub-voxel detail with grey levels in this spirit).

Both are geometric idealisations of the same kind: the cured resin is taken to sit as a
film of that thickness on the layer below. In a bottom-up vat a partial cure forms
against the vat floor and holds to the part through its cured neighbours; whether such a
film survives the peel is a question of printer and resin that neither model settles.
For a tile, whose every column is solid from the bed up, the printed height of a pixel is
the sum over layers of the thickness its dose cures.

**Lateral cure spread.** A pixel's light does not stay in its square: the display's and
the vat film's blur and the resin's scattering spread it. Luongo et al. 2019 model it as a
Gaussian spot per pixel, the standard model; Reid et al. 2024 ("Impact of beam shape on
print accuracy in digital light processing additive manufacture", *3D Print. Addit. Manuf.*
11(2)) find that a heavier-tailed Lorentzian predicts small features better. The Gaussian
is used here. With a spread ``sigma`` (:func:`spread_dose`), each layer's dose at a pixel's centre
is the sum of its lit neighbours' doses times the Gaussian's integral over them, and the
cure model turns that dose (as a grey level ``255 E / E_full``) into a thickness. Without
it, anti-aliased grey below the working curve's threshold cures nothing and every layer's
outline is a staircase of whole pixels along x and y, whose walls reflect light only in
the xz and yz planes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: the layers' raster imports numba, which validation need not
    from slicing.layers import Slices

CURE_MODELS = ("working-curve", "linear")


@dataclass(frozen=True)
class CureModel:
    """How thick a pixel of grey level ``g`` cures in a layer of thickness ``t`` (see the module).

    Build one with :meth:`linear` or :meth:`working_curve`.

    Attributes
    ----------
    kind : str
        ``"working-curve"`` or ``"linear"``.
    penetration_depth_mm : float
        ``Dp``, the depth over which the curing light falls by a factor e (working curve only).
    critical_dose : float
        ``Ec``, the dose at which the resin gels (mJ/cm^2; working curve only).
    full_dose : float
        ``E_full``, the dose a fully lit pixel (grey 255) receives (mJ/cm^2; working curve only).
    """

    kind: str
    penetration_depth_mm: float = math.nan
    critical_dose: float = math.nan
    full_dose: float = math.nan

    @classmethod
    def linear(cls) -> CureModel:
        """A grey pixel cures ``g / 255`` of its layer."""
        return cls("linear")

    @classmethod
    def working_curve(cls, penetration_depth_mm: float, critical_dose: float, full_dose: float) -> CureModel:
        """Jacobs' working curve ``Cd = Dp ln(E / Ec)`` with ``E = full_dose g / 255``.

        Raises
        ------
        ValueError
            If a constant is not positive and finite, or a fully lit pixel would cure nothing
            (``full_dose <= critical_dose``).
        """
        for name, value in (
            ("penetration depth", penetration_depth_mm),
            ("critical dose", critical_dose),
            ("full dose", full_dose),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}: expected a positive, finite value, got {value!r}")
        if full_dose <= critical_dose:
            raise ValueError(
                f"full dose: {full_dose:g} mJ/cm^2 is not above the critical dose {critical_dose:g} mJ/cm^2, "
                "so a fully lit pixel would cure nothing"
            )
        return cls("working-curve", float(penetration_depth_mm), float(critical_dose), float(full_dose))

    @property
    def full_cure_depth_mm(self) -> float:
        """``Cd`` of a fully lit pixel (mm): the layer plus the overcure that bonds it (working curve)."""
        return self.penetration_depth_mm * math.log(self.full_dose / self.critical_dose)

    def threshold_grey(self) -> float:
        """The grey level below which a pixel cures nothing (``255 Ec / E_full``; linear: 0)."""
        return 0.0 if self.kind == "linear" else 255.0 * self.critical_dose / self.full_dose

    def saturation_grey(self, layer_mm: float) -> float:
        """The grey level from which a pixel cures its whole layer of ``layer_mm`` (at most 255)."""
        if self.kind == "linear":
            return 255.0
        excess = self.full_cure_depth_mm - layer_mm
        return 255.0 * math.exp(-excess / self.penetration_depth_mm) if excess > 0 else 255.0

    def cure_depth_mm(self, grey: np.ndarray | float) -> np.ndarray:
        """Depth a pixel of grey level ``grey`` cures (mm), without the layer's limit (working curve).

        ``Dp ln(g E_full / (255 Ec))`` where positive, else 0.
        """
        if self.kind == "linear":
            raise ValueError("cure depth: the linear model has none; it cures a share of the layer")
        g = np.asarray(grey, dtype=np.float64)
        dose = self.full_dose * g / 255.0
        with np.errstate(divide="ignore"):
            depth = self.penetration_depth_mm * np.log(dose / self.critical_dose)
        return np.where(dose > self.critical_dose, depth, 0.0)

    def thickness_mm(self, grey: np.ndarray | float, layer_mm: float) -> np.ndarray:
        """Thickness of resin (mm) a pixel of grey level ``grey`` cures in a layer of ``layer_mm``."""
        g = np.asarray(grey, dtype=np.float64)
        if self.kind == "linear":
            return layer_mm * g / 255.0
        return np.minimum(self.cure_depth_mm(g), layer_mm)

    def grey_for_thickness(self, thickness_mm: np.ndarray, layer_mm: float) -> np.ndarray:
        """The 8-bit grey level whose cured thickness is nearest ``thickness_mm`` in a layer of ``layer_mm``.

        The inverse of :meth:`thickness_mm` (for the working curve,
        ``g = 255 (Ec / E_full) exp(d / Dp)``): 0 for nothing, 255 for the whole layer, and
        in between the nearer of the two grey levels around the exact one.
        """
        d = np.clip(np.asarray(thickness_mm, dtype=np.float64), 0.0, layer_mm)
        if self.kind == "linear":
            exact = 255.0 * d / layer_mm
        else:
            exact = np.minimum(
                255.0 * self.critical_dose / self.full_dose * np.exp(d / self.penetration_depth_mm), 255.0
            )
        lo = np.floor(exact)
        hi = np.minimum(lo + 1.0, 255.0)
        nearer_hi = np.abs(self.thickness_mm(hi, layer_mm) - d) < np.abs(self.thickness_mm(lo, layer_mm) - d)
        grey = np.where(nearer_hi, hi, lo)
        grey = np.where(d <= 0.0, 0.0, np.where(d >= layer_mm, 255.0, grey))
        return grey.astype(np.uint8)

    def describe(self) -> str:
        """One line for the manifest."""
        if self.kind == "linear":
            return "linear sub-voxel growth: a pixel of grey g cures g/255 of its layer"
        return (
            f"Jacobs' working curve: Cd = Dp ln(E / Ec) with Dp {self.penetration_depth_mm * 1000:.4g} um, "
            f"Ec {self.critical_dose:.4g} mJ/cm^2 and {self.full_dose:.4g} mJ/cm^2 at grey 255 "
            f"(cures {self.full_cure_depth_mm * 1000:.4g} um; nothing below grey {self.threshold_grey():.0f})"
        )


LINEAR = CureModel.linear()


def _pixel_psf_weights(sigma_px: float, offset_px: float = 0.0) -> np.ndarray:
    """Share of a pixel's light (a Gaussian spot, standard deviation ``sigma_px``) at a point k pixels on.

    ``w[k] = Phi((1/2 - k - o) / sigma) - Phi((-1/2 - k - o) / sigma)`` for k = -K..K: the
    Gaussian centred on the receiving point, ``o`` pixels (``offset_px``, within a pixel)
    from the centre of its pixel, integrated over the uniformly lit pixel k before it. At
    ``o = 0`` the weights are symmetric and sum to 1. ``K`` reaches 5 sigma (the tail
    left out is below 3e-7); with ``sigma_px = 0`` the point takes its own pixel's dose.
    """
    if sigma_px == 0.0:
        return np.array([0.0, 1.0, 0.0])
    reach = int(math.ceil(5.0 * sigma_px)) + 1
    k = np.arange(-reach, reach + 1, dtype=np.float64)
    erf = np.vectorize(math.erf)

    def phi(x: np.ndarray) -> np.ndarray:
        return 0.5 * (1.0 + erf(x / math.sqrt(2.0)))

    return phi((0.5 - k - offset_px) / sigma_px) - phi((-0.5 - k - offset_px) / sigma_px)


def spread_dose(
    dose: np.ndarray, sigma_x_px: float, sigma_y_px: float | None = None, oversample: int = 1
) -> np.ndarray:
    """An exposure image as the resin receives it: each pixel's dose spread by a Gaussian spot.

    Lateral cure spread (module docstring; Luongo et al. 2019, Reid et al. 2024): the dose
    at a point is the sum over pixels of their dose times the Gaussian's integral over
    them, separable into :func:`_pixel_psf_weights` along each axis. Nothing is lit
    outside the image. The total dose is kept (up to what spreads out of the image), and a
    lit half-plane gives ``Phi(-d / sigma)`` at a distance ``d`` beyond its edge, exactly.

    Parameters
    ----------
    dose : (rows, cols) array
        Dose per pixel, in any unit (e.g. grey / 255).
    sigma_x_px, sigma_y_px : float
        The spot's standard deviation along columns (x) and rows (y), in pixels (y
        defaults to x). Zero leaves that axis alone.
    oversample : int
        Points per pixel along each axis where the dose is evaluated, at the centres of
        ``oversample x oversample`` equal sub-squares (1: the pixels' centres).

    Returns
    -------
    (rows * oversample, cols * oversample) float64 array
    """
    out = np.asarray(dose, dtype=np.float64)
    if out.ndim != 2:
        raise ValueError("dose: expected a 2-D image")
    if not (isinstance(oversample, int) and oversample >= 1):
        raise ValueError(f"oversample: expected a whole number of points per pixel, got {oversample!r}")
    sigmas = (sigma_y_px if sigma_y_px is not None else sigma_x_px, sigma_x_px)
    offsets = (np.arange(oversample) + 0.5) / oversample - 0.5
    for axis, sigma in enumerate(sigmas):
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"sigma: expected a non-negative, finite spread in pixels, got {sigma}")
        if sigma == 0.0 and oversample == 1:
            continue
        n = out.shape[axis]
        shape = list(out.shape)
        shape[axis] = n * oversample
        spread = np.zeros(shape)
        for j, offset in enumerate(offsets):
            weights = _pixel_psf_weights(float(sigma), float(offset))
            reach = (len(weights) - 1) // 2
            padded = np.pad(out, [(reach, reach) if a == axis else (0, 0) for a in range(2)])
            part = np.zeros_like(out)
            for k, w in zip(range(-reach, reach + 1), weights, strict=True):
                # Point i gathers the dose of pixel i - k, sent k pixels on with weight w[k].
                start = reach - k
                part += w * (padded[start : start + n, :] if axis == 0 else padded[:, start : start + n])
            if axis == 0:
                spread[j::oversample, :] = part
            else:
                spread[:, j::oversample] = part
        out = spread
    return out


def printed_heights(
    slices: Slices, cure: CureModel | None = None, spread_mm: float = 0.0, oversample: int = 1
) -> np.ndarray:
    """As-printed height (mm above the bed) of the slices' window, at its pixels or finer.

    ``cure`` is the cure model (default: :data:`LINEAR`, a grey pixel cures that share of
    its layer). ``spread_mm`` is the lateral cure spread, the standard deviation (mm) of
    the Gaussian spot each pixel's light makes in the resin (:func:`spread_dose`; 0: none):
    each layer's dose is spread before it cures. ``oversample`` points per pixel along
    each axis (:func:`spread_dose`) resolve the layers' outlines inside the pixels: at 1,
    a step between two pixels' heights is drawn as a slope across the whole pixel.

    Returns
    -------
    (rows * oversample, cols * oversample) float64 array, row 0 at the smallest Y, column
    0 at the smallest X; at oversample 1, for pixel centres at ((col0 + c + 1/2) px,
    (row0 + r + 1/2) py) in bed coordinates.
    """
    cure = LINEAR if cure is None else cure
    p = slices.profile
    if not (math.isfinite(spread_mm) and spread_mm >= 0.0):
        raise ValueError(f"spread: expected a non-negative, finite length in mm, got {spread_mm}")
    heights = np.zeros((slices.rows * oversample, slices.cols * oversample))
    for k, cov in slices.coverages():
        thickness = p.initial_layer_height_mm if k == 0 else slices.layer_height_mm
        grey = slices.grey(cov)
        if spread_mm > 0.0 or oversample > 1:
            # The spread dose, as the grey level that would give it: no longer whole levels.
            dose = spread_dose(grey / 255.0, spread_mm / p.pitch_x_mm, spread_mm / p.pitch_y_mm, oversample)
            heights += cure.thickness_mm(255.0 * np.clip(dose, 0.0, 1.0), thickness)
        elif cure.kind == "linear":
            heights += thickness * grey / 255.0
        else:
            # Grey levels are 0..255: one lookup table per layer thickness.
            table = cure.thickness_mm(np.arange(256.0), thickness)
            heights += table[grey]
    return heights


def pixel_centres_mm(slices: Slices) -> tuple[np.ndarray, np.ndarray]:
    """Bed x and y (mm) of the window's pixel centres, as 1-D arrays along columns and rows."""
    p = slices.profile
    x = (slices.col0 + np.arange(slices.cols) + 0.5) * p.pitch_x_mm
    y = (slices.row0 + np.arange(slices.rows) + 0.5) * p.pitch_y_mm
    return x, y
