"""``printapp fit`` on a measured surface: an fBm relief with the same ISO 25178 statistics.

A height map that printapp reads (``.al3d``, ``.x3p``, ``.gwy``; ``.npy`` with ``--pitch-mm``)
is levelled (least-squares plane, the F-operator), its missing samples filled, and
described by the ISO 25178-2 parameters that carry how it looks and feels:

* **Sq** (root mean square height) and **Sdq** (root mean square gradient):
  :func:`printapp.topography.roughness`;
* **Sal** (autocorrelation length), **Str** (texture aspect ratio) and **Std** (texture
  direction): :func:`printapp.topography.lateral`;
* the power spectrum, in quarter-octave bins (:mod:`printapp.fit_spectral`).

The relief is the ``fbm`` texture kind, stretched along the lay (``stretch`` and
``angle_rad``) on a tile the size of the measured area, at the map's pitch:

1. its direction is Std, and it is stretched only where Str < 0.5 (ISO's threshold of a
   directional texture);
2. its stretch is ``0.8 / Str`` (0.8: the Str of an unstretched relief, below 1 on an area
   that holds few large features); its base feature size starts at three times Sal (so that
   the area holds several features), its octave weights (H) and finest octave at the
   spectrum's fit (a measurement is often smoother at its finest scales than fBm: the
   instrument's own resolution); Nelder-Mead then adjusts these three until the relief
   that the design builds (its own noise, seeded) has the map's Sal and Sdq / Sq (from a
   second and third base size if the first does not come within a few percent): a
   measured area holds few of its largest features, so the statistics of one
   realisation are what is matched;
3. its amplitude (peak to valley, ``[relief] amplitude_mm``) is set so that its Sq is the map's.

The fragment holds ``[base]``, ``[relief]`` and ``[texture]``: ``printapp design`` prints
it as is, ``[texture] from`` takes its texture. A measurement finer than the printer's
pixel is magnified up to it (``--magnify`` says otherwise): its heights and lengths grow,
its slopes (Sdq), and so its gloss, stay.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from printapp.errors import DesignError, PrintappError

MAX_SIDE = 512
"""Maps are fitted at most this many samples on a side (block-averaged down)."""
ISOTROPIC_STR = 0.8
"""Str of an unstretched relief on a measured area: below 1, since the area holds few large features."""
GOOD_ENOUGH = 0.003
"""Sum of squared log-ratios (Sal, Sdq / Sq) below which a start is not followed by another: about 4 %."""
CLOSE_ENOUGH = 1e-4
"""... and below which the search stops at once: well under 1 %."""


class _MatchedError(Exception):
    """Raised by the objective to stop Nelder-Mead when the statistics match."""

    def __init__(self, u: np.ndarray, cost: float) -> None:
        super().__init__()
        self.u, self.cost = np.array(u, dtype=float), cost


@dataclass
class SurfaceStats:
    """The ISO 25178 statistics that the fit matches, in µm and degrees."""

    sq_um: float
    sdq: float
    sal_um: float
    str_ratio: float
    std_deg: float
    lay_deg: float

    @classmethod
    def of(cls, heights_mm: np.ndarray, px: float, py: float) -> SurfaceStats:
        from printapp.topography import lateral, roughness

        r = roughness(heights_mm, px, py)
        lat = lateral(heights_mm, px, py)
        return cls(r.sq_um, r.sdq, lat.sal_um, lat.str_ratio, lat.std_deg, lat.lay_deg)

    def as_dict(self) -> dict[str, float]:
        return {
            "Sq_um": float(f"{self.sq_um:.5g}"),
            "Sdq": float(f"{self.sdq:.5g}"),
            "Sal_um": float(f"{self.sal_um:.5g}"),
            "Str": float(f"{self.str_ratio:.4g}"),
            "Std_deg": float(f"{self.std_deg:.4g}"),
            "lay_deg": float(f"{self.lay_deg:.4g}"),
        }


@dataclass
class SurfaceFit:
    """A fitted surface: the design that prints it, and the statistics it matches."""

    path: str
    design: Any
    measured: SurfaceStats
    fitted: SurfaceStats
    heights_mm: np.ndarray
    relief_mm: np.ndarray
    pitch_mm: float
    seed: int
    evaluations: int
    seconds: float
    magnification: float = 1.0
    """The fragment's relief is the fitted one magnified this many times (lengths and heights)."""
    warnings: list[str] = field(default_factory=list)

    def relative_errors(self) -> dict[str, float]:
        m, f = self.measured, self.fitted
        return {
            "Sq": f.sq_um / m.sq_um - 1.0,
            "Sdq": f.sdq / m.sdq - 1.0,
            "Sal": f.sal_um / m.sal_um - 1.0,
            "Str": f.str_ratio / m.str_ratio - 1.0,
        }

    def metrics(self) -> dict[str, Any]:
        texture = self.design.texture
        return {
            "surface": self.path,
            "samples": list(self.heights_mm.shape),
            "pitch_um": self.pitch_mm * 1000.0,
            "seed": self.seed,
            "model": "fbm",
            "params": {
                "H": texture.H,
                "lacunarity": texture.lacunarity,
                "octaves": texture.octaves,
                "feature_size_mm": texture.feature_size_mm,
                "stretch": texture.stretch,
                "angle_deg": round(math.degrees(texture.angle_rad), 4),
                "amplitude_mm": self.design.relief.amplitude_mm,
                "magnification": self.magnification,
            },
            "measured": self.measured.as_dict(),
            "fitted": self.fitted.as_dict(),
            "relative_errors": {k: round(v, 4) for k, v in self.relative_errors().items()},
            "evaluations": self.evaluations,
            "fit_seconds": round(self.seconds, 3),
            "warnings": self.warnings,
            "method": {
                "Sq, Sdq": "ISO 25178-2 on the plane-levelled map (printapp.topography.roughness)",
                "Sal, Str, Std": "ISO 25178-2 from the FFT autocorrelation (threshold 0.2) and the angular "
                "power spectrum (printapp.topography.lateral)",
                "fit": "fBm stretched along Std by 0.8/Str; feature size, H and finest octave from Sal and "
                "the spectrum, then Nelder-Mead to Sal and Sdq/Sq of the relief the design builds; "
                "amplitude from Sq",
            },
        }

    def summary_lines(self) -> list[str]:
        m, f = self.measured, self.fitted
        errors = self.relative_errors()
        return [
            f"{Path(self.path).name}: fbm relief, {self.heights_mm.shape[1]} x {self.heights_mm.shape[0]} "
            f"samples at {self.pitch_mm * 1000:.4g} µm ({self.seconds:.1f} s); the fragment magnifies it "
            f"{self.magnification:g} times",
            f"Sq {m.sq_um:.4g} -> {f.sq_um:.4g} µm ({errors['Sq']:+.1%}), Sdq {m.sdq:.4g} -> {f.sdq:.4g} "
            f"({errors['Sdq']:+.1%}), Sal {m.sal_um:.4g} -> {f.sal_um:.4g} µm ({errors['Sal']:+.1%}), "
            f"Str {m.str_ratio:.3g} -> {f.str_ratio:.3g}, Std {m.std_deg:.4g} -> {f.std_deg:.4g} deg, "
            f"lay {m.lay_deg:.4g} -> {f.lay_deg:.4g} deg",
        ]


