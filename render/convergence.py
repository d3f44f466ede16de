"""How noisy is a render, and rendering until it is not: independent halves, progressive passes.

**The noise figure.** A render is accumulated in two independent halves ``A`` and ``B`` of
equal sample counts (different seeds, so different randomisations of the stratified
sampler). For pixel ``i`` with luminances ``a_i``, ``b_i`` the preview is ``(a_i + b_i) / 2``,
and ``E[(a_i - b_i)^2] = 2 Var(a_i)``, so ``(a_i - b_i)^2 / 4`` is an unbiased estimate of
the preview pixel's variance, whatever the sampler's stratification within a half. The
*relative noise* of a render is

    noise = sqrt( mean_obj (a_i - b_i)^2 / 4 ) / mean_obj (a_i + b_i) / 2

over the object's pixels (its coverage mask): the RMS standard error of a pixel's luminance
relative to the object's mean luminance (the background's constant environment has none).
The mean of the squares is unbiased; its square root is biased low by about
``Var(s^2) / (8 s^4)`` (Jensen's inequality), under 0.1 % with 10,000 object pixels of
Gaussian noise and a few per cent when a handful of fireflies carry the variance (then the
estimate itself fluctuates from seed to seed, which tests/test_convergence.py measures).

**The denoised preview's error, from the render itself.** A denoiser ``D`` is applied to
each half; ``B`` is independent of ``A`` and unbiased for the converged image ``C``, so
``E[(D(A)_i - b_i)^2] = E[(D(A)_i - c_i)^2] + Var(b_i)`` and

    e_A^2 = mean_obj (D(A)_i - b_i)^2 - mean_obj (a_i - b_i)^2 / 2

estimates, without any reference, the mean squared error of ``D(A)`` against the converged
image, the denoiser's blur and artefacts included (likewise ``e_B``). The preview delivered
is ``(D(A) + D(B)) / 2``, whose RMS error is at most ``(e_A + e_B) / 2`` (Minkowski's
inequality): that, over the object's mean luminance, is the *denoised error*. It is reported,
and a denoised image is delivered only where it is below the raw noise; whether a preview
has converged is decided by the raw noise alone.

**Progressive rendering** (:func:`converge`): both halves start at ``first_spp`` samples and
are doubled once, uniformly; from then on each pixel gets samples in proportion to its own
noise (*adaptive sampling*). A pixel's variance at one sample is read from its halves,
averaged over its 5 x 5 neighbourhood (one pixel's halves give one degree of freedom) and
floored at 5 % of the mean; noise falls as ``spp^-a`` (``a`` measured from the last two rounds,
:func:`round_rate`), and the counts that reach the goal for the fewest samples in all are the
Lagrange optimum ``N_i ~ v_i^(1 / (1 + 2a))`` (:func:`allocate_samples`; ``N_i ~ sigma_i`` for
independent samples), within the per-pixel cap and no round adding more than :data:`MAX_LEAP`
times the samples taken (a hot pixel may leap further: the round's total is what extrapolates
the rate). Uniform
sampling needs ``mean(sigma^2)`` where this needs ``mean(sigma)^2``: on the CAD examples, whose
soft-box glints and caustics hold most of the variance, 2 % takes 1.6-2.1 times fewer samples
and 1.3-1.7 times less rendering (``printapp bench sampling``).
The noise figure is unchanged: each pixel's halves keep equal counts, so ``(a_i - b_i)^2 / 4`` is
still its variance, and the figure is measured, never predicted. Every decision is taken from
the image, never from a clock, so the same scene and seed give the same passes and the same
image. The one exception is the time cap: the time the second round took (warm: the first also
compiles) fixes how many samples fit in the cap (their mean per pixel rounded down to 1, 2, 3,
4, 6, 8, 12..., :func:`_half_octave_floor`), and each later round fixes it again from its own
time a sample (the second round is small, and each pass's fixed cost made it foretell too few).
Where that binds (a round cut short of what the image asked for, or the run stopped by the
cap), a machine a good deal faster or slower may take a different number of samples;
:class:`Converged` says whether it did. The time cap counts rendering only, not the denoiser.

**A light-traced part** (``converge(caustics=...)``, :mod:`render.caustics`): paths the camera's
samples leave out, estimated apart in each half and added before the noise is measured.

The module is one piece (about 730 lines; the allocation's numba kernels stand apart, in
``render._allocation_kernels``): the noise figure, the allocation and its rate, and
the loop that uses them share one estimator (the halves' ``(a - b)^2 / 4``) and one model (a
pixel's variance ``v N^-2a``). Split apart, the loop's predictions and the figure it checks
them against could drift from each other, so they stay where one reading shows both.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance weights of linear RGB."""

