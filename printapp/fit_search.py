"""How ``printapp fit`` searches a synthesised model's parameters: coarse to fine, global, in parallel.

Two levels look at the photo: the whole of it downsampled to about 128 px (the large
scales: how big the veins' network is, where the ground's power sits) and 128 px windows
at full resolution (the fine ones: how thin the veins are, the grain). The objective at
a level sums the measures of :mod:`printapp.fit_measures` (spectrum, orientation, lines,
layout, continuity), each over the photo's own variation at that level; the values are
matched exactly over the whole image by construction, and at the coarse level their
distributions in the halves are compared too (veins that fade in and out make halves
that differ).

1. **Scan** (coarse level): the starting points the photo suggests, then a low-discrepancy
   sequence (Roberts' R_d), for every discrete choice (network, sign).
2. **CMA-ES** (both levels; Hansen 2016, "The CMA Evolution Strategy: A Tutorial",
   :func:`cma_es`) from the best scanned points.
3. **Finalists**: the five best distinct points are handed back, to be measured on the
   texture itself (exact noise, full resolution) by the caller, which keeps the best:
   the search reads the noise from tables, so its ranking of near-equal points is a
   ranking on another realisation of the noise.

The optimiser's random numbers have a fixed seed of their own: the fit depends on
``--seed`` only through the noise it synthesises. Each population is evaluated by a pool
of threads and the results are taken in order, so they do not depend on the number of
workers.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from printapp.fit_measures import (
    FLOORS,
    LineMaps,
    Stats,
    continuity,
    distances,
    half_stats,
    halves,
    layout_spectra,
    line_maps,
    line_scales,
    line_statistics,
    match_values,
    spectra,
)
from printapp.fit_models import Grid, Model

COARSE_SIDE = 128
"""Longer side (px) of the coarse level."""
WINDOW = 128
"""Side (px) of the fine level's full-resolution window."""
OBJECTIVE_MEASURES = ("spectrum", "orientation", "lines", "layout", "continuity")
OPTIMISER_SEED = 20_251_202
"""The optimiser's own seed (CMA-ES's samples): fixed, whatever ``--seed`` is."""


