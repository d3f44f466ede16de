"""Where does numba's compilation time go? Every compilation in one run, timed.

    NUMBA_CACHE_DIR=$(mktemp -d) .venv/bin/python scripts/compile-profile.py [--top N] [SCRIPT]

Runs :func:`printapp.warmup.warm_up` (or, given ``SCRIPT``, that Python file) with a
listener on numba's ``numba:compile`` events, and prints each jitted function's compilation
time, exclusive of the functions it compiled on the way (its callees that are dispatchers of
their own, numba's overloads among them) and inclusive of them, largest first; then, for the
heaviest of numba's own overloads, which of our kernels made it compile. Set
``NUMBA_CACHE_DIR`` to an empty folder: with a warm cache nothing compiles.

What it found (docs/benchmarks.md, "commands", thirteenth run): 3-D array expressions, slice
assignments and ``np.linalg`` in a kernel each compile numba's shape checks, error messages or
LAPACK wrappers, seconds apiece; an IR-inlined helper is typed once per call site.
"""

from __future__ import annotations

import argparse
import runpy
import time
from typing import Any

from numba.core import event


class _Timings(event.Listener):
    """Inclusive and exclusive seconds per dispatcher, and who compiled numba's overloads."""

    def __init__(self) -> None:
        self.stack: list[list[Any]] = []
        self.inclusive: dict[str, float] = {}
        self.exclusive: dict[str, float] = {}
        self.callers: dict[str, dict[str, float]] = {}

    @staticmethod
    def _name(dispatcher: Any) -> str:
        f = dispatcher.py_func
        return f"{f.__module__}.{f.__qualname__}"

    def on_start(self, ev: event.Event) -> None:
        self.stack.append([self._name(ev.data["dispatcher"]), time.perf_counter(), 0.0])

    def on_end(self, ev: event.Event) -> None:
        name, start, nested = self.stack.pop()
        seconds = time.perf_counter() - start
        self.inclusive[name] = self.inclusive.get(name, 0.0) + seconds
        self.exclusive[name] = self.exclusive.get(name, 0.0) + seconds - nested
        if self.stack:
            parent = self.stack[-1]
            parent[2] += seconds
            by = self.callers.setdefault(name, {})
            by[parent[0]] = by.get(parent[0], 0.0) + seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("script", nargs="?", help="a Python file to run instead of the warm-up")
    parser.add_argument("--top", type=int, default=40, help="how many functions to list")
    args = parser.parse_args()
    timings = _Timings()
    event.register("numba:compile", timings)
    start = time.perf_counter()
    if args.script:
        runpy.run_path(args.script, run_name="__main__")
    else:
        from printapp.warmup import warm_up

        warm_up(quiet=True)
    wall = time.perf_counter() - start
    print(f"run {wall:.1f} s, of which compiling {sum(timings.exclusive.values()):.1f} s")
    print(f"{'exclusive s':>12} {'inclusive s':>12}  function")
    ranked = sorted(timings.exclusive, key=lambda k: -timings.exclusive[k])
    for name in ranked[: args.top]:
        print(f"{timings.exclusive[name]:12.2f} {timings.inclusive[name]:12.2f}  {name}")
    print("\nnumba's own overloads, by the kernels that compiled them (inclusive s):")
    ours = sorted((k for k in timings.callers if k.startswith("numba.")), key=lambda k: -timings.inclusive[k])
    for name in ours[:10]:
        by = sorted(timings.callers[name].items(), key=lambda kv: -kv[1])[:3]
        print(f"{timings.inclusive[name]:6.2f}  {name}  <- " + ", ".join(f"{k} {v:.2f}" for k, v in by))


if __name__ == "__main__":
    main()
