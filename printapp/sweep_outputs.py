"""The files of a sweep: its table as CSV and Parquet, its timings, and a chart per varied key."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

CHART_METRICS = ("gloss_20", "gloss_60", "gloss_85", "haze", "anisotropy", "highlight_azimuth_deg")
"""Metrics charted against each varied key: the traced value where there is one, else the surrogate's."""


def parquet_bytes(rows: list[dict[str, Any]]) -> bytes:
    """The rows as a Parquet table (pyarrow; no timestamps, so the same rows give the same bytes)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns = list(dict.fromkeys(k for row in rows for k in row))
    arrays = {}
    for column in columns:
        values = [row.get(column) for row in rows]
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {int, float} and kinds != {int} and kinds:
            values = [None if v is None else float(v) for v in values]
        elif len(kinds) > 1:
            values = [None if v is None else str(v) for v in values]
        arrays[column] = pa.array(values)
    buffer = io.BytesIO()
    pq.write_table(pa.table(arrays), buffer, compression="zstd")
    return buffer.getvalue()


def chart_png(rows: list[dict[str, Any]], key: str, keys: list[str]) -> bytes:
    """Each metric against ``key``, one panel per metric: the traced value (dots, solid) and the
    surrogate's (crosses, dashed), one line per combination of the other varied keys (a grid),
    or the points alone (a Latin hypercube, where no two share the other keys)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    others = [k for k in keys if k != key]
    groups: dict[tuple[str, ...], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault(tuple(f"{k.rsplit('.', 1)[-1]}={row.get(k)}" for k in others), []).append(row)
    joined = max(len(g) for g in groups.values()) > 1
    metrics = [m for m in CHART_METRICS if any(m in r or f"surrogate_{m}" in r for r in rows)]
    cols = (len(metrics) + 1) // 2
    fig, axes = plt.subplots(2, cols, figsize=(3.4 * cols, 5.8), dpi=100, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    numeric = all(isinstance(r.get(key), (int, float)) and not isinstance(r.get(key), bool) for r in rows)
    for ax, metric in zip(axes.ravel(), metrics, strict=False):
        for g, (label, members) in enumerate(groups.items()):
            members = sorted(members, key=lambda r: r[key] if numeric else str(r[key]))
            xs = [r[key] if numeric else str(r[key]) for r in members]
            colour = colours[g % len(colours)] if joined else colours[0]
            for column, style in ((metric, "o-"), (f"surrogate_{metric}", "x--")):
                if not all(column in r for r in members):
                    continue
                ys = [r[column] for r in members]
                named = ", ".join(label) if joined and label else None
                ax.plot(
                    xs,
                    ys,
                    style if joined else style[0],
                    color=colour,
                    ms=4,
                    lw=0.8,
                    alpha=0.85,
                    label=named if column == metric or metric == "anisotropy" else None,
                )
        ax.set_xlabel(key, fontsize=8)
        ax.set_ylabel(metric if metric != "anisotropy" else "anisotropy (slopes)", fontsize=8)
        ax.tick_params(labelsize=7)
        if joined and len(groups) <= 8 and any(label for label in groups):
            ax.legend(fontsize=6)
    for ax in axes.ravel()[len(metrics) :]:
        ax.axis("off")
    fig.suptitle(f"metrics against {key}: traced (o, solid) and surrogate (x, dashed)", fontsize=9)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def write_sweep_outputs(
    out_dir: Path, rows: list[dict[str, Any]], timings: list[dict[str, Any]], keys: list[str]
) -> list[Path]:
    """Write ``results.csv``, ``results.parquet``, ``timings.csv`` and ``chart_KEY.png`` into ``out_dir``."""
    from printapp.outputs import atomic_write_files

    out_dir.mkdir(parents=True, exist_ok=True)
    files = [
        (out_dir / "results.csv", csv_bytes(rows)),
        (out_dir / "results.parquet", parquet_bytes(rows)),
        (out_dir / "timings.csv", csv_bytes(timings)),
    ]
    files += [(out_dir / f"chart_{key.replace('.', '_')}.png", chart_png(rows, key, keys)) for key in keys]
    return atomic_write_files(files)


def csv_bytes(rows: list[dict[str, Any]]) -> bytes:
    """Rows as CSV (columns in first-seen order, floats as Python writes them exactly)."""
    columns = list(dict.fromkeys(k for row in rows for k in row))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: row.get(k, "") for k in columns})
    return buffer.getvalue().encode("utf-8")
