"""Branching veins: Musgrave's ridged multifractal over noise or cellular edges, domain-warped, in layers.

The pieces, each after its source:

* **Ridges.** A ridge follows the zero set of a basis ``d >= 0``: ``d = |n| / sigma_n``
  for sparse convolution noise ``n`` (zero crossings: meandering lines), or
  ``d = F2 - F1`` for cellular noise (Voronoi edges: a crack network with Y-junctions,
  :mod:`noise.cellular`). The ridge profile is ``r(d) = max(0, 1 - d / width)^sharpness``:
  1 on the ridge line, 0 from ``width`` away.
* **Ridged multifractal** (F. K. Musgrave, in Ebert et al., *Texturing and Modeling: A
  Procedural Approach*, 3rd ed. 2003, ch. 16, ``RidgedMultifractal``): octave ``i``
  (frequency ``lacunarity^i``) adds ``lacunarity^(-H i) w_i r(d_i)``, where the weight
  ``w_i = clamp(gain * s_(i-1), 0, 1)`` is the previous octave's weighted signal
  ``s_(i-1) = w_(i-1) r(d_(i-1))`` (``w_0 = 1``): fine ridges grow only beside coarse
  ones, so veins branch; where the weight falls to 0.001 a point's sum stops, as
  Musgrave's loop does (so finer octaves are computed only near veins). Musgrave's
  ``(offset - |n|)^2`` is ``r`` with ``sharpness = 2``
  and ``width = offset``, clamped at zero beyond ``offset`` (Musgrave's squares negative
  values back up into spurious bumps). The sum is divided by the sum of the octave
  weights, so values lie in [0, 1].
* **Domain warping** (noise of noise; Perlin 1985's turbulence-displaced marble, and
  Quílez's "domain warping"): the basis is read at ``q = p + warp (g_1(p / 2), g_2(p / 2))``
  with ``g_k`` independent fBm (octave weights ``2^(-warp_H i)``, one octave more than the
  veins) normalised to unit standard deviation, features twice the network's cells:
  straight cell edges and smooth zero sets become the wandering, kinked veins of marble
  (with ``warp_H = 1`` kinked alike at every scale, as cracks are).
* **Layers**: layer ``l`` (0, 1, ...) is the same network turned by ``l * layer_turn``,
  its cells ``layer_scale^l`` as big, weighted ``layer_weight^l``, from its own noise
  streams; the value is the weighted maximum over layers (veins cross, they do not add up).

Coordinates are noise units: one cell of the first layer's first octave per unit.
Noise comes from a ``sampler`` (:mod:`noise.tables`): the exact sparse convolution noise
by default, a periodic table with its spectrum while fitting.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from noise.cellular import cellular
from noise.tables import Sampler, exact_sampler, stream_seed

NOISE_STD = 0.1503
"""Standard deviation of sparse convolution noise with 30 impulses per cell (measured, 4 million samples)."""
BASES = ("noise", "cells")
_SHIFT = np.array([4.0, 4.0])
"""Every warped coordinate is moved by this much, so that tables starting at 0 hold them."""
_OCTAVE_SHIFT = np.array([0.37, 0.71])
"""Octave i is read at ``lacunarity^i q + i * shift``: octaves do not share a lattice origin."""


CUTOFF = 1e-3
"""An octave is skipped at a point where its weight is at most this (Musgrave's loop stops there)."""


@njit(cache=True, nogil=True)
def _ridged_octave(
    distances: np.ndarray,
    active: np.ndarray,
    first: bool,
    width: float,
    sharpness: float,
    gain: float,
    weight: float,
    previous: np.ndarray,
    total: np.ndarray,
) -> np.ndarray:
    """One octave of the cascade at the ``active`` points (``distances[k]`` belongs to ``active[k]``).

    Adds ``weight * s`` to ``total`` and keeps ``s`` in ``previous``; returns the points whose
    next octave's weight ``clamp(gain * s, 0, 1)`` exceeds :data:`CUTOFF`.
    """
    keep = np.empty(active.size, dtype=np.int64)
    count = 0
    for k in range(active.size):
        j = active[k]
        u = 1.0 - distances[k] / width
        s = (u * u if sharpness == 2.0 else u**sharpness) if u > 0.0 else 0.0
        if not first:
            s *= min(max(gain * previous[j], 0.0), 1.0)
        total[j] += weight * s
        previous[j] = s
        if min(gain * s, 1.0) > CUTOFF:
            keep[count] = j
            count += 1
    return keep[:count]


def _check_cascade(width: float, sharpness: float, gain: float) -> None:
    _check_positive("width", width)
    if not (math.isfinite(sharpness) and sharpness >= 1.0):
        raise ValueError(f"sharpness: expected a number >= 1, got {sharpness!r}")
    if not (math.isfinite(gain) and gain >= 0.0):
        raise ValueError(f"gain: expected a number >= 0, got {gain!r}")


def ridged_cascade(
    basis,
    n: int,
    *,
    octaves: int,
    width: float,
    sharpness: float = 2.0,
    gain: float = 2.0,
    weights: np.ndarray,
) -> np.ndarray:
    """Musgrave's ridged multifractal over a basis evaluated only where it still counts.

    ``basis(i, index)`` gives octave ``i``'s distances ``d_i >= 0`` (0 on the ridge lines) at
    the points ``index`` (an int64 array into the ``n`` points). Octave 0 is read everywhere;
    octave ``i`` only where its weight ``clamp(gain * s_(i-1), 0, 1)`` exceeds
    :data:`CUTOFF` (Musgrave's loop, ``for (...; weight > 0.001 && ...)``, tests the weight one
    octave later, so it adds one more octave of weight at most 0.001): away
    from the coarse ridges, no finer octave is ever computed.

    Parameters
    ----------
    basis : callable
    n : int
        Number of points.
    octaves : int
    width : float
        Where the ridge profile reaches zero, in the basis's units (> 0).
    sharpness : float
        The profile's exponent (>= 1); Musgrave squares it (2).
    gain : float
        How strongly an octave's signal lets the next one through (>= 0; Musgrave: 2).
    weights : (octaves,) float array
        The octaves' weights, ``lacunarity^(-H i)``, > 0.

    Returns
    -------
    (n,) float64 array in [0, 1]: the sum divided by the sum of the weights.
    """
    _check_cascade(width, sharpness, gain)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (octaves,) or octaves < 1 or not np.all(w > 0):
        raise ValueError(f"weights: expected {octaves} positive octave weights, got shape {w.shape}")
    total = np.zeros(n)
    previous = np.ones(n)
    active = np.arange(n, dtype=np.int64)
    for i in range(octaves):
        if active.size == 0:
            break
        d = np.ascontiguousarray(basis(i, active), dtype=np.float64)
        if d.shape != active.shape or not np.all(np.isfinite(d)):
            raise ValueError(f"basis: expected {active.size} finite distances for octave {i}")
        active = _ridged_octave(
            d, active, i == 0, float(width), float(sharpness), float(gain), float(w[i]), previous, total
        )
    return total / float(np.sum(w))


def _check_positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name}: expected a positive number, got {value!r}")


