"""Work off a design run's critical path, on one background thread.

A design run is a chain (relief, as-printed relief, BRDF, preview, light sweep) whose every
link needs the one before; the solid checks, a mesh's slicing, the model files and the
report's BRDF maps hang off it and are needed only at the end. They run on one background
thread while the main thread goes down the chain: the chain's stages spend much of their
time in code that releases the GIL (Dr.Jit's kernels, numba's, Open Image Denoise,
numpy), so the two share the machine's cores. One thread, first in first out, because the
machine has two cores and the main thread's kernels already use both: more would only
queue, and one keeps the order of the background work fixed.

A task's result is the same whenever it runs: every task is a pure function of what it is
given, so outputs stay byte-identical (the tests run the demo twice and compare).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from types import TracebackType
from typing import Any, TypeVar

T = TypeVar("T")


class Background:
    """One background thread for a run's side work; a context manager.

    Leaving the block cancels the tasks that have not started and waits for the one
    running (each checks for Ctrl-C and SIGTERM at its stage boundaries, through
    :class:`printapp.progress.StageTimer`), so no task outlives the run's output folder.
    """

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="printapp-background")

    def submit(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> Future[T]:
        """Run ``fn(*args, **kwargs)`` after the tasks submitted before it; its result or error
        comes back from ``result()``."""
        return self._pool.submit(fn, *args, **kwargs)

    def __enter__(self) -> Background:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)
