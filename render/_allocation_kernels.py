"""The numba kernels of :func:`render.convergence.allocate_samples`' bisection trials.

Apart from the loop they serve, so that ``render.convergence`` (the noise figure, the allocation
and the loop, one piece) imports no numba. Checked against the plain numpy trials of
``printapp.bench.reference.allocate_plain``: the same counts, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit


def kernel_trials(
    unit_variance: np.ndarray,
    weight: np.ndarray,
    have: np.ndarray,
    ceiling: np.ndarray,
    measured: np.ndarray,
    goal: float,
    rate: float,
    step: int,
) -> tuple[Callable[[float], tuple[np.ndarray, int]], Callable[[float], bool]]:
    """The trials through kernels: the counts, then each measured pixel's predicted variance from a
    table of N^(-2 rate) over the multiples of ``step`` (the numbers numpy's power gives), summed
    by np.mean: the plain numpy trials' answers, bit for bit, in a tenth of their 0.75 s a call
    on 170k pixels, spent between render rounds."""
    if not (np.all(have % step == 0) and np.all(ceiling % step == 0)):
        raise ValueError(f"have, cap: expected multiples of step ({step}) samples")
    picked = np.flatnonzero(measured)
    unit_measured = unit_variance[picked]
    powers = (np.arange(int(ceiling.max()) // step + 1, dtype=np.int64) * step).astype(np.float64)
    with np.errstate(divide="ignore"):  # (N = 0 never occurs: every pixel has samples)
        powers **= -2.0 * rate
    trial = np.empty(have.size, dtype=np.int64)
    terms = np.empty(picked.size)

    def count(lam: float) -> tuple[np.ndarray, int]:
        return trial, int(_counts(float(lam), weight, have, ceiling, int(step), trial))

    def reaches(lam: float) -> bool:
        count(lam)
        _measured_terms(trial, picked, unit_measured, powers, int(step), terms)
        return float(np.mean(terms)) <= goal

    return count, reaches


@njit(cache=True)
def _counts(lam, weight, have, ceiling, step, out) -> int:
    """``allocate_samples``'s counts at ``lam`` (as the plain numpy version computes them) into
    ``out``; returns the samples they add."""
    added = 0
    for i in range(weight.size):
        raw = min(max(lam * weight[i], float(have[i])), float(ceiling[i]))
        whole = np.int64(math.ceil(raw))
        out[i] = min(-(-whole // step) * step, ceiling[i])
        added += out[i] - have[i]
    return added


@njit(cache=True)
def _measured_terms(n, picked, unit_measured, powers, step, out) -> None:
    for k in range(picked.size):
        out[k] = unit_measured[k] * powers[n[picked[k]] // step]
