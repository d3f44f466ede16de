"""The sample allocation of progressive rendering in plain numpy: the reference that
``render.convergence.allocate_samples`` is checked against (it was the production code before its
bisection's trials went through numba kernels; the counts must come out the same, bit for bit).
"""

from collections.abc import Callable

import numpy as np

from render.convergence import MAX_LEAP


def allocate_plain(
    unit_variance: np.ndarray,
    have: np.ndarray,
    measured: np.ndarray,
    goal: float,
    rate: float,
    *,
    step: int,
    cap: int,
    lanes: int | None = None,
) -> np.ndarray:
    """:func:`render.convergence.allocate_samples` as written in numpy: the same arguments and result."""
    have = np.asarray(have, dtype=np.int64)
    if have.size == 0:
        return have
    ceiling = np.maximum(cap, have)
    leap = (MAX_LEAP - 1) * int(np.sum(have))
    most = leap if lanes is None else min(lanes, leap)  # samples this round may add
    weight = np.asarray(unit_variance, dtype=np.float64) ** (1.0 / (1.0 + 2.0 * rate))

    def counts(lam: float) -> np.ndarray:
        raw = np.clip(lam * weight, have, ceiling)
        return np.minimum(-(-np.ceil(raw).astype(np.int64) // step) * step, ceiling)

    def mean_variance(n: np.ndarray) -> float:
        return float(np.mean(unit_variance[measured] * n[measured].astype(np.float64) ** (-2.0 * rate)))

    def fits(n: np.ndarray) -> bool:
        return int(np.sum(n - have)) <= most

    def bisect(good: Callable[[float], bool], lo: float, hi: float, smallest: bool) -> float:
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if good(mid) == smallest:
                hi = mid
            else:
                lo = mid
        return hi if smallest else lo

    top = float(np.max(ceiling / np.maximum(weight, 1e-300)))
    reaches = lambda lam: mean_variance(counts(lam)) <= goal  # noqa: E731
    lam = bisect(reaches, 0.0, top, smallest=True) if reaches(top) else top
    if not fits(counts(lam)):  # the lane budget binds before the goal: spend what fits
        lam = bisect(lambda x: fits(counts(x)), 0.0, lam, smallest=False)
    return counts(lam)
