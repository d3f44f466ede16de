"""``printapp bench slice``: printapp's slicer beside PrusaSlicer 2.5, on the same STL and settings.

Two parts on the Original Prusa SL1 profile (``printapp/bench/peers/sl1_flat.ini``, supports and pad
off): a 40 mm sphere (800 layers) and a closed 20 x 20 mm slab with a 0.5 mm relief from
a 512 x 512 height field (50 layers). Both tools run as commands, start-up included
(``printapp slice`` and ``prusa-slicer --export-sla``), medians over repeats in the same
run; printapp's in-process time is reported too. The layers are compared pixel by pixel:
intersection over union of cured pixels (grey > 127) over all layers and per layer, and
the mean absolute grey difference on edge pixels.
"""

from __future__ import annotations

import io
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.peers import peer_file
from printapp.bench.timing import StageResult
from printapp.errors import PrintappError


def _parts(folder: Path) -> list[tuple[str, Path]]:
    import trimesh

    import noise
    from noise.heightfield import HeightField
    from printapp.exporters import stl_bytes
    from printapp.mesh import slab_from_heightfield

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=20.0)
    sphere.apply_translation([0.0, 0.0, 20.0])
    (folder / "sphere40.stl").write_bytes(stl_bytes(sphere.vertices, sphere.faces))
    axis = np.linspace(0.0, 4.0, 512)
    relief = noise.fbm_grid(axis, axis, octaves=3, seed=1)
    relief = (relief - relief.min()) / (relief.max() - relief.min()) * 0.5
    slab = slab_from_heightfield(HeightField(relief, 20.0 / 511, 20.0 / 511), 2.0)
    (folder / "slab20.stl").write_bytes(stl_bytes(slab.vertices, slab.faces))
    return [
        ("40 mm sphere", folder / "sphere40.stl"),
        ("20 x 20 mm slab, 512^2 relief", folder / "slab20.stl"),
    ]


def _timed(command: list[str], repeats: int) -> tuple[float, list[float]]:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, timeout=600)
        times.append(time.perf_counter() - start)
    return statistics.median(times), times


def _compare(ours: list[np.ndarray], theirs: list[np.ndarray]) -> dict[str, float]:
    inter = union = 0
    per_layer = []
    edge_diff = []
    for a, b in zip(ours, theirs, strict=False):
        a, b = a.astype(np.int16), b.astype(np.int16)
        i = int(((a > 127) & (b > 127)).sum())
        u = int(((a > 127) | (b > 127)).sum())
        inter += i
        union += u
        if u:
            per_layer.append(i / u)
        edge = ((a > 0) & (a < 255)) | ((b > 0) & (b < 255))
        if edge.any():
            edge_diff.append(float(np.abs(a - b)[edge].mean()))
    return {
        "iou_all": round(inter / max(union, 1), 5),
        "iou_min_layer": round(min(per_layer), 5) if per_layer else None,
        "edge_grey_mad": round(float(np.mean(edge_diff)), 2) if edge_diff else None,
    }


