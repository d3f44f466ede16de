"""``printapp solve --reachable``: what a printer, layer height and resin reach within ``[solve]``'s bounds.

A Latin hypercube (seeded by ``[solve] seed``) over the free parameters of ``[solve]`` is
evaluated on the surrogate through the engine (:mod:`printapp.engine`), and every
``len / TRACED`` -th design also traced, to show the surrogate's gap. The chart puts 60-degree
gloss against haze and the slopes' anisotropy against 60-degree gloss; the table
(``reachable.csv``) lists every design's parameters and predictions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from printapp.design import Design

TRACED = 12
"""Designs of the sample also traced (evenly spread over it), for the surrogate's gap."""


@dataclass
class Reachable:
    """The sampled designs (one row each), the summary line and the files written."""

    rows: list[dict[str, Any]]
    summary: str
    written: list[Path]


def sample_params(space: Any, points: int, seed: int) -> list[dict[str, Any]]:
    """``points`` parameter sets of a Latin hypercube over the space's free parameters."""
    from scipy.stats import qmc

    names = list(space.distributions)
    unit = qmc.LatinHypercube(d=len(names), seed=seed).random(points)
    out = []
    for row in unit:
        params: dict[str, Any] = {}
        for u, name in zip(row, names, strict=True):
            dist = space.distributions[name]
            if hasattr(dist, "choices"):
                params[name] = dist.choices[min(int(u * len(dist.choices)), len(dist.choices) - 1)]
            elif getattr(dist, "log", False):
                params[name] = round(math.exp(math.log(dist.low) + u * math.log(dist.high / dist.low)), 6)
            elif isinstance(dist.low, int) and isinstance(dist.high, int) and not isinstance(dist.low, bool):
                params[name] = min(dist.high, dist.low + int(u * (dist.high - dist.low + 1)))
            else:
                params[name] = round(dist.low + u * (dist.high - dist.low), 6)
        out.append(params)
    return out


