"""The texture models that ``printapp fit`` fits, each a printable texture kind on the project's own noise.

Every model gives a scalar field ``s`` on the photo's pixel grid (pixel centres at
``i + 1/2``, rows upwards, lengths in analysed pixels); the photo's luminance is ``s``
mapped onto the photo's luminance distribution rank by rank (exact histogram matching,
:func:`printapp.fit_measures.match_values`; the ``sign`` says whether high ``s`` is bright),
and a palette of the photo's colours ordered along luminance colours it.

* ``fbm``: ``s = sum_i lacunarity^(-H i) noise(lacunarity^i p / F)``, fitted on its
  expected spectrum (no synthesis; :mod:`printapp.fit_spectral`);
* ``turbulence``: ``s = sum_i 2^-i |noise(2^i p / F)|``, likewise;
* ``marble``: Perlin's marble, ``s = ((1 + sin(2 pi (n . p) / period + k T(p / F))) / 2)^sharpness``
  with ``T`` the turbulence (:mod:`noise.veins`); the veins' direction ``n`` from the
  structure tensor (Bigun & Granlund 1987) and their period from the spectrum's mean
  frequency across them, in closed form; the rest by synthesis;
* ``veined``: branching veins, a domain-warped ridged multifractal over noise or cellular
  edges, over an fBm ground (:mod:`noise.ridged`, the ``veined`` texture kind), by synthesis.

While fitting, the noise is read from tables (:class:`noise.tables.NoiseTable`: periodic
Gaussian stand-ins with the noise's spectrum); the fitted texture is then evaluated
exactly, through the same code as a design's relief.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from noise.ridged import NOISE_STD
from noise.spectra import dominant_orientation

MODELS = ("fbm", "turbulence", "marble", "veined")
SYNTHESISED = ("marble", "veined")
"""Models fitted on syntheses (the others on their expected spectrum)."""
MAX_OCTAVES = 10


@dataclass(frozen=True)
class Param:
    """One searched parameter: a box, searched on a log scale when ``log``."""

    name: str
    lo: float
    hi: float
    log: bool = False

    def value(self, u: float) -> float:
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))

    def unit(self, value: float) -> float:
        if self.log:
            u = (math.log(value) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        else:
            u = (value - self.lo) / (self.hi - self.lo)
        return min(max(u, 0.0), 1.0)


@dataclass(frozen=True)
class Grid:
    """Pixel centres of an image in analysed pixels: ``xs`` (columns), ``ys`` (rows, y up)."""

    xs: np.ndarray
    ys: np.ndarray
    pitch_px: float

    @classmethod
    def of(cls, shape: tuple[int, int], analysed_shape: tuple[int, int], origin=(0.0, 0.0)) -> Grid:
        """A ``shape`` image covering the analysed image (moved to ``origin``, in analysed px)."""
        ny, nx = shape
        sy, sx = analysed_shape[0] / ny, analysed_shape[1] / nx
        return cls(
            origin[1] + (np.arange(nx) + 0.5) * sx, origin[0] + (np.arange(ny) + 0.5) * sy, max(sx, sy)
        )

    def points(self) -> np.ndarray:
        xx, yy = np.meshgrid(self.xs, self.ys)
        return np.column_stack([xx.ravel(), yy.ravel()])

    @property
    def shape(self) -> tuple[int, int]:
        return self.ys.size, self.xs.size


@dataclass(frozen=True)
class Hints:
    """What the photo says before any fitting: its size, and the direction and coherence of its structure."""

    shape: tuple[int, int]
    angle: float
    """Direction (rad, [0, pi), from +x towards +y) the photo's structure runs along."""
    coherence: float
    period_px: float
    """Inverse of the spectrum's mean frequency across that direction (px): the veins' period if any."""
    polarity: float = 0.0
    """+1 where the photo's strongest thin lines are bright, -1 dark, 0 where neither stands out."""
    ground: dict[str, Any] | None = None
    """An fBm fitted to the photo's spectrum (feature_px, H, ...), where the veins' ground starts."""

    @classmethod
    def of(cls, lum: np.ndarray, strengths: np.ndarray | None = None) -> Hints:
        """Hints from a luminance image (and its line strengths at 1, 2, 4... px, if known)."""
        gradient_angle, coherence = dominant_orientation(lum)
        angle = float(np.mod(gradient_angle + math.pi / 2, math.pi))
        return cls(lum.shape, angle, coherence, _peak_period(lum, gradient_angle), _polarity(lum, strengths))


