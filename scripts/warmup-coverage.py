"""Which numba specialisations does a run compile that ``printapp warmup`` did not?

    .venv/bin/python scripts/warmup-coverage.py [--twice] [EXAMPLE ...]

In one process: :func:`printapp.warmup.warm_up`, then each example (all of ``examples/`` by
default) built as ``printapp design`` builds it, with its preview shrunk to 64 x 48 pixels and
a 5 s cap (the kernels a preview uses do not depend on its size). After each example it lists
every jitted function that gained a type signature, with the signature: each is a compilation
that a user's first run of that example pays (seconds), and a gap in the warm-up or a kernel
whose argument types depend on the data. Exits 1 if there is any.

The kernels load from the cache, so a run costs what the examples do (about 3 minutes for all
fifteen on 2 cores). With ``--twice`` each example is built a second time and both times are
printed: with ``NUMBA_CACHE_DIR`` set to an empty folder, the first run's excess over the
second is what a user's first run pays after ``make``. To compare with an older commit, run
this script with that commit's checkout first on ``PYTHONPATH``.
"""

from __future__ import annotations

import gc
import sys
import tempfile
import time
from pathlib import Path

from numba.core.dispatcher import Dispatcher

ROOT = Path(__file__).resolve().parents[1]


def signatures() -> dict[str, set[str]]:
    """Every live numba dispatcher's compiled signatures, by module and name."""
    found: dict[str, set[str]] = {}
    for obj in gc.get_objects():
        if isinstance(obj, Dispatcher):
            name = f"{obj.py_func.__module__}.{obj.py_func.__qualname__}"
            found.setdefault(name, set()).update(str(sig) for sig in obj.signatures)
    return found


def main(args: list[str]) -> int:
    from printapp.design_io import load_design
    from printapp.pipeline import run_design
    from printapp.warmup import warm_up

    twice = "--twice" in args
    names = [a for a in args if a != "--twice"]
    names = names or sorted(p.stem for p in (ROOT / "examples").glob("*.toml"))
    began = time.perf_counter()
    warm_up(quiet=True)
    print(f"warm-up: {time.perf_counter() - began:.1f} s", flush=True)
    before = signatures()
    gaps = 0
    for name in names:
        design = load_design(ROOT / "examples" / f"{name}.toml")
        small = design.render.model_copy(update={"width_px": 64, "height_px": 48, "time_cap_s": 5.0})
        small_design = design.model_copy(update={"render": small})
        seconds = []
        for _ in range(2 if twice else 1):
            with tempfile.TemporaryDirectory() as folder:
                began = time.perf_counter()
                run_design(small_design, Path(folder) / "out", quiet=True, force=True)
                seconds.append(time.perf_counter() - began)
        if twice:
            print(f"{name}: first run {seconds[0]:.1f} s, second {seconds[1]:.1f} s", flush=True)
        after = signatures()
        new = {k: sorted(v - before.get(k, set())) for k, v in after.items() if v - before.get(k, set())}
        for kernel, sigs in sorted(new.items()):
            for sig in sigs:
                print(f"{name}: {kernel} {sig}")
        print(f"{name}: {len(new)} kernels compiled past the warm-up", flush=True)
        gaps += len(new)
        before = after
    return 1 if gaps else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