def downsample(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Lanczos resampling to ``shape`` (Pillow, float32): anti-aliased, flat almost to Nyquist."""
    from PIL import Image

    if image.shape == shape:
        return image.astype(np.float64)
    im = Image.fromarray(image.astype(np.float32), mode="F")
    return np.asarray(im.resize((shape[1], shape[0]), Image.Resampling.LANCZOS), dtype=np.float64)


def coarse_shape(shape: tuple[int, int]) -> tuple[int, int]:
    factor = max(1.0, max(shape) / COARSE_SIDE)
    return max(16, round(shape[0] / factor)), max(16, round(shape[1] / factor))


@dataclass
class Level:
    """One resolution the objective looks at: the photo's statistics there, their spread, the grid."""

    target: Stats
    spread: dict[str, float]
    """Each measure's typical distance between two samples of the photo at this level (its weight)."""
    grid: Grid
    sorted_lum: np.ndarray
    scales: tuple[float, ...] | None = None
    """Line filter scales (px); default those of the level's image size."""
    half_values: tuple[np.ndarray, ...] = ()
    """The photo's sorted values in its left, right, bottom and top halves at this level, if the
    halves' value distributions are to be matched too (the whole image's is matched exactly)."""
    values_spread: float = 1.0

    def synthesise(self, model: Model, values: dict[str, Any], sampler, seed: int) -> np.ndarray:
        return model.field(values, self.grid, sampler, seed)

    def cost(self, lum: np.ndarray) -> float:
        radial, orientation = spectra(lum)
        maps = line_maps(lum, self.scales)
        lines = line_statistics(maps.strengths, float(lum.std()))
        stats = Stats(
            self.target.shape,
            radial,
            orientation,
            (),
            lines,
            layout_spectra(maps.strengths),
            continuity(maps),
        )
        d = distances_without_values(stats, self.target)
        total = sum(d[m] / self.spread[m] for m in OBJECTIVE_MEASURES)
        if self.half_values:
            mine = [np.sort(h, axis=None) for h in halves(lum)]
            pairs = ((0, 1), (1, 0), (2, 3), (3, 2))
            w1 = np.mean([np.mean(np.abs(mine[a] - self.half_values[b])) for a, b in pairs])
            total += float(w1) / self.values_spread
        return total


def distances_without_values(a: Stats, b: Stats) -> dict[str, float]:
    """The objective's measures (all but the values, which matching makes equal)."""
    d = distances(
        Stats(a.shape, a.spectrum, a.orientation, (np.zeros(1),), a.lines, a.layout, a.continuity),
        Stats(b.shape, b.spectrum, b.orientation, (np.zeros(1),), b.lines, b.layout, b.continuity),
    )
    return {m: getattr(d, m) for m in OBJECTIVE_MEASURES}


def coarse_level(lum: np.ndarray) -> Level:
    """The whole photo at about 128 px; the spread is the distance between its halves."""
    shape = coarse_shape(lum.shape)
    small = downsample(lum, shape)
    target = Stats.of(small)
    pieces = half_stats(small)
    own = {
        m: 0.5
        * (
            distances_without_values(pieces[0], pieces[1])[m]
            + distances_without_values(pieces[2], pieces[3])[m]
        )
        for m in OBJECTIVE_MEASURES
    }
    spread = {m: max(own[m], getattr(FLOORS, m)) for m in OBJECTIVE_MEASURES}
    grid = Grid.of(shape, lum.shape)
    sorted_halves = tuple(np.sort(h, axis=None) for h in halves(small))
    own_values = 0.5 * (
        float(np.mean(np.abs(sorted_halves[0] - sorted_halves[1])))
        + float(np.mean(np.abs(sorted_halves[2] - sorted_halves[3])))
    )
    return Level(
        target,
        spread,
        grid,
        np.sort(small, axis=None),
        half_values=sorted_halves,
        values_spread=max(own_values, FLOORS.values),
    )


def window_level(lum: np.ndarray, maps: LineMaps | None = None) -> Level | None:
    """128 px windows at full resolution (None for photos of at most 1.5 windows).

    The target averages the power of all the photo's windows (Welch) and takes the line
    statistics of the whole photo; the spread is the median distance of one window from it.
    ``maps`` are the photo's line maps at :func:`line_scales` if already known.
    """
    ny, nx = lum.shape
    if min(ny, nx) < WINDOW or max(ny, nx) <= 1.5 * WINDOW:
        return None
    from noise.spectra import periodogram

    scales = line_scales(lum.shape)
    maps = line_maps(lum, scales) if maps is None else maps
    tiles = [(r, c) for r in range(0, ny - WINDOW + 1, WINDOW) for c in range(0, nx - WINDOW + 1, WINDOW)]
    powers, stats = [], []
    for r, c in tiles:
        window = lum[r : r + WINDOW, c : c + WINDOW]
        powers.append(periodogram(window))
        stats.append(Stats.of(window, lines=maps.crop(slice(r, r + WINDOW), slice(c, c + WINDOW))))
    from printapp.fit_measures import spectra_of_power

    radial, orientation = spectra_of_power(np.mean(powers, axis=0))
    layout = np.log10(np.mean([10.0**s.layout for s in stats], axis=0))
    target = Stats(
        (WINDOW, WINDOW),
        radial,
        orientation,
        (),
        line_statistics(maps.strengths, float(lum.std())),
        layout,
        continuity(maps),
    )
    spread = {
        m: max(float(np.median([distances_without_values(s, target)[m] for s in stats])), getattr(FLOORS, m))
        for m in OBJECTIVE_MEASURES
    }
    grid = Grid.of((WINDOW, WINDOW), (WINDOW, WINDOW))
    return Level(target, spread, grid, np.sort(lum, axis=None), scales=scales)


@dataclass
class SearchTrace:
    """Evaluations so far and the best objective after each generation."""

    evaluations: int = 0
    best: list[tuple[int, float]] = field(default_factory=list)


@dataclass
class ModelFit:
    """What the optimiser found for one model."""

    model: Model
    values: dict[str, Any]
    objective: float
    evaluations: int
    trace: list[tuple[int, float]] = field(default_factory=list)
    candidates: list[tuple[float, dict[str, Any]]] = field(default_factory=list)
    """The best few distinct points (objective, values), best first: finalists for the exact measures."""


class Objective:
    """The objective of a model over levels, evaluated for whole populations by a thread pool."""

    def __init__(
        self, model: Model, levels: list[Level], sampler, seed: int, pool: ThreadPoolExecutor
    ) -> None:
        self.model, self.levels, self.sampler, self.seed, self.pool = model, levels, sampler, seed, pool
        self.trace = SearchTrace()
        self.best_value = math.inf
        self.best: tuple[np.ndarray, dict[str, Any]] | None = None
        self.seen: list[tuple[float, np.ndarray, dict[str, Any]]] = []

    def one(self, u: np.ndarray, choice: dict[str, Any]) -> float:
        values = self.model.decode(np.clip(u, 0.0, 1.0), choice)
        total = 0.0
        for level in self.levels:
            s = level.synthesise(self.model, values, self.sampler, self.seed)
            lum = match_values(s, level.sorted_lum, values["sign"])
            total += level.cost(lum)
        return total

    def many(self, points: list[tuple[np.ndarray, dict[str, Any]]]) -> list[float]:
        results = list(self.pool.map(lambda item: self.one(*item), points))
        for (u, choice), value in zip(points, results, strict=True):
            self.trace.evaluations += 1
            self.seen.append((value, np.array(u, dtype=float), dict(choice)))
            if value < self.best_value:
                self.best_value, self.best = value, (np.array(u, dtype=float), dict(choice))
        self.trace.best.append((self.trace.evaluations, self.best_value))
        return results


def low_discrepancy(count: int, dims: int) -> np.ndarray:
    """``count`` points of Roberts' R_d sequence in the unit cube (Roberts 2018, "The unreasonable
    effectiveness of quasirandom sequences"): ``frac(1/2 + k alpha)``, ``alpha_j = phi_d^-(j+1)`` with
    ``phi_d`` the root of ``x^(d+1) = x + 1``. As even as a Sobol sequence, for any count."""
    phi = 2.0
    for _ in range(40):
        phi = (1.0 + phi) ** (1.0 / (dims + 1))
    alpha = phi ** -(np.arange(dims) + 1.0)
    return np.mod(0.5 + np.outer(np.arange(1, count + 1), alpha), 1.0)


def cma_es(objective: Objective, x0: np.ndarray, choice: dict[str, Any], sigma0: float, budget: int) -> None:
    """CMA-ES in the unit box (Hansen 2016, "The CMA Evolution Strategy: A Tutorial", fig. 6).

    ``(mu / mu_w, lambda)`` selection with ``lambda = 4 + floor(3 ln n)``, cumulative step-size
    adaptation, rank-one and rank-mu covariance updates, the tutorial's default constants.
    Points outside the box are evaluated at their projection onto it and penalised by their
    squared distance from it, so that the distribution is steered back inside. Its own
    random generator (seed :data:`OPTIMISER_SEED`): never numpy's global one. Stops after
    ``budget`` evaluations (whole generations) or once the steps are below 1e-4.
    """
    n = x0.size
    lam = 4 + int(3 * math.log(n))
    mu = lam // 2
    w = math.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mueff = 1.0 / float(np.sum(w * w))
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = (mueff + 2) / (n + mueff + 5)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    damps = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    chi_n = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))
    rng = np.random.default_rng(OPTIMISER_SEED)
    mean = np.clip(np.asarray(x0, dtype=float), 0.02, 0.98)
    sigma, pc, ps, cov = float(sigma0), np.zeros(n), np.zeros(n), np.eye(n)
    spent, generation = 0, 0
    while spent + lam <= budget:
        eigenvalues, basis = np.linalg.eigh(cov)
        scale = np.sqrt(np.maximum(eigenvalues, 1e-20))
        z = rng.standard_normal((lam, n))
        y = (z * scale) @ basis.T
        x = mean + sigma * y
        inside = np.clip(x, 0.0, 1.0)
        values = objective.many([(u, choice) for u in inside])
        penalty = np.sum((x - inside) ** 2, axis=1)
        order = np.argsort(np.asarray(values) + penalty, kind="stable")[:mu]
        spent += lam
        generation += 1
        y_w = w @ y[order]
        mean = mean + sigma * y_w
        inv_sqrt = basis @ np.diag(1 / scale) @ basis.T
        ps = (1 - cs) * ps + math.sqrt(cs * (2 - cs) * mueff) * (inv_sqrt @ y_w)
        h_sigma = float(
            np.linalg.norm(ps) / math.sqrt(1 - (1 - cs) ** (2 * generation)) < (1.4 + 2 / (n + 1)) * chi_n
        )
        pc = (1 - cc) * pc + h_sigma * math.sqrt(cc * (2 - cc) * mueff) * y_w
        rank_mu = (y[order].T * w) @ y[order]
        cov = (
            (1 - c1 - cmu) * cov
            + c1 * (np.outer(pc, pc) + (1 - h_sigma) * cc * (2 - cc) * cov)
            + cmu * rank_mu
        )
        cov = 0.5 * (cov + cov.T)
        sigma *= math.exp((cs / damps) * (np.linalg.norm(ps) / chi_n - 1))
        if sigma * math.sqrt(float(np.max(np.diag(cov)))) < 1e-4:
            break


