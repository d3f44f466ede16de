"""``printapp bench pipeline``: the demo design end to end, median seconds per stage."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from printapp.bench.timing import StageResult


def bench_pipeline(repeats: int) -> StageResult:
    """The demo design end to end: median seconds per stage."""
    from printapp.design_io import load_default_design
    from printapp.pipeline import run_design

    design = load_default_design()
    per_stage: dict[str, list[float]] = {}
    totals = []
    with tempfile.TemporaryDirectory() as tmp:
        run_design(design, Path(tmp) / "warm", quiet=True)
        for i in range(min(repeats, 3)):
            start = time.perf_counter()
            outcome = run_design(design, Path(tmp) / f"run{i}", quiet=True)
            totals.append(time.perf_counter() - start)
            for stage, seconds in outcome.manifest["stages_s"].items():
                per_stage.setdefault(stage, []).append(seconds)
    rows = [{"stage": s, "median_s": round(statistics.median(v), 4)} for s, v in per_stage.items()]
    rows.append({"stage": "total", "median_s": round(statistics.median(totals), 4)})

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3), dpi=110)
        ax.barh([r["stage"] for r in rows], [r["median_s"] for r in rows])
        ax.set_xlabel("median seconds")
        ax.set_title("printapp demo, per stage (warm)")
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "pipeline", "the demo design end to end, warm (numba caches and imports loaded)", rows, chart
    )
