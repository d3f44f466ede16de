"""``printapp sweep``: variants of a design on a grid or a Latin hypercube, evaluated on Dask.

Each ``--vary KEY=START:STOP:N`` (N values from START to STOP) or ``KEY=A,B,C`` (a list)
names a design key as a file writes it (``relief.amplitude_um``, ``texture.kind``); the
variants are every combination (a grid) or ``--lhs N`` points of a Latin hypercube over
the ranges (seeded). Each variant is validated as a design (a value out of range is one
sentence naming ``--vary KEY``), resolved, and evaluated by :class:`printapp.engine.Engine`
as far as ``--until`` says (:data:`printapp.evaluate.LEVELS`; ``design`` writes each
variant's outputs into ``points/NNNN/``).

The folder holds ``results.csv`` and ``results.parquet`` (one row per variant, in variant
order: its index, the varied values, the metrics, the verdict and the design's hash; no
timings, so the table is the same bytes for 1, 2 or N workers and for a resumed sweep),
``timings.csv`` (seconds per variant, whether it came from the cache, which worker), a
chart of each metric against each varied key (``chart_KEY.png``), and ``cache/``, from
which an interrupted sweep resumes.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from itertools import product
from pathlib import Path
from typing import Any

from printapp.design import Design, design_from_dict
from printapp.design_io import resolved_toml, to_file_units
from printapp.errors import DesignError, PrintappError

_UNIT_SUFFIXES = (("_um", "_mm", "_cm"), ("_deg", "_rad"))


@dataclass(frozen=True)
class Vary:
    """One varied key: its dotted name as a file writes it, and its values (a range or a list)."""

    key: str
    values: tuple[Any, ...]
    start: float | None = None
    stop: float | None = None

    @property
    def numeric(self) -> bool:
        return self.start is not None


def _scalar(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()  # a bare word such as fbm


def parse_vary(text: str) -> Vary:
    """``KEY=START:STOP:N`` or ``KEY=A,B,C``; else a :class:`PrintappError` naming ``--vary``."""
    key, sep, spec = text.partition("=")
    key = key.strip()
    if not sep or not key or not spec.strip() or key.count(".") < 1:
        raise PrintappError(
            f"--vary: expected KEY=START:STOP:N or KEY=A,B,C with a dotted design key such as "
            f"relief.amplitude_um, got {text!r}"
        )
    if ":" in spec:
        parts = spec.split(":")
        try:
            start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
        except (ValueError, IndexError):
            raise PrintappError(
                f"--vary {key}: expected START:STOP:N (two numbers and a count), got {spec!r}"
            ) from None
        if len(parts) != 3 or not (math.isfinite(start) and math.isfinite(stop)) or not 1 <= n <= 10_000:
            raise PrintappError(f"--vary {key}: expected START:STOP:N with finite ends and 1 <= N <= 10000")
        values = [start + (stop - start) * i / (n - 1) if n > 1 else start for i in range(n)]
        # Integers when the ends are written as integers and every step lands on one.
        if all(p.strip().lstrip("+-").isdigit() for p in parts[:2]) and all(v == round(v) for v in values):
            values = [round(v) for v in values]
        return Vary(key, tuple(dict.fromkeys(values)), start, stop)
    values = [_scalar(v) for v in spec.split(",") if v.strip()]
    if not values:
        raise PrintappError(f"--vary {key}: expected at least one value")
    return Vary(key, tuple(values))


def design_raw(design: Design) -> dict[str, Any]:
    """The design's own settings (not its defaults) as a file would write them, paths resolved."""
    return to_file_units(design.model_dump(mode="python", exclude_unset=True))


def with_values(raw: dict[str, Any], values: dict[str, Any], source: str) -> Design:
    """The design ``raw`` with each dotted ``KEY`` set to its value, validated.

    A key with a unit suffix replaces the same key in other units (``relief.amplitude_um``
    replaces ``relief.amplitude_mm``). Raises a :class:`DesignError` naming the key.
    """
    data = {k: (dict(v) if isinstance(v, dict) else v) for k, v in raw.items()}
    for dotted, value in values.items():
        *path, leaf = dotted.split(".")
        table = data
        for part in path:
            inner = table.get(part, {})
            if not isinstance(inner, dict):
                raise DesignError(f"{source}: --vary {dotted}: '{part}' is not a table of the design")
            table[part] = dict(inner)
            table = table[part]
        for group in _UNIT_SUFFIXES:
            suffix = next((s for s in group if leaf.endswith(s)), None)
            if suffix is not None:
                for other in group:
                    table.pop(leaf[: -len(suffix)] + other, None)
        table[leaf] = value
    try:
        return design_from_dict(data, source)
    except DesignError as exc:
        keys = ", ".join(f"--vary {k}" for k in values)
        raise DesignError(f"{exc} (from {keys})") from None