def bench_slice(repeats: int) -> StageResult:
    """``printapp slice`` beside PrusaSlicer on a sphere and a relief slab: time and layer agreement."""
    from printapp.mesh import load_closed_mesh
    from slicing import PRINTERS, read_sl1, slice_mesh, write_sl1

    prusa = shutil.which("prusa-slicer")
    reps = max(1, min(repeats, 3))
    rows: list[dict[str, Any]] = []
    sweep: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp, peer_file("sl1_flat.ini") as peer_ini:
        folder = Path(tmp)
        for name, stl in _parts(folder):
            ours_path = folder / f"{stl.stem}_printapp.sl1"
            ours_s, _ = _timed(
                [sys.executable, "-m", "printapp", "slice", str(stl), "-o", str(ours_path)], reps
            )
            mesh = load_closed_mesh(stl)

            def in_process(antialias: bool, mesh=mesh) -> float:
                start = time.perf_counter()
                write_sl1(
                    io.BytesIO(),
                    slice_mesh(mesh.vertices, mesh.faces, PRINTERS["prusa-sl1"], antialias=antialias),
                    "x",
                )
                return time.perf_counter() - start

            in_process(True)
            inproc_s = statistics.median(in_process(True) for _ in range(reps))
            with open(ours_path, "rb") as stream:
                _, ours = read_sl1(stream)
            row: dict[str, Any] = {
                "part": name,
                "layers": len(ours),
                "printapp_cmd_s": round(ours_s, 3),
                "printapp_inprocess_s": round(inproc_s, 3),
                "printapp_layers_per_s": round(len(ours) / inproc_s, 1),
            }
            if prusa is not None:
                peer_path = folder / f"{stl.stem}_prusa.sl1"
                command = [
                    prusa, "--datadir", str(folder / "datadir"), "--loglevel", "1", "--load", str(peer_ini),
                    "--export-sla", "-o", str(peer_path), str(stl),
                ]  # fmt: skip
                peer_s, _ = _timed(command, reps)
                with open(peer_path, "rb") as stream:
                    _, theirs = read_sl1(stream)
                row.update(
                    {
                        "prusaslicer_cmd_s": round(peer_s, 3),
                        "prusaslicer_layers": len(theirs),
                        "speedup_cmd": round(peer_s / ours_s, 2),
                        "speedup_inprocess": round(peer_s / inproc_s, 2),
                        **_compare(ours, theirs),
                    }
                )
                # anti-aliasing quality against time: exact coverage vs pure black and white
                for antialias in (True, False):
                    seconds = statistics.median(in_process(antialias) for _ in range(reps))
                    buffer = io.BytesIO()
                    write_sl1(
                        buffer,
                        slice_mesh(mesh.vertices, mesh.faces, PRINTERS["prusa-sl1"], antialias=antialias),
                        "x",
                    )
                    buffer.seek(0)
                    _, layers = read_sl1(buffer)
                    sweep.append(
                        {
                            "part": name,
                            "method": "exact area coverage" if antialias else "no anti-aliasing",
                            "seconds": round(seconds, 3),
                            **_compare(layers, theirs),
                        }
                    )
                sweep.append(
                    {"part": name, "method": "PrusaSlicer 2.5 (command)", "seconds": round(peer_s, 3)}
                )
            rows.append(row)

    if not rows:
        raise PrintappError("bench slice produced no rows")

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(12, 4), dpi=110)
        x = np.arange(len(rows))
        axes[0].bar(x - 0.2, [r["printapp_inprocess_s"] for r in rows], 0.2, label="printapp (in process)")
        axes[0].bar(x, [r["printapp_cmd_s"] for r in rows], 0.2, label="printapp slice (command)")
        if prusa is not None:
            axes[0].bar(
                x + 0.2, [r["prusaslicer_cmd_s"] for r in rows], 0.2, label="PrusaSlicer 2.5 (command)"
            )
        axes[0].set_xticks(x, [r["part"] for r in rows], fontsize=8)
        axes[0].set_ylabel("median seconds")
        axes[0].set_title("slicing to .sl1, Original Prusa SL1")
        axes[0].legend(fontsize=8)
        for r in sweep:
            if "edge_grey_mad" in r and r["edge_grey_mad"] is not None:
                marker = "o" if r["method"].startswith("exact") else "x"
                axes[1].plot(r["seconds"], r["edge_grey_mad"], marker, label=f"{r['part']}: {r['method']}")
        axes[1].set_xlabel("seconds (in process)")
        axes[1].set_ylabel("mean |grey difference| on edge pixels vs PrusaSlicer")
        axes[1].set_yscale("log")
        axes[1].set_title("anti-aliasing against time")
        axes[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    notes = ["times are medians of command runs (start-up included) in the same run"]
    if prusa is None:
        notes.append(
            "prusa-slicer is not installed (Debian: apt-get install prusa-slicer): no peer in this run"
        )
    result = StageResult("slice", "slicing to .sl1 beside PrusaSlicer 2.5", rows, chart, notes)
    result.extra = {"antialias_sweep": sweep}
    return result
