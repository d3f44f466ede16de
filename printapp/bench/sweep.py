"""``printapp bench sweep``: the speed-up of a 16-point sweep against workers, and Dask's cost per point.

The sweep is the demo's tile at 8 amplitudes, with and without grey levels, to ``--until brdf``
(the surrogate and the traced glossmeter). Three contenders evaluate the same 16 designs,
timed in turn within each repeat (no cache): a plain loop in this process with numba on one
thread, a LocalCluster of one worker and one of two (one thread each). Each cluster is
started once and warmed by a first sweep; the timed sweeps run on warm workers, and the
start-up is reported apart. The goal (issue #17) is a speed-up of at least 1.7 with two
workers on 2 cores.

Dask's overhead per point is measured apart, where it is not lost in the noise of seconds-long
points on a shared machine: 64 tiny designs (2 mm tiles to the surrogate, tens of milliseconds
each) on the plain loop and on the one-worker cluster, interleaved; the difference of the
medians over the points.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

from printapp.bench.timing import StageResult

POINTS = 16


def _jobs() -> list[Any]:
    from printapp.design_io import load_default_design, resolved_toml
    from printapp.engine import Job
    from printapp.sweep import design_raw, parse_vary, variant_values, with_values

    design = load_default_design()
    raw = design_raw(design)
    varies = [parse_vary("relief.amplitude_um=100:380:8"), parse_vary("relief.grey_levels=false,true")]
    points = variant_values(varies)
    assert len(points) == POINTS
    return [Job(resolved_toml(with_values(raw, p, "bench")), "brdf") for p in points]


def _tiny_jobs() -> list[Any]:
    """64 designs whose evaluation is tens of milliseconds: what is left is the engine's cost."""
    from printapp.design import design_from_dict
    from printapp.design_io import resolved_toml
    from printapp.engine import Job

    return [
        Job(resolved_toml(design_from_dict({"base": {"width_mm": 2.0, "depth_mm": 2.0, "thickness_mm": 1.0},
                                            "texture": {"feature_size_mm": 0.5, "seed": k}})), "surrogate")
        for k in range(64)
    ]  # fmt: skip


def bench_sweep(repeats: int) -> StageResult:
    """Sweep 16 designs on a plain loop, 1 and 2 Dask workers: medians, speed-up, overhead per point."""
    import numba

    from printapp.engine import Engine
    from printapp.evaluate import evaluate_resolved

    jobs = _jobs()
    threads = numba.get_num_threads()

    def plain() -> list[dict[str, Any]]:
        numba.set_num_threads(1)
        try:
            return [evaluate_resolved(j.resolved, j.level) for j in jobs]
        finally:
            numba.set_num_threads(threads)

    engines = {n: Engine(None, workers=n) for n in (1, 2)}
    startup = {}
    try:
        for n, engine in engines.items():
            start = time.perf_counter()
            engine.run(jobs[:n])  # starts the cluster, loads the kernels in every worker
            startup[n] = time.perf_counter() - start
        plain()
        times: dict[str, list[float]] = {"plain loop": [], "1 worker": [], "2 workers": []}
        results: dict[str, list[dict[str, Any]]] = {}
        for _ in range(max(1, repeats)):
            for label, run in (
                ("plain loop", plain),
                ("1 worker", lambda: [o.result for o in engines[1].run(jobs)]),
                ("2 workers", lambda: [o.result for o in engines[2].run(jobs)]),
            ):
                start = time.perf_counter()
                results[label] = run()
                times[label].append(time.perf_counter() - start)
    finally:
        for engine in engines.values():
            engine.close()
        tiny = _tiny_jobs()
        tiny_times: dict[str, list[float]] = {"plain loop": [], "1 worker": []}
        for _ in range(max(3, repeats)):
            numba.set_num_threads(1)
            start = time.perf_counter()
            plain_tiny = [evaluate_resolved(j.resolved, j.level) for j in tiny]
            tiny_times["plain loop"].append(time.perf_counter() - start)
            numba.set_num_threads(threads)
            start = time.perf_counter()
            dask_tiny = [o.result for o in engines[1].run(tiny)]
            tiny_times["1 worker"].append(time.perf_counter() - start)
        same_tiny = [r["metrics"] for r in plain_tiny] == [r["metrics"] for r in dask_tiny]
    medians = {k: statistics.median(v) for k, v in times.items()}
    same = all(
        [r["metrics"] for r in results[k]] == [r["metrics"] for r in results["plain loop"]] for k in results
    )
    tiny_medians = {k: statistics.median(v) for k, v in tiny_times.items()}
    overhead = (tiny_medians["1 worker"] - tiny_medians["plain loop"]) / len(tiny)
    same = same and same_tiny
    rows = [
        {
            "contender": label,
            "median_s": round(medians[label], 2),
            "runs_s": [round(t, 2) for t in times[label]],
            "per_point_s": round(medians[label] / POINTS, 3),
            "speed_up_vs_1_worker": round(medians["1 worker"] / medians[label], 2),
            "cluster_start_s": None if label == "plain loop" else round(startup[int(label[0])], 1),
        }
        for label in times
    ]

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.6), dpi=110)
        labels = list(times)
        for i, label in enumerate(labels):
            ax.scatter([i] * len(times[label]), times[label], color="grey", s=12)
        ax.bar(labels, [medians[k] for k in labels], alpha=0.6)
        ax.set_ylabel(f"seconds for {POINTS} points (median)")
        ax.set_title(
            f"sweep --until brdf: 2 workers {medians['1 worker'] / medians['2 workers']:.2f}x one; "
            f"Dask {overhead * 1000:.0f} ms/point"
        )
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "sweep",
        f"{POINTS}-point sweep (demo tile, 8 amplitudes x grey levels, --until brdf): "
        "plain loop, 1 and 2 workers",
        rows,
        chart,
        [
            f"speed-up with 2 workers: {medians['1 worker'] / medians['2 workers']:.2f}x "
            "(goal >= 1.7 on 2 cores)",
            f"Dask's overhead per point (64 tiny designs, 1 worker less the plain loop: "
            f"{tiny_medians['1 worker']:.2f} s against {tiny_medians['plain loop']:.2f} s): "
            f"{overhead * 1000:.0f} ms",
            f"every contender gave the same metrics: {same}",
        ],
        {"same_metrics": same, "overhead_per_point_s": round(overhead, 4)},
    )
