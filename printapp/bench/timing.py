"""What every bench stage shares: its result, and timers built for a shared, noisy machine.

Medians of repeats, never means or minima; contenders timed in turn within each repeat
(:func:`interleaved_seconds`), so that the load of other jobs falls on all of them alike.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class StageResult:
    """Rows of one bench stage, and how to chart them."""

    name: str
    description: str
    rows: list[dict[str, Any]]
    chart: Callable[[Path], None] | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


def median_seconds(fn: Callable[[], object], repeats: int, *, warm: bool = True) -> tuple[float, list[float]]:
    """Median wall time of ``fn`` over ``repeats`` calls, after one untimed warm-up call (unless
    ``warm`` is false: the caller has compiled and warmed what ``fn`` runs already)."""
    if warm:
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), times


def interleaved_seconds(
    fns: dict[str, Callable[[], Any]], repeats: int, warmups: dict[str, Callable[[], Any]] | None = None
) -> tuple[dict[str, float], dict[str, Any], dict[str, float]]:
    """Median wall time of each ``fn``, timed in turn within every repeat.

    Round-robin, so that the load of a shared machine falls on every contender alike.
    Each function is first called once untimed; ``warmups``, when given, replaces those
    calls (cheaper ones, or none). Returns the medians, each function's last result,
    and its process CPU time over wall time (how many cores it kept busy).
    """
    for warm in (fns if warmups is None else warmups).values():
        warm()
    times: dict[str, list[float]] = {k: [] for k in fns}
    cpu: dict[str, float] = dict.fromkeys(fns, 0.0)
    last: dict[str, Any] = {}
    for _ in range(max(1, repeats)):
        for key, fn in fns.items():
            cpu0, start = time.process_time(), time.perf_counter()
            last[key] = fn()
            times[key].append(time.perf_counter() - start)
            cpu[key] += time.process_time() - cpu0
    medians = {k: statistics.median(v) for k, v in times.items()}
    return medians, last, {k: cpu[k] / max(sum(times[k]), 1e-12) for k in fns}
