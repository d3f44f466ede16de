"""``printapp bench solve``: time and evaluations for ``printapp solve`` to meet each example's targets.

Each example with a ``[solve]`` table is solved from scratch (no cache) on a LocalCluster of
two workers, ``repeats`` times (at most 3: a solve takes up to a minute or two); the table gives
the median time of the search and confirmation (not the ``printapp design`` run of the result),
the evaluations on the surrogate and by the tracer, the rounds, and the traced value beside each
target with the surrogate's gap. The goal (issue #17) is under two minutes on 2 cores.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from printapp.bench.timing import StageResult

EXAMPLES = ("matte_tile", "satin_tile", "brushed_target")
GOAL_S = 120.0


def _example(name: str) -> Path:
    """An example design, from the checkout beside the package (the examples are not package data)."""
    from importlib.resources import files

    root = Path(str(files("printapp"))).parent
    return root / "examples" / f"{name}.toml"


def bench_solve(repeats: int) -> StageResult:
    """Solve each example's targets from scratch: median time, evaluations, achieved values."""
    from printapp.design_io import load_design
    from printapp.engine import Engine
    from printapp.solve import solve_design

    rows = []
    missing = []
    runs = max(1, min(repeats, 3))
    for name in EXAMPLES:
        path = _example(name)
        if not path.exists():
            missing.append(name)
            continue
        design = load_design(path)
        seconds = []
        outcome = None
        for _ in range(runs):
            with Engine(None, workers=2) as engine:
                start = time.perf_counter()
                outcome = solve_design(design, engine)
                seconds.append(time.perf_counter() - start)
        assert outcome is not None
        rows.append(
            {
                "example": name,
                "met": outcome.met,
                "median_s": round(statistics.median(seconds), 1),
                "runs_s": [round(s, 1) for s in seconds],
                "surrogate_evaluations": outcome.evaluations,
                "traced": outcome.traced,
                "rounds": outcome.rounds,
                "targets": {k: list(v) for k, v in outcome.targets.items()},
                "achieved": outcome.achieved,
                "gap": outcome.gaps,
                "params": outcome.params,
            }
        )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.6), dpi=110)
        names = [r["example"] for r in rows]
        ax.bar(names, [r["median_s"] for r in rows], color="tab:blue")
        for i, r in enumerate(rows):
            ax.annotate(
                f"{r['surrogate_evaluations']} + {r['traced']} traced",
                (i, r["median_s"]),
                ha="center",
                va="bottom",
                fontsize=8,
            )
        ax.axhline(GOAL_S, color="grey", ls=":", label="goal: 2 min")
        ax.set_ylabel("median time to meet the targets (s)")
        ax.set_title("printapp solve, LocalCluster of 2 workers, no cache")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "solve",
        "time and evaluations for printapp solve to meet each example's targets (2 workers, no cache)",
        rows,
        chart,
        [
            "median_s: the search on the surrogate and the traced confirmation, not the design run after it",
            "achieved: the traced values (what printapp design reports); gap: traced minus surrogate",
            *([f"not found (run from a checkout): {', '.join(missing)}"] if missing else []),
        ],
    )