def variant_values(varies: list[Vary], lhs: int | None = None, seed: int = 0) -> list[dict[str, Any]]:
    """Every combination of the varied values (a grid), or ``lhs`` points of a Latin hypercube."""
    if lhs is None:
        return [
            dict(zip([v.key for v in varies], combo, strict=True))
            for combo in product(*(v.values for v in varies))
        ]
    from scipy.stats import qmc

    if not 1 <= lhs <= 100_000:
        raise PrintappError(f"--lhs: expected 1 to 100000 points, got {lhs}")
    unit = qmc.LatinHypercube(d=len(varies), seed=seed).random(lhs)
    points = []
    for row in unit:
        point = {}
        for u, vary in zip(row, varies, strict=True):
            if vary.numeric:
                value = vary.start + (vary.stop - vary.start) * float(u)
                point[vary.key] = (
                    round(value) if all(isinstance(v, int) for v in vary.values) else round(value, 9)
                )
            else:
                point[vary.key] = vary.values[min(int(u * len(vary.values)), len(vary.values) - 1)]
        points.append(point)
    return points


@dataclass
class SweepResult:
    """What a sweep computed: one row per variant, and where it wrote."""

    rows: list[dict[str, Any]]
    timings: list[dict[str, Any]]
    written: list[Path]
    hits: int
    computed: int
    where: str
    seconds: float


def run_sweep(
    design: Design,
    varies: list[Vary],
    out_dir: Path,
    *,
    until: str = "design",
    lhs: int | None = None,
    seed: int = 0,
    workers: int = 2,
    scheduler: str | None = None,
    source: str = "design",
    progress: Any = None,
) -> SweepResult:
    """Evaluate the variants (see the module) and write the table, timings and charts into ``out_dir``."""
    import time

    from printapp.engine import Engine, Job
    from printapp.evaluate import LEVELS
    from printapp.sweep_outputs import write_sweep_outputs

    if until not in LEVELS:
        raise PrintappError(f"--until: expected one of {', '.join(LEVELS)}, got {until!r}")
    if not varies:
        raise PrintappError("--vary: expected at least one KEY=START:STOP:N")
    if len({v.key for v in varies}) != len(varies):
        raise PrintappError("--vary: each key may be varied once")
    raw = design_raw(design)
    points = variant_values(varies, lhs, seed)
    if len(points) > 100_000:
        raise PrintappError(f"--vary: {len(points)} variants; expected at most 100000")
    designs = [with_values(raw, point, source) for point in points]
    if out_dir.exists() and not out_dir.is_dir():
        raise PrintappError(f"{out_dir}: output folder is a file, expected a folder")
    jobs = [
        Job(resolved_toml(d), until, str(out_dir / "points" / f"{i:04d}") if until == "design" else None)
        for i, d in enumerate(designs)
    ]
    start = time.perf_counter()
    with Engine(out_dir / "cache", workers=workers, scheduler=scheduler, progress=progress) as engine:
        outcomes = engine.run(jobs)
        where = engine.where
    seconds = time.perf_counter() - start
    rows, timings = [], []
    for i, (point, job, outcome) in enumerate(zip(points, jobs, outcomes, strict=True)):
        result = outcome.result
        rows.append(
            {
                "index": i,
                **point,
                **result["metrics"],
                "verdict": result["verdict"],
                "reasons": "; ".join(result["reasons"]),
                "design_hash": job.key,
            }
        )
        timings.append(
            {
                "index": i,
                "cached": outcome.cached,
                "seconds": round(outcome.seconds, 3),
                **{f"{k}_s": v for k, v in result.get("seconds", {}).items()},
                "worker": outcome.worker,
            }
        )
    written = write_sweep_outputs(out_dir, rows, timings, [v.key for v in varies])
    return SweepResult(rows, timings, written, engine.hits, engine.computed, where, seconds)


def sweep_file(
    path: Path,
    vary: list[str],
    out_dir: Path,
    *,
    until: str = "design",
    lhs: int | None = None,
    seed: int = 0,
    workers: int = 2,
    scheduler: str | None = None,
    progress: Any = None,
) -> SweepResult:
    """``printapp sweep``: load the design, parse each ``--vary``, run the sweep (:func:`run_sweep`)."""
    from printapp.design_io import load_design

    if workers < 0:
        raise PrintappError(f"--workers: expected 0 (here, no Dask) or more, got {workers}")
    design = load_design(path)
    varies = [parse_vary(text) for text in vary]
    return run_sweep(
        design,
        varies,
        out_dir,
        until=until,
        lhs=lhs,
        seed=seed,
        workers=workers,
        scheduler=scheduler,
        source=str(path),
        progress=progress,
    )