POLARITY_THRESHOLD = 0.03
"""Decades by which one polarity's strongest lines must outdo the other's to decide the veins' sign."""


def _polarity(lum: np.ndarray, strengths: np.ndarray | None = None) -> float:
    """Whether the strongest thin lines are bright (+1) or dark (-1): the 99th percentiles of the line
    strengths (:mod:`noise.line_filters`) at 1, 2 and 4 px, dark over bright, in decades, averaged."""
    from noise.line_filters import line_strengths

    strengths = line_strengths(lum, (1.0, 2.0, 4.0)) if strengths is None else strengths[:3]
    tails = np.quantile(strengths.reshape(3, 2, -1), 0.99, axis=2) + 1e-12
    asymmetry = float(np.mean(np.log10(tails[:, 1] / tails[:, 0])))
    if abs(asymmetry) < POLARITY_THRESHOLD:
        return 0.0
    return -1.0 if asymmetry > 0 else 1.0


def _peak_period(lum: np.ndarray, across: float) -> float:
    """The veins' period (px): the inverse of the power-weighted mean frequency across them.

    Over the half of the frequency plane facing the direction ``across`` (the wave
    vector's), ``1 / (sum P(f) f.n / sum P(f))``, then the same within a factor two of that
    (twice more), so that the power near zero frequency does not pull it down. For a
    marble ``sin(2 pi u / period + k T)`` with stationary turbulence ``T`` the power sits in
    a lobe centred near ``1 / period`` however strong the turbulence (the mean of
    ``dT/du`` is zero), where the peak alone wanders between realisations.
    """
    from noise.spectra import periodogram

    power = periodogram(lum)
    ny, nx = lum.shape
    fy = np.fft.fftfreq(ny)[:, None]
    fx = np.fft.fftfreq(nx)[None, :]
    projected = fx * math.cos(across) + fy * math.sin(across)
    lo, hi = 0.0, 1.0
    mean = 0.0
    for _ in range(3):
        weight = np.where((projected > lo) & (projected < hi), power, 0.0)
        total = float(np.sum(weight))
        if total <= 0:
            return float(max(lum.shape))
        mean = float(np.sum(weight * projected)) / total
        lo, hi = mean / 2.0, mean * 2.0
    return float(min(max(1.0 / mean, 2.0), 4.0 * max(lum.shape)))


class Model(ABC):
    """A model: its searched parameters, discrete choices, field and design texture (lengths in px).

    Abstract: each kind (:class:`FBM`, :class:`Turbulence`, :class:`Marble`, :class:`Veined`)
    says how it draws its field and which ``[texture]`` prints it.
    """

    name = ""

    def __init__(self, hints: Hints) -> None:
        self.hints = hints
        self.side = float(max(hints.shape))

    def params(self) -> list[Param]:
        return []

    def choices(self) -> list[dict[str, Any]]:
        return [{"sign": 1.0}, {"sign": -1.0}]

    def decode(self, u: np.ndarray, choice: dict[str, Any]) -> dict[str, Any]:
        values = {p.name: p.value(float(x)) for p, x in zip(self.params(), u, strict=True)}
        return values | choice

    def encode(self, values: dict[str, Any]) -> np.ndarray:
        return np.array([p.unit(values[p.name]) for p in self.params()])

    def starts(self) -> list[dict[str, Any]]:
        """Parameter values the photo suggests, scanned first (besides the quasi-random scan)."""
        return []

    def neutral(self) -> dict[str, Any]:
        """The middle of the search box: what an image with nothing to fit (a constant one) gets."""
        return self.decode(np.full(len(self.params()), 0.5), self.choices()[0])

    @abstractmethod
    def field(self, values: dict[str, Any], grid: Grid, sampler, seed: int) -> np.ndarray:
        """The model's grey field on ``grid`` for parameter ``values``."""

    @abstractmethod
    def texture_fields(self, values: dict[str, Any]) -> dict[str, Any]:
        """``[texture]`` fields (lengths in analysed px) of the kind that prints this model."""


