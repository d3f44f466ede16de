"""Veined marble: a sine along a direction, its phase perturbed by turbulence (Perlin 1985).

``v(p) = ((1 + sin(2 pi (n . p) / period + strength * turbulence(p))) / 2) ** sharpness``

with ``n = (-sin a, cos a)`` the wave vector's direction, so the veins (the crests of
the sine, where ``v`` is 1) run along the angle ``a`` from +x towards +y. Perlin's
marble is ``marble(p) = m(sin(p_x + turbulence(p)))`` with a colour spline ``m``
(Perlin 1985, "An image synthesizer", SIGGRAPH; the talk's "Noise-based modeling");
here the colour map is applied by the caller and ``sharpness`` thins the veins before
it. Coordinates are in noise units (one turbulence cell per unit).
"""

from __future__ import annotations

import math

import numpy as np

from noise.scn import turbulence, turbulence_grid


def _check_veins(angle: float, period: float, strength: float, sharpness: float) -> None:
    if not math.isfinite(angle):
        raise ValueError(f"angle: expected a finite angle in radians, got {angle!r}")
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"period: expected a positive number, got {period!r}")
    if not (math.isfinite(strength) and strength >= 0):
        raise ValueError(f"strength: expected a number >= 0, got {strength!r}")
    if not (math.isfinite(sharpness) and sharpness >= 1):
        raise ValueError(f"sharpness: expected a number >= 1, got {sharpness!r}")


def _shape(phase: np.ndarray, sharpness: float) -> np.ndarray:
    v = 0.5 * (1.0 + np.sin(phase))
    return v if sharpness == 1.0 else v**sharpness


def veins(
    points: np.ndarray,
    *,
    angle: float,
    period: float,
    strength: float,
    sharpness: float = 1.0,
    low: int = 0,
    high: int = 4,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """Veined marble at points (see the module docstring for the formula).

    Parameters
    ----------
    points : (n, 2) or (n, 3) float array
        Positions in noise units; the sine depends on x and y only.
    angle : float
        Direction the veins run along (rad, from +x towards +y).
    period : float
        Distance between veins across their direction (noise units).
    strength : float
        Radians of phase per unit of turbulence, >= 0: 0 gives straight stripes.
    sharpness : float
        Exponent >= 1 applied to the [0, 1] value: large values give thin veins.
    low, high, seed, impulses, cell_seed, min_pitch
        The turbulence's, as for :func:`noise.turbulence`.

    Returns
    -------
    (n,) float64 array in [0, 1].
    """
    _check_veins(angle, period, strength, sharpness)
    pts = np.asarray(points, dtype=np.float64)
    t = turbulence(
        pts, low=low, high=high, seed=seed, impulses=impulses, cell_seed=cell_seed, min_pitch=min_pitch
    )
    along = -math.sin(angle) * pts[:, 0] + math.cos(angle) * pts[:, 1]
    return _shape(2.0 * math.pi * along / period + strength * t, sharpness)


def veins_grid(
    x: np.ndarray,
    y: np.ndarray,
    *,
    angle: float,
    period: float,
    strength: float,
    sharpness: float = 1.0,
    low: int = 0,
    high: int = 4,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """:func:`veins` on the grid ``x`` by ``y`` (z = 0), shaped (len(y), len(x)): the fast path."""
    _check_veins(angle, period, strength, sharpness)
    t = turbulence_grid(
        x, y, low=low, high=high, seed=seed, impulses=impulses, cell_seed=cell_seed, min_pitch=min_pitch
    )
    xs = np.asarray(x, dtype=np.float64)[None, :]
    ys = np.asarray(y, dtype=np.float64)[:, None]
    along = -math.sin(angle) * xs + math.cos(angle) * ys
    return _shape(2.0 * math.pi * along / period + strength * t, sharpness)
