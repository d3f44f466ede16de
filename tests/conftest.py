"""Scheduling for `pytest -n auto` (pytest-xdist with ``--dist loadgroup``, as the Makefile runs it).

Tests that share an expensive module fixture stay on one worker (an ``xdist_group`` each), so
the fixture runs once; and the heavy tests (marked ``slow``) are handed out first, so that no
worker is left with a long test while the other has finished.

Each of ``n`` workers gets ``cores / n`` threads for numba's and Dr.Jit's pools (the command
lines the tests start inherit numba's): with every worker's pools as wide as the machine, two
workers ran four busy threads on two cores (on 2026-12-04's quiet machine the suite took
5:03 with 9:03 of user time; with numba's pools narrowed 4:48 and 8:38; with both, 4:37 and
8:24). Results do not depend on the thread count (the determinism tests run both).
"""

import os
import sys

import pytest

WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
THREADS = max(1, len(os.sched_getaffinity(0)) // WORKERS) if WORKERS > 1 else None
if THREADS is not None:
    # Read once, when numba is first imported: that is after this file in a worker.
    os.environ.setdefault("NUMBA_NUM_THREADS", str(THREADS))

_drjit_narrowed = False


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """Narrow Dr.Jit's pool once it is loaded (importing it here, before Mitsuba's variant is
    chosen with the libLLVM it finds, could start it without that library)."""
    global _drjit_narrowed
    dr = sys.modules.get("drjit")
    if THREADS is not None and not _drjit_narrowed and dr is not None:
        dr.set_thread_count(THREADS)
        _drjit_narrowed = True


SHARED_FIXTURES = ("demo_runs", "vein_fits", "marble_fits", "cylinder_reliefs", "brushed", "passed")
"""Module fixtures of more than a second or two (see ``--durations``)."""


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        for name in SHARED_FIXTURES:
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(name))
                break
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
