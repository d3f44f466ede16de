"""The sample allocation of progressive rendering with its trials in plain numpy: the reference that
``render.convergence.allocate_samples``'s kernels are checked against (they were the production
code before the bisection's trials went through numba; the counts must come out the same, bit for
bit). The bisection itself is the production one (``render.convergence.allocate_samples``).
"""

import numpy as np

from render.convergence import allocate_samples


def _numpy_trials(unit_variance, weight, have, ceiling, measured, goal, rate, step):
    def count(lam):
        raw = np.clip(lam * weight, have, ceiling)
        n = np.minimum(-(-np.ceil(raw).astype(np.int64) // step) * step, ceiling)
        return n, int(np.sum(n - have))

    def reaches(lam):
        n, _ = count(lam)
        return (
            float(np.mean(unit_variance[measured] * n[measured].astype(np.float64) ** (-2.0 * rate))) <= goal
        )

    return count, reaches


def allocate_plain(unit_variance, have, measured, goal, rate, *, step, cap, lanes=None):
    """:func:`render.convergence.allocate_samples` with the plain numpy trials: the same result."""
    return allocate_samples(
        unit_variance, have, measured, goal, rate, step=step, cap=cap, lanes=lanes, trials=_numpy_trials
    )