def _block_mean(z: np.ndarray, k: int) -> np.ndarray:
    ny, nx = (z.shape[0] // k) * k, (z.shape[1] // k) * k
    return z[:ny, :nx].reshape(ny // k, k, nx // k, k).mean(axis=(1, 3))


def _design(texture_fields: dict[str, Any], shape: tuple[int, int], pitch: float, amplitude_mm: float):
    from printapp.design import design_from_dict

    ny, nx = shape
    return design_from_dict(
        {
            "base": {"shape": "tile", "width_mm": (nx - 1) * pitch, "depth_mm": (ny - 1) * pitch},
            "relief": {"amplitude_mm": amplitude_mm, "pitch_mm": pitch},
            "texture": texture_fields,
        },
        "fitted surface",
    )


def _relief(design) -> np.ndarray:
    from printapp.texture import relief_heightfield

    return relief_heightfield(design).heights_mm


def magnified(design, factor: float):
    """The design with its tile, pitch, amplitude and feature size multiplied by ``factor``.

    The relief is the same pattern (noise coordinates are lengths over the feature size),
    its heights and lengths times ``factor``: Sq and Sal scale with it, Sdq (a slope) not.
    """
    from printapp.design import design_from_dict
    from printapp.design_io import to_file_units

    data = to_file_units(design.model_dump(mode="python"))
    for table, keys in (("base", ("width_mm", "depth_mm")), ("relief", ("amplitude_mm", "pitch_mm"))):
        for key in keys:
            data[table][key] = float(f"{data[table][key] * factor:.6g}")
    data["texture"]["feature_size_mm"] = float(f"{data['texture']['feature_size_mm'] * factor:.6g}")
    return design_from_dict(data, "fitted surface")


def default_magnification(pitch_mm: float) -> float:
    """The factor that brings a map's pitch up to the default printer's pixel (1 for coarser maps)."""
    from slicing import find_printer

    return float(f"{max(1.0, find_printer('prusa-sl1').pitch_mm / pitch_mm):.4g}")


def fit_surface(
    source: str | Path,
    *,
    pitch_mm: float | None = None,
    seed: int = 0,
    max_side: int = MAX_SIDE,
    magnify: float | None = None,
    timer=None,
) -> SurfaceFit:
    """Fit an fBm relief to a measured height map (module docstring).

    The fragment's design is the fitted relief magnified ``magnify`` times (default
    :func:`default_magnification`: a measurement finer than the printer's pixel is printed
    at the printer's pixel, with the same slopes, Sdq, and so the same gloss).

    Raises
    ------
    PrintappError
        For unreadable maps, missing or bad ``pitch_mm``, maps too small to describe.
    """
    import contextlib

    from scipy.optimize import minimize

    from printapp.fit_spectral import fit_spectral
    from printapp.topography import load_corrected

    def stage(name: str, label: str):
        return timer.stage(name, label) if timer is not None else contextlib.nullcontext()

    start = time.perf_counter()
    source = Path(source)
    with stage("read", "reading the height map"):
        try:
            corrected = load_corrected(source, pitch_mm=pitch_mm, flatten="plane")
        except DesignError as exc:
            raise PrintappError(str(exc)) from None
        z = corrected.heights_mm
        px, py = corrected.pitch_x_mm, corrected.pitch_y_mm
        if min(z.shape) < 32:
            raise PrintappError(
                f"{source}: the map is {z.shape[1]} x {z.shape[0]} samples; expected 32 or more"
            )
        warnings = []
        if abs(px / py - 1.0) > 0.01:
            warnings.append(
                f"the map's pixels are not square ({px * 1e3:.4g} x {py * 1e3:.4g} µm); fitted at x's"
            )
        k = max(1, math.ceil(max(z.shape) / max_side))
        if k > 1:
            z = _block_mean(z, k)
            warnings.append(
                f"the map was averaged over {k} x {k} blocks to {z.shape[1]} x {z.shape[0]} samples"
            )
        pitch = px * k
        z = z - z.mean()
        if float(np.std(z)) <= 0:
            raise PrintappError(f"{source}: the levelled map is flat; there is no relief to fit")
        measured = SurfaceStats.of(z, pitch, pitch)
    with stage("fit", "fitting an fBm relief"):
        spectral, _, _ = fit_spectral("fbm", z / np.std(z))
        anisotropic = measured.str_ratio < 0.5
        base = {
            "kind": "fbm",
            "seed": seed,
            "lacunarity": 2.0,
            "angle_rad": math.radians(measured.std_deg) if anisotropic else 0.0,
            "stretch": float(f"{min(max(ISOTROPIC_STR / measured.str_ratio, 1.0), 8.0):.6g}")
            if anisotropic
            else 1.0,
        }
        target_ratio = measured.sdq / measured.sq_um
        count = 0
        # Start: features a few Sal across (so that the area holds several), the spectrum's H,
        # stretched by 1 / Str along the lay; all three then adjusted by Nelder-Mead.
        finest_mm = spectral["feature_px"] * pitch / spectral["lacunarity"] ** (spectral["octaves"] - 1)
        u0 = np.array(
            [
                math.log(3.0 * measured.sal_um / 1000.0),
                float(np.clip(spectral["H"], 0.05, 1.0)),
                math.log(finest_mm),
            ]
        )

        def fields_of(u: np.ndarray) -> dict[str, Any]:
            feature = math.exp(float(u[0]))
            finest = math.exp(float(u[2]))
            out = {
                **base,
                "octaves": int(min(max(1 + round(math.log2(max(feature / finest, 1.0))), 1), 16)),
                "feature_size_mm": float(f"{feature:.6g}"),
                "H": float(f"{min(max(float(u[1]), 0.02), 1.0):.6g}"),
            }
            return out

        def objective(u: np.ndarray) -> float:
            nonlocal count
            count += 1
            relief = _relief(_design(fields_of(u), z.shape, pitch, 1.0))
            fitted = SurfaceStats.of(relief, pitch, pitch)
            ratio = fitted.sdq / fitted.sq_um
            cost = math.log(fitted.sal_um / measured.sal_um) ** 2 + math.log(ratio / target_ratio) ** 2
            if cost < CLOSE_ENOUGH:
                raise _MatchedError(u, cost)
            return cost

        # Nelder-Mead from three base feature sizes in turn, until one matches to about 5 %.
        best_u, best_cost = u0, math.inf
        for factor in (1.0, 0.6, 1.6):
            start_u = u0.copy()
            start_u[0] += math.log(factor)
            simplex = [start_u] + [start_u + step for step in 0.3 * np.eye(u0.size)]
            try:
                found = minimize(
                    objective,
                    start_u,
                    method="Nelder-Mead",
                    options={
                        "initial_simplex": simplex,
                        "maxfev": 25 * u0.size,
                        "xatol": 0.01,
                        "fatol": 1e-4,
                    },
                )
                u_found, cost_found = found.x, float(found.fun)
            except _MatchedError as matched:
                u_found, cost_found = matched.u, matched.cost
            if cost_found < best_cost:
                best_u, best_cost = u_found, cost_found
            if best_cost < GOOD_ENOUGH:
                break
        fields = fields_of(best_u)
        relief = _relief(_design(fields, z.shape, pitch, 1.0))
        amplitude = float(f"{np.ptp(relief) * measured.sq_um / (1000.0 * np.std(relief)):.6g}")
        design = _design(fields, z.shape, pitch, amplitude)
        relief = _relief(design)
        fitted = SurfaceStats.of(relief, pitch, pitch)
        factor = default_magnification(pitch) if magnify is None else float(magnify)
        if not (math.isfinite(factor) and 0 < factor <= 1e6):
            raise PrintappError(f"--magnify: expected a positive factor, got {magnify}")
        if factor != 1.0:
            design = magnified(design, factor)
    return SurfaceFit(
        path=str(source),
        design=design,
        magnification=factor,
        measured=measured,
        fitted=fitted,
        heights_mm=z,
        relief_mm=relief - relief.mean(),
        pitch_mm=pitch,
        seed=seed,
        evaluations=count,
        seconds=time.perf_counter() - start,
        warnings=warnings,
    )