NOISE_TARGET = 0.02
"""Relative noise of a converged preview (the issue's 2 %)."""

DENOISE_ABOVE = 0.5
"""A preview is denoised where its raw noise is above this fraction of its target: below, there
is nothing a viewer could see for the denoiser to remove."""
DENOISE_FLOOR = 0.02
"""Nor where its raw noise is within this (the default goal, under which noise is not seen): on
textured reliefs the denoiser's own error never came under 1.1 %, and on every example that
reached a 2 % goal its image was the worse one (1.1-3.1 % against 1.0-1.9 % raw, 2026-12-06);
trying it cost a CAD part's preview about a second."""

Denoiser = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``(colour, albedo, normal) -> colour``: float32 ``(h, w, 3)`` linear RGB in and out."""


def luminance(image: np.ndarray) -> np.ndarray:
    """Linear-RGB images ``(..., 3)`` to luminance ``(...)``."""
    return np.asarray(image, dtype=np.float64) @ LUMINANCE


def relative_noise(half_a: np.ndarray, half_b: np.ndarray, mask: np.ndarray) -> float:
    """RMS standard error of the mean of two independent halves, relative to its mean (module doc).

    Parameters
    ----------
    half_a, half_b : (h, w, 3) or (h, w) arrays
        Two renders of the same scene with equal sample counts and independent seeds
        (RGB is reduced to luminance).
    mask : (h, w) bool array
        The object's pixels.

    Returns
    -------
    float; ``inf`` when the object's mean is not positive, 0 for an empty mask.
    """
    a, b = _lum(half_a)[mask], _lum(half_b)[mask]
    if a.size == 0:
        return 0.0
    mean = float(np.mean(0.5 * (a + b)))
    if not mean > 0.0:
        return math.inf
    return math.sqrt(float(np.mean((a - b) ** 2)) / 4.0) / mean


def denoised_error(
    denoised_a: np.ndarray, denoised_b: np.ndarray, half_a: np.ndarray, half_b: np.ndarray, mask: np.ndarray
) -> float:
    """Cross-validated RMS error of ``(denoised_a + denoised_b) / 2`` against the converged image,
    relative to the mean (module doc): each denoised half is compared with the *other* raw half."""
    return 0.5 * (
        _one_half_error(denoised_a, half_a, half_b, mask) + _one_half_error(denoised_b, half_b, half_a, mask)
    )


def _one_half_error(denoised: np.ndarray, half: np.ndarray, other: np.ndarray, mask: np.ndarray) -> float:
    """One denoised half's share of :func:`denoised_error`: against the other raw half, whose own
    noise (half the halves' mean squared difference) is taken off, relative to the mean."""
    a, b, d = _lum(half)[mask], _lum(other)[mask], _lum(denoised)[mask]
    if a.size == 0:
        return 0.0
    mean = float(np.mean(0.5 * (a + b)))
    if not mean > 0.0:
        return math.inf
    var_half = float(np.mean((a - b) ** 2)) / 2.0
    return math.sqrt(max(float(np.mean((d - b) ** 2)) - var_half, 0.0)) / mean


def _lum(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image, dtype=np.float64)
    return image @ LUMINANCE if image.ndim == 3 else image


def object_crop(mask: np.ndarray, margin: int = 16) -> tuple[slice, slice]:
    """The rows and columns of the object's bounding box, ``margin`` pixels wider (the denoiser's window)."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return slice(0, 0), slice(0, 0)
    h, w = mask.shape
    return (
        slice(max(int(rows[0]) - margin, 0), min(int(rows[-1]) + margin + 1, h)),
        slice(max(int(cols[0]) - margin, 0), min(int(cols[-1]) + margin + 1, w)),
    )


@dataclass(frozen=True)
class ConvergenceSettings:
    """What a converged preview is, and what it may cost.

    ``target``: the raw (un-denoised) relative noise of a converged preview;
    ``first_spp``: samples per half of the first passes (a power of two); ``max_spp``: the
    sample budget, both halves together; ``time_cap_s``: seconds of rendering after which no
    more samples are added (see the module doc for how this stays reproducible);
    ``adaptive``: samples where the noise is (else every object pixel gets the same, by the same
    predictions: the comparison ``printapp bench sampling`` makes).
    """

    target: float = NOISE_TARGET
    first_spp: int = 4
    max_spp: int = 4096
    time_cap_s: float = 60.0
    adaptive: bool = True

    def __post_init__(self) -> None:
        # Every count the loop asks for is a whole number of first passes (allocate_samples' step).
        if self.first_spp < 1 or self.first_spp & (self.first_spp - 1):
            raise ValueError(f"first_spp: expected a power of two, got {self.first_spp}")


@dataclass
class Converged:
    """A preview rendered to its noise goal (or to its budget), and the record of how."""

    image: np.ndarray
    """The preview delivered: denoised when :attr:`denoised`, else the raw mean of the halves."""
    raw: np.ndarray
    noise: float
    """Raw (un-denoised) relative noise, :func:`relative_noise`."""
    denoised: bool
    denoised_error: float | None
    target: float
    spp: int
    """Samples per pixel, both halves, averaged over the object's pixels (:attr:`samples` has each)."""
    passes: int
    stopped: str
    """``"noise target"``, ``"sample budget"`` or ``"time cap"``."""
    seconds: float
    budget_spp: int
    timing_dependent: bool
    """True when the time cap set the sample budget (then the image may differ on another machine)."""
    history: list[tuple[int, float]] = field(default_factory=list)
    denoiser: str | None = None
    time_cap_s: float = 0.0
    samples: np.ndarray | None = None
    """Samples each pixel took, both halves together, ``(h, w)``: more where the noise is."""
    spp_range: tuple[int, int] = (0, 0)
    """The fewest and the most samples an object pixel took."""
    light_paths: int = 0
    """Light paths traced for the part of the image the camera's samples leave out (both halves)."""

    @property
    def converged(self) -> bool:
        """The raw (un-denoised) noise is within the target: the denoiser never decides this."""
        return self.noise <= self.target


PREDICTION_MARGIN = 1.1
"""Samples predicted for the goal are this many times what the measured rate says."""
MAX_LEAP = 8
"""A round adds at most this many times the samples already taken: the rate is then measured
again before the prediction reaches far."""
LIGHT_SHARE = 0.15
"""With a light-traced part (``converge(caustics=...)``), the share of the goal's variance it is
given; the camera's samples get the rest. On ``part_relief`` the cheapest split gave it about a
tenth (its paths are some 75 times cheaper per unit of variance, and the camera's part is the
larger); more is given because adaptive sampling makes the camera's part cheaper than uniform."""
LIGHT_PATHS_PER_SAMPLE = 16
"""The light-traced part's budget, per half: this many paths for each sample the camera may take
(``max_spp`` over the object's pixels). The previews take about a quarter of a path per sample;
without a budget a goal out of reach doubled the light paths round after round (a design asking
0.1 % in 32 samples traced on for minutes, past its time cap of 2 s)."""


def round_rate(before: tuple[np.ndarray, np.ndarray], after: tuple[np.ndarray, np.ndarray]) -> float:
    """The exponent ``a`` in a pixel's noise ~ spp^-a, read from one round with its reallocation set apart.

    ``before`` and ``after`` are ``(samples, variances)`` of the measured pixels at the start and
    the end of the round: each pixel's samples per half and its variance estimate (its halves'
    ``(a - b)^2 / 4``). ``a`` is the exponent at which the variances before, each scaled by
    ``(N_before / N_after)^(2a)``, sum to the variances measured after.

    Independent samples give 1/2; a stratified sampler does better within a pass (up to 3/4
    on a pixel's edges, Mitchell 1996), which a prediction at 1/2 turns into too many samples
    (``fitted_marble``'s preview: 1.68 % at 1,024 samples for a 2 % goal). For a uniform round
    this is the noise figure's own rate. An adaptive round's noise also falls because its samples
    went to the noisy pixels; the noise figure's rate counted that as a steeper fall and the next
    round then took too few samples (``part_relief``: 0.66 from 16 to 129 samples, and the next
    round ended at 2.07 % for a 2 % goal), where this counts only what each pixel's own samples
    did. Taken only from a round that at least quadrupled the samples (from closer rounds the
    noise of the estimates swamps it), and kept within [1/2, 3/4]; otherwise 1/2, the safe side.
    """
    (have_before, var_before), (have_after, var_after) = before, after
    var_before = np.asarray(var_before, dtype=np.float64)
    total_after = float(np.sum(var_after))
    grew = np.sum(have_after) >= 4 * np.sum(have_before)
    if not (grew and total_after > 0.0 and np.all(np.isfinite(var_before))):
        return 0.5
    n_before = np.asarray(have_before, dtype=np.float64)
    log_ratio = np.log(np.minimum(n_before / np.maximum(np.asarray(have_after, dtype=np.float64), 1.0), 1.0))

    def predicted(rate: float) -> float:
        return float(np.sum(var_before * np.exp(2.0 * rate * log_ratio)))

    lo, hi = 0.5, 0.75
    if predicted(lo) <= total_after:
        return lo
    if predicted(hi) >= total_after:
        return hi
    for _ in range(40):  # the predicted sum falls as the rate grows
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if predicted(mid) > total_after else (lo, mid)
    return 0.5 * (lo + hi)


def _pow2_floor(n: float) -> int:
    return 1 << max(0, math.floor(math.log2(max(n, 1.0))))


def _half_octave_floor(n: float) -> int:
    """``n`` rounded down to 1, 2, 3, 4, 6, 8, 12, 16, 24...: steps of at most 1.5 times.

    The time cap's budget is rounded so, not to a power of two: a machine a few per cent faster
    or slower still takes the same budget, and no more than a third of what fits is thrown away
    (a power of two threw away up to half: 60 s fitting 900 samples a pixel bought 512)."""
    low = _pow2_floor(n)
    return low * 3 // 2 if low >= 2 and low * 3 // 2 <= n else low


SMOOTHING_RADIUS_PX = 2
"""A pixel's variance is read from its (2r + 1)^2 neighbourhood: one pixel's two halves give
one degree of freedom, too few to steer its samples by."""
VARIANCE_FLOOR = 0.05
"""No pixel's variance is taken below this fraction of the mean: a rare path not yet found in a
pixel would otherwise starve it of the samples that find it."""


Trials = Callable[..., tuple[Callable[[float], tuple[np.ndarray, int]], Callable[[float], bool]]]
"""Makes the bisection's two trials from ``(unit_variance, weight, have, ceiling, measured, goal,
rate, step)``: the counts at a multiplier (and the samples they add), and whether they reach the goal."""


def allocate_samples(
    unit_variance: np.ndarray,
    have: np.ndarray,
    measured: np.ndarray,
    goal: float,
    rate: float,
    *,
    step: int,
    cap: int,
    lanes: int | None = None,
    trials: Trials | None = None,
) -> np.ndarray:
    """Samples per pixel (per half) that reach a noise goal for the fewest samples in all.

    A pixel with ``N`` samples is predicted to have variance ``unit_variance * N^(-2 rate)``;
    the counts minimising ``sum N`` under ``mean_measured(variance) <= goal`` are (Lagrange)
    ``N_i = lambda * unit_variance_i^(1 / (1 + 2 rate))``, kept between what the pixel has and
    ``cap`` and rounded up to whole ``step``s, the total at most :data:`MAX_LEAP` times what the
    pixels have; ``lambda`` is found by bisection. With ``lanes``, no more than that many samples
    are added (the time cap).

    Parameters
    ----------
    unit_variance : (n,) array
        Each pixel's variance at one sample (in luminance^2).
    have : (n,) int array
        Samples each pixel has, per half.
    measured : (n,) bool array
        The pixels in the noise figure (the object's; its border is sampled but not measured).
    goal : float
        The mean variance over ``measured`` to reach.
    rate : float
        Noise ~ spp^-rate (:func:`round_rate`).
    trials : Trials, optional
        How the bisection's trials are computed: by default numba kernels; the plain numpy
        ones they are checked against are ``printapp.bench.reference.allocate_plain``'s.

    Returns
    -------
    (n,) int array: the samples per half each pixel should have, at least ``have``.
    """
    have = np.asarray(have, dtype=np.int64)
    if have.size == 0:
        return have
    ceiling = np.maximum(cap, have)
    leap = (MAX_LEAP - 1) * int(np.sum(have))
    most = leap if lanes is None else min(lanes, leap)  # samples this round may add
    unit_variance = np.asarray(unit_variance, dtype=np.float64)
    weight = unit_variance ** (1.0 / (1.0 + 2.0 * rate))
    if trials is None:
        from render._allocation_kernels import kernel_trials as trials
    count, reaches = trials(unit_variance, weight, have, ceiling, measured, goal, rate, step)

    def fits(lam: float) -> bool:
        return count(lam)[1] <= most

    def bisect(good: Callable[[float], bool], lo: float, hi: float, smallest: bool) -> float:
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if good(mid) == smallest:
                hi = mid
            else:
                lo = mid
        return hi if smallest else lo

    top = float(np.max(ceiling / np.maximum(weight, 1e-300)))
    lam = bisect(reaches, 0.0, top, smallest=True) if reaches(top) else top
    if not fits(lam):  # the lane budget binds before the goal: spend what fits
        lam = bisect(fits, 0.0, lam, smallest=False)
    return count(lam)[0].copy()


def _unit_variance(
    a: np.ndarray, b: np.ndarray, have: np.ndarray, active: np.ndarray, measured: np.ndarray, rate: float
) -> np.ndarray:
    """Each active pixel's variance at one sample, smoothed over its active neighbours and floored
    (:data:`SMOOTHING_RADIUS_PX`, :data:`VARIANCE_FLOOR`), scaled so that its prediction at the
    current counts is what the halves measure over the ``measured`` pixels (those of the noise
    figure: scaled over every active pixel, the smoothing could carry the object's variance
    onto its unmeasured border, and a prediction that the goal was met kept a measured 2.03 %
    above a 2 % goal, round after round)."""
    from scipy.ndimage import uniform_filter

    h, w = a.shape[:2]
    diff = (_lum(a) - _lum(b)).reshape(-1)[active]
    now = diff**2 / 4.0  # the preview pixel's variance, one degree of freedom
    unit = now * have.astype(np.float64) ** (2.0 * rate)
    field_ = np.zeros(h * w)
    inside = np.zeros(h * w)
    field_[active] = unit
    inside[active] = 1.0
    size = 2 * SMOOTHING_RADIUS_PX + 1
    total = uniform_filter(field_.reshape(h, w), size, mode="constant").reshape(-1)[active]
    count = uniform_filter(inside.reshape(h, w), size, mode="constant").reshape(-1)[active]
    smooth = total / np.maximum(count, 1e-12)
    mean = float(np.mean(smooth))
    if not mean > 0.0:
        return np.full(active.size, 1.0)
    smooth = np.maximum(smooth, VARIANCE_FLOOR * mean)
    which = measured if np.any(measured) else np.ones(active.size, dtype=bool)
    predicted = float(np.sum(smooth[which] * have[which].astype(np.float64) ** (-2.0 * rate)))
    return smooth * (float(np.sum(now[which])) / predicted if predicted > 0.0 else 1.0)


def converge(
    render: Callable[[int, int, np.ndarray | None], np.ndarray],
    mask: np.ndarray,
    *,
    seed: int,
    settings: ConvergenceSettings | None = None,
    denoiser: Denoiser | None = None,
    guides: tuple[np.ndarray, np.ndarray] | None = None,
    denoiser_name: str | None = None,
    clock: Callable[[], float] = time.perf_counter,
    caustics: Callable[[int, int], np.ndarray] | None = None,
) -> Converged:
    """Render in passes until the object's pixels reach the noise goal, or the budget is spent.

    Parameters
    ----------
    render : callable ``(spp, seed, pixels) -> array``
        The mean of ``spp`` (a power of four) samples per pixel with that seed, ``(h, w, 3)``
        for ``pixels=None``, else ``(len(pixels), 3)`` for those flat pixel indices only;
        calls with different seeds must be independent.
    mask : (h, w) bool array
        The object's pixels, where the noise is measured. After the first passes only they
        (and a 2-pixel border) get more samples: the background is a constant sky.
    seed : int
        The preview's seed; pass ``k`` of half ``A`` (``B``) uses a seed derived from it and
        ``2k`` (``2k + 1``).
    denoiser : callable, optional
        With it (and ``guides``, the albedo and normal images), each half is denoised once the
        passes stop, where the raw noise is above ``DENOISE_ABOVE`` times the target and above
        ``DENOISE_FLOOR``, and the denoised preview is delivered where its cross-validated
        error is below the raw noise.
    caustics : callable ``(n_paths, seed) -> array``, optional
        A part of the image that ``render`` leaves out, estimated apart (by light tracing,
        :mod:`render.caustics`): the mean of ``n_paths`` paths with that seed, ``(h, w, 3)``,
        independent for different seeds. Each half gets its own and the noise figure is taken
        on the sums; the paths are added round by round so that this part's variance stays
        within :data:`LIGHT_SHARE` of the goal, and the camera's samples aim at the rest.
    """
    s = settings or ConvergenceSettings()
    if not (s.first_spp >= 1 and s.first_spp & (s.first_spp - 1) == 0):
        raise ValueError(f"first_spp: expected a power of two, got {s.first_spp}")
    from render.progressive import passes_of

    start = clock()
    passes = 0
    h, w = mask.shape
    active = np.flatnonzero(_dilate(mask, 2))
    measured = mask.reshape(-1)[active]

    def first_round(n_add: int, which: int) -> np.ndarray:
        nonlocal passes
        total = None
        for count in passes_of(n_add):
            image = np.asarray(render(count, _pass_seed(seed, passes, which), None), dtype=np.float64)
            total = image * count if total is None else total + image * count
            passes += 1
        assert total is not None
        return total / n_add

    def add(old: np.ndarray, have: np.ndarray, want: np.ndarray, which: int) -> np.ndarray:
        """More samples for the active pixels, ``want - have`` each, in passes of powers of four.

        One pass per power: a pixel that needs ``k`` blocks of that power is listed ``k`` times
        (each listing a different randomisation of the sampler), so a round takes a handful of
        calls however the counts vary from pixel to pixel."""
        nonlocal passes
        out = old.copy()
        flat = out.reshape(-1, 3)
        acc = flat[active] * have[:, None]
        rest = (want - have).astype(np.int64)
        power = 1
        while power * 4 <= int(rest.max(initial=0)):
            power *= 4
        while power >= 1:
            blocks = rest // power
            if blocks.any():
                listed = np.repeat(np.arange(active.size), blocks)
                values = np.asarray(
                    render(power, _pass_seed(seed, passes, which), active[listed]), dtype=np.float64
                )
                np.add.at(acc, listed, power * values)  # in listing order: deterministic
                rest -= blocks * power
                passes += 1
            power //= 4
        flat[active] = acc / np.maximum(want, 1)[:, None]
        return out

    # The light-traced part: each half's mean image, its paths (per half), and its calls.
    light = {"a": np.zeros((h, w, 3)), "b": np.zeros((h, w, 3)), "paths": 0, "passes": 0}

    def add_light(n_add: int) -> None:
        if caustics is None or n_add <= 0:
            return
        total = light["paths"] + n_add
        for which, key in ((0, "a"), (1, "b")):
            image = np.asarray(caustics(n_add, _pass_seed(seed, 1_000_000 + light["passes"], which)))
            light[key] = (light[key] * light["paths"] + image.reshape(h, w, 3) * n_add) / total
        light["paths"] = total
        light["passes"] += 1

    def light_variance() -> float:
        """The light-traced part's variance of the mean of halves, over the object's pixels."""
        if caustics is None or not mask.any():
            return 0.0
        return float(np.mean((_lum(light["a"]) - _lum(light["b"]))[mask] ** 2)) / 4.0

    def light_wanted(goal: float) -> int:
        """Paths per half that bring the light-traced part within its share of ``goal``."""
        v = light_variance()
        if caustics is None or not goal > 0.0 or v <= LIGHT_SHARE * goal:
            return light["paths"]
        want = math.ceil(light["paths"] * v / (LIGHT_SHARE * goal))
        return min(want, MAX_LEAP * light["paths"], max(light_cap, light["paths"]))

    def total_noise() -> float:
        if caustics is None:
            return relative_noise(a, b, mask)
        return relative_noise(a + light["a"], b + light["b"], mask)

    def mean_spp(have: np.ndarray) -> int:
        if measured.any():
            return int(round(2.0 * float(np.mean(have[measured]))))
        return 2 * int(have.max(initial=s.first_spp))  # (no object in view: what every pixel took)

    # Round one: every pixel (the background is rendered once); round two doubles the object's
    # samples and times them, warm (round one also compiles Dr.Jit's kernels).
    n = s.first_spp
    a = first_round(n, 0)
    b = first_round(n, 1)
    # A quarter as many light paths as the camera's samples, to measure their variance by; later
    # rounds add what the goal needs (a loose goal needs few).
    add_light(max(int(mask.sum()) * n // 4, 1))
    have = np.full(active.size, n, dtype=np.int64)
    history = [(2 * n, total_noise())]

    def pixel_variance() -> np.ndarray:
        """The camera's part alone, each measured pixel's variance: the rate is read from it."""
        diff = (_lum(a) - _lum(b)).reshape(-1)[active][measured]
        return diff**2 / 4.0

    rounds = [(have[measured], pixel_variance())]
    cap = max(_pow2_floor(s.max_spp / 2), n)
    light_cap = LIGHT_PATHS_PER_SAMPLE * cap * max(int(mask.sum()), 1)
    budget = cap  # mean samples per pixel, per half
    lanes_left: int | None = None
    limit = "sample budget"

    def fit_budget(per_lane: float) -> None:
        """The mean samples per pixel that fit in the time cap at ``per_lane`` seconds a sample,
        rounded down to a half octave (a machine a little faster or slower takes the same)."""
        nonlocal budget, lanes_left, limit
        if not per_lane > 0.0:
            return
        spent = float(np.mean(have))
        more = max(s.time_cap_s - (clock() - start), 0.0) / (2 * per_lane * active.size)
        affordable = _half_octave_floor(spent + more)
        if affordable < cap:
            budget, limit = max(affordable, n), "time cap"
            lanes_left = max(int(budget * active.size - np.sum(have)), 0)
        else:  # (a second, better estimate may find that everything fits after all)
            budget, limit, lanes_left = cap, "sample budget", None

    if history[-1][1] > s.target and 2 * n <= cap:
        warm = clock()
        doubled = have * 2
        a = add(a, have, doubled, 0)
        b = add(b, have, doubled, 1)
        have = doubled
        per_lane = (clock() - warm) / (2 * n * max(active.size, 1))  # both halves
        n *= 2
        history.append((mean_spp(have), total_noise()))
        rounds.append((have[measured], pixel_variance()))
        fit_budget(per_lane)
    stopped = limit
    truncated = False  # whether the clock's budget cut a round short of what the image asked for
    while True:
        noise = history[-1][1]
        if noise <= s.target:
            stopped = "noise target"
            break
        rate = round_rate(rounds[-2], rounds[-1]) if len(rounds) > 1 else 0.5
        lum = 0.5 * (_lum(a + light["a"]) + _lum(b + light["b"]))
        goal = (s.target / PREDICTION_MARGIN * float(np.mean(lum[mask]))) ** 2
        light_want = light_wanted(goal)
        whole_goal = goal
        if light["paths"] > 0:
            # The camera's samples aim at what the light-traced part leaves of the goal.
            goal -= light_variance() * light["paths"] / light_want
        if math.isfinite(noise) and goal > 0.0:
            unit = _unit_variance(a, b, have, active, measured, rate)
            if not s.adaptive:  # every pixel alike: the mean variance, the same counts
                unit = np.full_like(unit, float(np.mean(unit[measured])) if measured.any() else 1.0)
            want = allocate_samples(
                unit, have, measured, goal, rate, step=s.first_spp, cap=cap, lanes=lanes_left
            )
            if lanes_left is not None:
                free = allocate_samples(unit, have, measured, goal, rate, step=s.first_spp, cap=cap)
                truncated |= not np.array_equal(want, free)
        else:
            want = np.minimum(2 * have, np.maximum(cap, have))
            if lanes_left is not None and int(np.sum(want - have)) > lanes_left:
                want = have
        added = int(np.sum(want - have))
        light_added = light_want - light["paths"]
        light_matters = light_variance() > 0.01 * whole_goal
        if (
            added == 0
            and light_added == 0
            and caustics is not None
            and light_matters
            and 2 * light["paths"] <= light_cap
        ):
            # Each part's prediction meets its share but their measured sum does not (a few
            # hundred pixels measure the parts loosely): halve the light-traced part's variance,
            # which also leaves the camera's part more of the goal next round. (Not once it is a
            # hundredth of the goal: then it cannot be what keeps the sum above it.)
            light_added = light["paths"]
        # The light-traced part keeps to the time cap too (the camera's samples keep to it by
        # their budget, fixed from the rounds' timing).
        over_time = light_added > 0 and clock() - start >= s.time_cap_s
        if over_time:
            light_added, truncated = 0, True
        if added == 0 and light_added == 0:
            if over_time:
                stopped = "time cap"
            elif lanes_left is not None and lanes_left >= active.size * s.first_spp:
                stopped = "sample budget"  # every pixel at max_spp before the clock ran out
            break
        began = clock()
        a = add(a, have, want, 0)
        b = add(b, have, want, 1)
        add_light(light_added)
        have = want
        if lanes_left is not None:
            # The second round is small, so each pass's fixed cost weighs on its timing (on
            # part_relief it foretold 512 samples a pixel where 880 fitted): every later, larger
            # round fixes the budget again from its own time a sample.
            fit_budget((clock() - began) / (2 * max(added, 1)))
        history.append((mean_spp(have), total_noise()))
        rounds.append((have[measured], pixel_variance()))
        stopped = limit
    a, b = a + light["a"], b + light["b"]
    raw = 0.5 * (a + b)
    noise = history[-1][1]
    image, error = raw, None
    if denoiser is not None and guides is not None and noise > max(DENOISE_ABOVE * s.target, DENOISE_FLOOR):
        den_a = _denoise_half(denoiser, guides, a, mask)
        error = _one_half_error(den_a, a, b, mask)
        # The second half only where the first says the denoiser may win: where one denoised half
        # is already further from the converged image than the raw preview, their mean (whose
        # estimate averages the two halves') is not trusted either, and a 1024 x 768 half costs
        # a quarter of a second (the demo's glinting tile: 7.7 % against 7.1 % raw).
        if error < noise:
            den_b = _denoise_half(denoiser, guides, b, mask)
            error = denoised_error(den_a, den_b, a, b, mask)
            if error < noise:  # never deliver an image worse than the raw one
                image = 0.5 * (den_a + den_b)
    samples = np.full(h * w, 2 * s.first_spp, dtype=np.int64)
    samples[active] = 2 * have
    samples = samples.reshape(h, w)
    object_samples = samples[mask] if mask.any() else samples.reshape(-1)
    return Converged(
        image=image.astype(np.float32),
        raw=raw.astype(np.float32),
        noise=noise,
        denoised=image is not raw,
        denoised_error=error,
        target=s.target,
        spp=mean_spp(have),
        passes=passes,
        stopped=stopped,
        seconds=clock() - start,
        budget_spp=2 * budget,
        timing_dependent=truncated or (limit == "time cap" and stopped != "noise target"),
        history=history,
        denoiser=denoiser_name if image is not raw else None,
        time_cap_s=s.time_cap_s,
        samples=samples,
        spp_range=(int(object_samples.min()), int(object_samples.max())),
        light_paths=2 * int(light["paths"]),
    )


def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    out = np.array(mask, dtype=bool, copy=True)
    for axis in (0, 1):
        grown = out.copy()
        for shift in range(1, radius + 1):
            grown |= np.roll(out, shift, axis=axis) | np.roll(out, -shift, axis=axis)
        out = grown
    return out


def _pass_seed(seed: int, k: int, which: int) -> int:
    x = (int(seed) * 0x9E3779B97F4A7C15 + (2 * k + which + 1) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    x ^= x >> 31
    return int(x & 0xFFFFFFFF)


def _denoise_half(
    denoiser: Denoiser, guides: tuple[np.ndarray, np.ndarray], half: np.ndarray, mask: np.ndarray
) -> np.ndarray:
    """A half denoised in the object's bounding box (the background, a constant sky, is left as it is)."""
    rows, cols = object_crop(mask)
    albedo, normal = guides
    full = np.array(half, dtype=np.float64, copy=True)
    if rows.stop > rows.start and cols.stop > cols.start:
        window = (rows, cols)
        full[window] = denoiser(
            np.ascontiguousarray(half[window], dtype=np.float32),
            np.ascontiguousarray(albedo[window], dtype=np.float32),
            np.ascontiguousarray(normal[window], dtype=np.float32),
        )
    return full
