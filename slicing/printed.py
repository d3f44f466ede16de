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
Light spreading sideways between pixels is not modelled. For a tile, whose every column
is solid from the bed up, the printed height of a pixel is the sum over layers of the
thickness its grey level cures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


def printed_heights(slices: Slices, cure: CureModel | None = None) -> np.ndarray:
    """As-printed height (mm above the bed) of each pixel of the slices' window.

    ``cure`` is the cure model (default: :data:`LINEAR`, a grey pixel cures that share of
    its layer).

    Returns
    -------
    (rows, cols) float64 array, row 0 at the smallest Y, column 0 at the smallest X, for
    pixel centres at ((col0 + c + 1/2) px, (row0 + r + 1/2) py) in bed coordinates.
    """
    cure = LINEAR if cure is None else cure
    p = slices.profile
    heights = np.zeros((slices.rows, slices.cols))
    for k, cov in slices.coverages():
        thickness = p.initial_layer_height_mm if k == 0 else slices.layer_height_mm
        grey = slices.grey(cov)
        if cure.kind == "linear":
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