def reachable_set(design: Design, engine: Any, points: int) -> list[dict[str, Any]]:
    """The sampled designs' parameters, surrogate predictions and (for every few) traced values."""
    from printapp.design_io import resolved_toml
    from printapp.engine import Job
    from printapp.solve import Space

    space = Space(design)
    assert design.solve is not None
    params = sample_params(space, points, design.solve.seed)
    designs = [space.candidate(p) for p in params]
    surrogate = engine.run([Job(resolved_toml(d), "surrogate") for d in designs])
    step = max(1, points // TRACED)
    chosen = list(range(0, points, step))[:TRACED]
    traced = dict(
        zip(chosen, engine.run([Job(resolved_toml(designs[i]), "brdf") for i in chosen]), strict=True)
    )
    rows = []
    for i, (p, o) in enumerate(zip(params, surrogate, strict=True)):
        row: dict[str, Any] = {"index": i, **p, **o.result["metrics"]}
        if i in traced:
            row.update(
                {k: v for k, v in traced[i].result["metrics"].items() if not k.startswith("surrogate_")}
            )
        row["printable"] = not any(
            "printer" in r or "layer" in r or "cures" in r for r in o.result["reasons"]
        )
        rows.append(row)
    return rows


def chart_png(rows: list[dict[str, Any]], title: str) -> bytes:
    """60-degree gloss against haze (colour: anisotropy) and anisotropy against 60-degree gloss."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    ok = [r for r in rows if "surrogate_gloss_60" in r]
    g60 = [r["surrogate_gloss_60"] for r in ok]
    haze = [r["surrogate_haze"] for r in ok]
    aniso = [max(1.0, min(r["surrogate_anisotropy"], 100.0)) for r in ok]
    grey = [bool(r.get("grey_levels", False)) for r in ok]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.6), dpi=100)
    norm = LogNorm(vmin=1.0, vmax=max(2.0, max(aniso)))
    for flag, marker, label in ((False, "o", "coverage (anti-aliased) exposure"), (True, "s", "grey levels")):
        idx = [i for i, g in enumerate(grey) if g == flag]
        if not idx:
            continue
        xs, ys, cs = [haze[i] for i in idx], [g60[i] for i in idx], [aniso[i] for i in idx]
        sc = a.scatter(xs, ys, c=cs, cmap="viridis", norm=norm, marker=marker, s=18, alpha=0.85, label=label)
        b.scatter([g60[i] for i in idx], [aniso[i] for i in idx], marker=marker, s=18, alpha=0.6, label=label)
    traced = [r for r in ok if r.get("gloss_60") is not None]
    xs, ys = [r["gloss_60"] - r["gloss_20"] for r in traced], [r["gloss_60"] for r in traced]
    a.scatter(xs, ys, facecolors="none", edgecolors="red", s=60, label="traced (same designs)")
    for r in traced:
        a.plot(
            [r["surrogate_haze"], r["gloss_60"] - r["gloss_20"]],
            [r["surrogate_gloss_60"], r["gloss_60"]],
            color="red",
            lw=0.6,
        )
    a.set_xlabel("G60 - G20 (GU): ASTM D4039 haze where G60 > 70")
    a.set_ylabel("60-degree gloss (GU)")
    a.legend(fontsize=7, loc="lower right")
    fig.colorbar(sc, ax=a, label="anisotropy (slopes)")
    b.set_yscale("log")
    b.set_xlabel("60-degree gloss (GU)")
    b.set_ylabel("anisotropy (ratio of principal roughnesses)")
    b.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def reachable_file(
    path: Path,
    out_dir: Path,
    *,
    points: int = 192,
    workers: int = 2,
    scheduler: str | None = None,
    progress: Any = None,
) -> Reachable:
    """``printapp solve --reachable``: sample, chart and tabulate (see the module) into ``out_dir``."""
    import statistics

    from printapp.design_io import load_design
    from printapp.engine import Engine
    from printapp.errors import DesignError
    from printapp.outputs import atomic_write_files
    from printapp.relief import cure_model
    from printapp.solve import Space
    from printapp.sweep_outputs import csv_bytes, parquet_bytes

    design = load_design(path)
    if design.solve is None:
        raise DesignError(f"{path}: no [solve] table; expected one naming the parameters to sample")
    Space(design)
    if out_dir.exists() and not out_dir.is_dir():
        raise DesignError(f"{out_dir}: output folder is a file, expected a folder")
    with Engine(out_dir / "cache", workers=workers, scheduler=scheduler, progress=progress) as engine:
        rows = reachable_set(design, engine, points)
    profile = design.printer.profile
    cure = cure_model(design)
    material = design.material.name or f"index {design.material.refractive_index:g}"
    where = (
        f"{profile.label} at {design.layer_height_mm:g} mm layers, {material}, "
        f"{'working-curve' if cure.kind != 'linear' else 'linear'} cure"
    )
    ok = [r for r in rows if "surrogate_gloss_60" in r]
    if not ok:
        raise DesignError(f"{path}: no sampled design could be built (over the memory budget?)")
    g60 = [r["surrogate_gloss_60"] for r in ok]
    haze = [r["surrogate_haze"] for r in ok]
    aniso = [r["surrogate_anisotropy"] for r in ok]
    gaps = [abs(r["gloss_60"] - r["surrogate_gloss_60"]) for r in ok if "gloss_60" in r]
    summary = (
        f"reachable on the {where}: 60-degree gloss {min(g60):.1f} to {max(g60):.1f} GU, "
        f"haze {min(haze):.1f} to {max(haze):.1f}, anisotropy {min(aniso):.2f} to {max(aniso):.2f} "
        f"over {len(ok)} designs ({len(gaps)} traced: surrogate within {statistics.median(gaps):.1f} GU "
        f"of the tracer at 60 degrees, median; at most {max(gaps):.1f})"
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    written = atomic_write_files(
        [
            (out_dir / "reachable.csv", csv_bytes(rows)),
            (out_dir / "reachable.parquet", parquet_bytes(rows)),
            (out_dir / "reachable.png", chart_png(rows, f"reachable set: {where}")),
        ]
    )
    return Reachable(rows, summary, written)