def _as_points2(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points: expected an (n, 2) or (n, 3) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points: expected finite coordinates, found NaN or infinity")
    return np.ascontiguousarray(pts[:, :2])


def domain_warp(
    points: np.ndarray,
    *,
    warp: float,
    octaves: int = 3,
    H: float = 0.5,
    seed: int = 0,
    streams: tuple[int, int] = (1, 2),
    sampler=None,
) -> np.ndarray:
    """Points displaced by noise: ``p + warp (g_1(p / 2), g_2(p / 2))`` (noise of noise).

    ``g_k`` is fBm (lacunarity 2, octave weights ``2^(-H i)``) of noise stream ``streams[k]``
    with features twice the size of a unit, divided by its standard deviation, so
    ``warp`` is the displacement's standard deviation along each axis in noise units
    (cells). With ``H = 1`` every octave displaces the points by the same fraction of its
    own features: the warped lines are kinked alike at every scale.

    Parameters
    ----------
    points : (n, 2) float array
    warp : float
        >= 0; 0 returns the points unchanged.
    octaves : int
        Octaves of the displacement field, >= 1.
    H : float
        In [0, 2]: how fast the finer octaves' displacements fall.
    seed, streams, sampler
        The noise: streams of ``seed`` read through ``sampler`` (:mod:`noise.tables`;
        default the exact sparse convolution noise).

    Returns
    -------
    (n, 2) float64 array
    """
    pts = _as_points2(points)
    if not (math.isfinite(warp) and warp >= 0):
        raise ValueError(f"warp: expected a number >= 0, got {warp!r}")
    if not (isinstance(octaves, (int, np.integer)) and 1 <= octaves <= 16):
        raise ValueError(f"octaves: expected an integer in 1..16, got {octaves!r}")
    if not (math.isfinite(H) and 0 <= H <= 2):
        raise ValueError(f"H: expected a number in [0, 2], got {H!r}")
    if warp == 0:
        return pts.copy()
    sample: Sampler = sampler if sampler is not None else exact_sampler(seed)
    weights = 2.0 ** (-H * np.arange(octaves))
    norm = warp / (NOISE_STD * math.sqrt(float(np.sum(weights * weights))))
    scales = 0.5 * 2.0 ** np.arange(octaves)
    shifts = np.outer(np.arange(octaves), _OCTAVE_SHIFT)
    out = pts.copy()
    for axis, stream in enumerate(streams):
        out[:, axis] += norm * sample.octave_sum(pts, stream, scales, weights, shifts)
    return out


def _octave_count(octaves: int, lacunarity: float, cell: float, min_pitch: float | None) -> int:
    """Octaves whose cells (``cell / lacunarity^i`` noise units) span two samples of ``min_pitch`` or more."""
    if min_pitch is None:
        return octaves
    kept = 1
    for i in range(1, octaves):
        if cell / lacunarity**i < 2.0 * min_pitch:
            break
        kept = i + 1
    return kept


def vein_network(
    points: np.ndarray,
    *,
    basis: str = "noise",
    octaves: int = 4,
    lacunarity: float = 2.0,
    H: float = 1.0,
    gain: float = 2.0,
    width: float = 0.5,
    sharpness: float = 2.0,
    warp: float = 0.0,
    warp_H: float = 1.0,
    layers: int = 1,
    layer_turn: float = math.pi / 3,
    layer_scale: float = 0.5,
    layer_weight: float = 0.5,
    seed: int = 0,
    min_pitch: float | None = None,
    sampler=None,
) -> np.ndarray:
    """Branching veins at points: layers of a domain-warped ridged multifractal (module docstring).

    Parameters
    ----------
    points : (n, 2) or (n, 3) float array
        Positions in noise units (z is ignored): one first-octave cell of the first layer per unit.
    basis : {"noise", "cells"}
        Ridges along the zero crossings of sparse convolution noise (``d = |n| / sigma``,
        :data:`NOISE_STD`), or along the edges of cellular noise (``d = F2 - F1``, Worley 1996).
    octaves, lacunarity, H, gain, width, sharpness
        The ridged multifractal's (:func:`ridged_cascade`): octave ``i`` has cells
        ``lacunarity^-i`` units across and weight ``lacunarity^(-H i)``. ``width`` is in
        the basis's units: noise standard deviations, or cell units of ``F2 - F1``.
    warp, warp_H : float
        Standard deviation of the domain warp (cells of the layer), >= 0, and how fast its
        octaves fall (:func:`domain_warp`); the warp has as many octaves as the veins, plus one.
    layers : int
        1 to 4 layers; layer ``l`` is turned by ``l * layer_turn`` (rad), its cells
        ``layer_scale^l`` as big (``0 < layer_scale``), weighted ``layer_weight^l`` (in (0, 1]).
    seed : int
        Layer ``l`` reads noise streams ``10 l .. 10 l + 3`` of ``seed`` (:func:`noise.tables.stream_seed`).
    min_pitch : float, optional
        Sampling pitch (noise units): octaves whose cells span fewer than two samples are dropped.
    sampler : callable, optional
        ``sampler(points, stream)`` (:mod:`noise.tables`); default the exact noise of ``seed``.

    Returns
    -------
    (n,) float64 array in [0, 1]: 1 on a vein's centre line, 0 away from veins.
    """
    pts = _as_points2(points)
    if basis not in BASES:
        raise ValueError(f"basis: expected one of {BASES}, got {basis!r}")
    if not (isinstance(octaves, (int, np.integer)) and 1 <= octaves <= 12):
        raise ValueError(f"octaves: expected an integer in 1..12, got {octaves!r}")
    if not (math.isfinite(lacunarity) and lacunarity > 1):
        raise ValueError(f"lacunarity: expected a number > 1, got {lacunarity!r}")
    if not (math.isfinite(H) and 0 <= H <= 2):
        raise ValueError(f"H: expected a number in [0, 2], got {H!r}")
    if not (isinstance(layers, (int, np.integer)) and 1 <= layers <= 4):
        raise ValueError(f"layers: expected an integer in 1..4, got {layers!r}")
    _check_positive("layer_scale", layer_scale)
    if not (math.isfinite(layer_weight) and 0 < layer_weight <= 1):
        raise ValueError(f"layer_weight: expected a number in (0, 1], got {layer_weight!r}")
    if not math.isfinite(layer_turn):
        raise ValueError(f"layer_turn: expected a finite angle (rad), got {layer_turn!r}")
    if min_pitch is not None:
        _check_positive("min_pitch", min_pitch)
    sample: Sampler = sampler if sampler is not None else exact_sampler(seed)
    result = np.zeros(pts.shape[0])
    for layer in range(layers):
        turn = layer * layer_turn
        c, s = math.cos(turn), math.sin(turn)
        scale = layer_scale**layer
        local = np.column_stack([c * pts[:, 0] + s * pts[:, 1], -s * pts[:, 0] + c * pts[:, 1]]) / scale
        base = 10 * layer
        pitch = None if min_pitch is None else min_pitch / scale
        count = _octave_count(octaves, lacunarity, 1.0, pitch)
        q = domain_warp(
            local, warp=warp, octaves=count + 1, H=warp_H, streams=(base + 1, base + 2), sampler=sample
        )
        q += _SHIFT
        cell_seed = stream_seed(seed, base + 3)

        def octave(i: int, index: np.ndarray, q=q, base=base, cell_seed=cell_seed) -> np.ndarray:
            shift = _OCTAVE_SHIFT * i
            at = q[index]
            if basis == "noise":
                return np.abs(sample(at, base, lacunarity**i, (float(shift[0]), float(shift[1])))) / NOISE_STD
            f1, f2 = cellular(at * lacunarity**i + shift, seed=cell_seed)
            return f2 - f1

        weights = lacunarity ** (-H * np.arange(count))
        v = ridged_cascade(
            octave, pts.shape[0], octaves=count, width=width, sharpness=sharpness, gain=gain, weights=weights
        )
        np.maximum(result, layer_weight**layer * v, out=result)
    return result


def fbm_sampled(
    points: np.ndarray,
    *,
    octaves: int,
    lacunarity: float = 2.0,
    H: float = 1.0,
    stream: int = 0,
    seed: int = 0,
    min_pitch: float | None = None,
    sampler=None,
) -> np.ndarray:
    """fBm of one noise stream at points, divided by its standard deviation (unit variance).

    ``sum_i lacunarity^(-H i) n(lacunarity^i p) / (sigma_n sqrt(sum_i lacunarity^(-2 H i)))``: the
    sum of :func:`noise.fbm` (octaves are uncorrelated, each of standard deviation
    :data:`NOISE_STD`), read through ``sampler`` (default: the exact noise of ``seed``).

    Parameters
    ----------
    points : (n, 2) or (n, 3) float array
        Positions in noise units (z is ignored).
    octaves, lacunarity, H
        As for :func:`noise.fbm`, except that ``H`` may be as low as -1: at 0 every octave is
        as strong as the next, below 0 the finer ones are stronger (a flat, grainy spectrum
        at -1, where fBm's ``f^-(2H+2)`` is ``f^0``).
    stream : int
        Which independent noise of ``seed`` (:func:`noise.tables.stream_seed`).
    min_pitch : float, optional
        Sampling pitch (noise units): octaves whose cells span fewer than two samples are dropped.
    """
    pts = _as_points2(points)
    if not (isinstance(octaves, (int, np.integer)) and 1 <= octaves <= 24):
        raise ValueError(f"octaves: expected an integer in 1..24, got {octaves!r}")
    if not (math.isfinite(lacunarity) and lacunarity > 1):
        raise ValueError(f"lacunarity: expected a number > 1, got {lacunarity!r}")
    if not (math.isfinite(H) and -1 <= H <= 1):
        raise ValueError(f"H: expected a number in [-1, 1], got {H!r}")
    sample: Sampler = sampler if sampler is not None else exact_sampler(seed)
    count = _octave_count(octaves, lacunarity, 1.0, min_pitch)
    weights = lacunarity ** (-H * np.arange(count))
    total = sample.octave_sum(pts, stream, lacunarity ** np.arange(count), weights, np.zeros((count, 2)))
    return total / (NOISE_STD * math.sqrt(float(np.sum(weights * weights))))