def _octave_sum(
    grid: Grid, sampler, feature: float, octaves: int, lacunarity: float, weight: float, absolute: bool
):
    pts = grid.points() / feature
    n = min(octaves, _octaves_at(feature, grid.pitch_px, lacunarity))
    i = np.arange(n)
    return sampler.octave_sum(pts, 0, lacunarity**i, weight**i, np.zeros((n, 2)), absolute).reshape(
        grid.shape
    )


class FBM(Model):
    name = "fbm"

    def neutral(self):
        return {"feature_px": self.side / 4, "H": 0.5, "lacunarity": 2.0, "octaves": 4, "sign": 1.0}

    def field(self, values, grid, sampler, seed):
        lac = values["lacunarity"]
        return _octave_sum(
            grid, sampler, values["feature_px"], values["octaves"], lac, lac ** -values["H"], False
        )

    def texture_fields(self, values):
        return {
            "kind": "fbm",
            "feature_size_mm": values["feature_px"],
            "octaves": int(values["octaves"]),
            "lacunarity": values["lacunarity"],
            "H": values["H"],
        }


class Turbulence(Model):
    name = "turbulence"

    def neutral(self):
        return {"feature_px": self.side / 4, "octaves": 4, "sign": 1.0}

    def field(self, values, grid, sampler, seed):
        return _octave_sum(grid, sampler, values["feature_px"], values["octaves"], 2.0, 0.5, True)

    def texture_fields(self, values):
        return {
            "kind": "turbulence",
            "feature_size_mm": values["feature_px"],
            "low": 0,
            "high": int(values["octaves"]) - 1,
        }


def _octaves_at(feature_px: float, pitch_px: float, lacunarity: float = 2.0) -> int:
    """Octaves whose cells span at least two samples of ``pitch_px``."""
    n = 1
    while n < MAX_OCTAVES and feature_px / lacunarity**n >= 2.0 * pitch_px:
        n += 1
    return n


class Marble(Model):
    """Perlin's marble: direction and period from the photo, closed form (:class:`Hints`); the rest searched.

    Both are first-order properties of the spectrum that the synthesis measures resolve
    less well than the closed forms do (the orientation bands are 22.5 degrees wide; the
    period moves the spectrum's lobe by less than a half-octave bin).
    """

    name = "marble"
    ANGLE_BOX = math.radians(8.0)

    def params(self) -> list[Param]:
        side = self.side
        return [
            Param("strength", 0.05, 40.0, log=True),
            Param("feature_px", 4.0, 2.0 * side, log=True),
            Param("sharpness", 1.0, 24.0, log=True),
        ]

    def decode(self, u, choice):
        values = super().decode(u, choice)
        values.setdefault("period_px", self.hints.period_px)
        values["angle"] = self.hints.angle
        return values

    def starts(self) -> list[dict[str, Any]]:
        """Turbulence of three strengths."""
        return [{"strength": k, "feature_px": self.side / 6, "sharpness": 1.0} for k in (0.5, 2.0, 6.0)]

    def field(self, values, grid, sampler, seed):
        feature = values["feature_px"]
        n = _octaves_at(feature, grid.pitch_px)
        pts = grid.points() / feature
        i = np.arange(n)
        t = sampler.octave_sum(pts, 0, 2.0**i, 2.0**-i, np.zeros((n, 2)), True)
        a = values["angle"]
        xx, yy = pts[:, 0] * feature, pts[:, 1] * feature
        along = -math.sin(a) * xx + math.cos(a) * yy
        v = 0.5 * (1.0 + np.sin(2.0 * math.pi * along / values["period_px"] + values["strength"] * t))
        return (v ** values["sharpness"]).reshape(grid.shape)

    def texture_fields(self, values):
        return {
            "kind": "marble",
            "feature_size_mm": values["feature_px"],
            "low": 0,
            "high": MAX_OCTAVES - 1,
            "vein_angle_rad": float(np.mod(values["angle"], math.pi)),
            "vein_period_mm": values["period_px"],
            "turbulence_strength": values["strength"],
            "vein_sharpness": values["sharpness"],
        }