def search(
    model: Model,
    levels: list[Level],
    sampler,
    seed: int,
    budget: int,
    workers: int,
    starts: list[dict[str, Any]] | None = None,
) -> ModelFit:
    """Fit a synthesised model: a scan at the coarse level, then CMA-ES on all levels.

    A third of ``budget`` scans (``starts``, then a low-discrepancy sequence, for every
    discrete choice) at the coarse level alone; the rest goes to CMA-ES on the sum of all
    levels, from the best scanned point of the best choice (of the best two, each with
    half, when 60 or more evaluations remain), with a step of 0.15 of the unit box.
    """
    coarse = levels[0]
    params = model.params()
    choices = model.choices()
    seeded = [(model.encode({**s, **c}), c) for c in choices for s in (starts or [])]
    n_sobol = max(2, (budget // 3 - len(seeded)) // len(choices))
    scan = low_discrepancy(n_sobol, len(params))
    items = seeded + [(u, c) for c in choices for u in scan]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        scanner = Objective(model, [coarse], sampler, seed, pool)
        values = scanner.many(items)
        best_per_choice: dict[str, tuple[float, np.ndarray, dict[str, Any]]] = {}
        for (u, c), v in zip(items, values, strict=True):
            key = repr(sorted(c.items()))
            if key not in best_per_choice or v < best_per_choice[key][0]:
                best_per_choice[key] = (v, u, c)
        ranked = sorted(best_per_choice.values(), key=lambda item: item[0])
        remaining = max(budget - len(items), 0)
        polish = ranked[:2] if remaining >= 60 else ranked[:1]
        objective = Objective(model, levels, sampler, seed, pool)
        for _, u0, c in polish:
            cma_es(objective, u0, c, 0.15, max(remaining // len(polish), 1))
        if objective.best is None:  # no budget left for CMA-ES: the best scanned point, on all levels
            objective.many([(ranked[0][1], ranked[0][2])])
    assert objective.best is not None
    u_best, c_best = objective.best
    trace = [(len(items) + n, v) for n, v in objective.trace.best]
    evaluations = len(items) + objective.trace.evaluations
    return ModelFit(
        model,
        model.decode(u_best, c_best),
        objective.best_value,
        evaluations,
        trace,
        [(v, model.decode(u, c)) for v, u, c in finalists(objective.seen, FINALISTS)],
    )


FINALISTS = 5
"""Distinct best points of a search that are measured exactly, on the texture that will be printed."""


def finalists(
    seen: list[tuple[float, np.ndarray, dict[str, Any]]], count: int, apart: float = 0.05
) -> list[tuple[float, np.ndarray, dict[str, Any]]]:
    """The ``count`` best points, each at least ``apart`` (in some unit-box coordinate) from better ones."""
    out: list[tuple[float, np.ndarray, dict[str, Any]]] = []
    for value, u, choice in sorted(seen, key=lambda item: item[0]):
        if all(choice != c or np.max(np.abs(u - v)) > apart for _, v, c in out):
            out.append((value, u, choice))
        if len(out) == count:
            break
    return out
