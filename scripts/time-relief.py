"""Time the relief of the mesh examples (``printapp.relief.build_relief``), as this checkout builds it.

    PYTHONPATH=TREE .venv/bin/python scripts/time-relief.py TREE

TREE is the checkout whose code and examples are timed (this one, or a worktree of an earlier
commit). Each example's relief is built once (numba loading its kernels), then twice more;
the best of the two is printed. Run it for two trees in turn to compare them.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from printapp.design_io import load_design
from printapp.relief import build_relief

EXAMPLES = ("brushed_part", "part_relief", "brushed_part_fbm", "brushed_cylinder", "tag_with_slot")

root = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
for name in EXAMPLES:
    design = load_design(root / "examples" / f"{name}.toml")
    build_relief(design)
    seconds = []
    for _ in range(2):
        start = time.perf_counter()
        build_relief(design)
        seconds.append(time.perf_counter() - start)
    print(f"{name}: {min(seconds):.2f} s", flush=True)