class Veined(Model):
    """Branching veins over an fBm ground (the ``veined`` kind)."""

    name = "veined"
    WIDTH = {"ridged": (0.04, 3.0), "cellular": (0.008, 0.6)}

    def params(self) -> list[Param]:
        side = self.side
        return [
            Param("vein_px", 8.0, 0.5 * side, log=True),
            Param("warp", 0.0, 1.2),
            Param("width_u", 0.0, 1.0),
            Param("gain", 0.25, 6.0, log=True),
            Param("fade", 0.0, 2.0),
            Param("ground_weight", 0.01, 0.6, log=True),
            Param("feature_px", 4.0, 2.0 * side, log=True),
            Param("H", -1.0, 1.0),
            Param("stretch", 1.0, self.max_stretch(), log=True),
        ]

    def max_stretch(self) -> float:
        """The most the veins may be stretched: twice what the photo's coherence implies, plus 0.15.

        Noise stretched ``e`` times has the structure tensor's coherence
        ``c = (e^2 - 1) / (e^2 + 1)``, so a photo of coherence ``c`` is stretched about
        ``sqrt((1 + c) / (1 - c))`` times.
        """
        c = min(max(self.hints.coherence, 0.0), 0.95)
        implied = math.sqrt((1.0 + c) / (1.0 - c))
        return min(1.15 + 2.0 * (implied - 1.0), 6.0)

    def choices(self):
        """Both networks; the sign the photo's strongest lines have (both where it cannot tell)."""
        signs = (self.hints.polarity,) if self.hints.polarity else (1.0, -1.0)
        return [{"network": n, "sign": s} for n in ("cellular", "ridged") for s in signs]

    def decode(self, u, choice):
        values = super().decode(u, choice)
        lo, hi = self.WIDTH[values["network"]]
        values["width"] = float(math.exp(math.log(lo) + values["width_u"] * math.log(hi / lo)))
        values["angle"] = self.hints.angle
        values["sharpness"] = 2.0  # Musgrave's square: the width alone sets how thin veins are
        values["vein_H"] = 1.0  # Musgrave's H: finer veins weigh as much less as they are finer
        return values

    def starts(self) -> list[dict[str, Any]]:
        """Marble-like networks: three cell sizes (an eighth, a quarter and two fifths of the photo) and two
        widths, moderately warped and faded, a faint ground with the photo's own spectrum (fBm fit)."""
        ground = self.hints.ground or {"feature_px": self.side / 8, "H": 0.5}
        return [
            {
                "vein_px": self.side * fraction,
                "warp": 0.6,
                "width_u": width_u,
                "gain": 1.5,
                "fade": 0.5,
                "ground_weight": 0.18,
                "feature_px": min(max(ground["feature_px"], 4.0), 2.0 * self.side),
                "H": min(max(ground["H"], -1.0), 1.0),
                "stretch": min(1.1, self.max_stretch()),
            }
            for fraction in (1 / 8, 1 / 4, 2 / 5)
            for width_u in (0.45, 0.65)
        ]

    def texture_fields(self, values):
        return {
            "kind": "veined",
            "feature_size_mm": values["feature_px"],
            "octaves": MAX_OCTAVES,
            "lacunarity": 2.0,
            "ground_H": values["H"],
            "vein_network": values["network"],
            "vein_scale_mm": values["vein_px"],
            "vein_octaves": MAX_OCTAVES,
            "vein_gain": values["gain"],
            "vein_H": values["vein_H"],
            "vein_width": values["width"],
            "vein_sharpness": values["sharpness"],
            "vein_warp": values["warp"],
            "vein_layers": 1,
            "vein_fade": values["fade"],
            "ground_weight": values["ground_weight"],
            "stretch": values["stretch"],
            "angle_rad": float(np.mod(values["angle"], math.pi)),
        }

    def field(self, values, grid, sampler, seed):
        from printapp.design import Texture
        from printapp.texture_kinds import stretch_to_noise_units, veined_values

        texture = Texture.model_construct(**{**self.texture_fields(values), "seed": seed})
        pts = stretch_to_noise_units(grid.points(), texture)
        pitch = grid.pitch_px / texture.feature_size_mm
        return veined_values(pts, texture, pitch, sampler=sampler).reshape(grid.shape)


def make_model(name: str, hints: Hints) -> Model:
    return {"fbm": FBM, "turbulence": Turbulence, "marble": Marble, "veined": Veined}[name](hints)


__all__ = ["MODELS", "NOISE_STD", "Grid", "Hints", "Model", "Param", "make_model"]
