"""``printapp bench commands``: whole commands as users time them, beside the peers' whole commands.

Every contender runs as its own process, start-up included, and within each repeat the
contenders run one after another (so a load on the machine falls on all of them alike);
medians over the repeats, ratios of medians from the same run:

* ``printapp slice`` beside ``prusa-slicer --export-sla`` (the SL1 profile of
  ``printapp/bench/peers/sl1_flat.ini``) on a 40 mm sphere (800 layers) and on a small
  displaced slab (20 x 20 mm, 512^2 relief, 50 layers);
* ``printapp emboss`` of a 1024^2 16-bit height map at its own resolution beside Blender's
  Displace workflow on the same map (``printapp/bench/peers/blender_displace.py``);
* ``printapp demo`` warm, and its first run (numba compiling into an empty cache, as after
  a fresh install without ``printapp warmup``; Mitsuba's own cache stays warm), and
  ``printapp warmup`` into an empty cache followed by the first demo (what ``make demo`` does);
* ``printapp design`` of every example in ``./examples`` (run from a checkout), warm
  (verification's convergence included; a design for ``printapp solve`` is timed as the
  design it solved to, ``examples/solved/``; one whose verification fails, exit 3, is timed
  and labelled so).
"""

from __future__ import annotations

import os
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

PRINTAPP = [sys.executable, "-m", "printapp"]


def _seconds(command: list[str], env: dict[str, str] | None = None) -> float:
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, timeout=1800, env=env)
    return time.perf_counter() - start


def _run(command: list[str]) -> tuple[float, int]:
    """Seconds and exit code of a command that may fail verification (exit 3, outputs forced)."""
    start = time.perf_counter()
    code = subprocess.run(command, capture_output=True, timeout=1800).returncode
    return time.perf_counter() - start, code


def _in_turn(commands: dict[str, list[str]], repeats: int) -> dict[str, float]:
    """Median seconds of each command, the commands run one after another within each repeat."""
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(repeats):
        for name, command in commands.items():
            times[name].append(_seconds(command))
    return {name: statistics.median(values) for name, values in times.items()}


def _models(folder: Path) -> dict[str, Path]:
    import trimesh
    from PIL import Image

    import noise
    from noise.heightfield import HeightField
    from printapp.exporters import stl_bytes
    from printapp.slab import slab_arrays

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=20.0)
    sphere.apply_translation([0.0, 0.0, 20.0])
    (folder / "sphere40.stl").write_bytes(stl_bytes(sphere.vertices, sphere.faces))
    axis = np.linspace(0.0, 4.0, 512)
    relief = noise.fbm_grid(axis, axis, octaves=3, seed=1)
    relief = (relief - relief.min()) / (relief.max() - relief.min()) * 0.5
    (folder / "slab20.stl").write_bytes(
        stl_bytes(*slab_arrays(HeightField(relief, 20.0 / 511, 20.0 / 511), 2.0))
    )
    axis = np.linspace(0.0, 6.0, 1024)
    height = noise.fbm_grid(axis, axis, octaves=5, seed=3)
    height = (height - height.min()) / (height.max() - height.min())
    Image.fromarray(np.round(height * 65535).astype(np.uint16)).save(folder / "map1024.png")
    return {"sphere": folder / "sphere40.stl", "slab": folder / "slab20.stl", "map": folder / "map1024.png"}


def bench_commands(repeats: int) -> StageResult:
    """Whole commands, start-up included, beside PrusaSlicer and Blender in the same run."""
    reps = max(1, min(repeats, 5))
    prusa, blender = shutil.which("prusa-slicer"), shutil.which("blender")
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    with (
        tempfile.TemporaryDirectory() as tmp,
        peer_file("sl1_flat.ini") as ini,
        peer_file("blender_displace.py") as script,
    ):
        folder = Path(tmp)
        models = _models(folder)
        for name, label in (
            ("sphere", "slice: 40 mm sphere, 800 layers"),
            ("slab", "slice: 20 mm slab, 50 layers"),
        ):
            commands = {
                "printapp": [*PRINTAPP, "slice", str(models[name]), "-o", str(folder / f"{name}.sl1")]
            }
            if prusa:
                out = str(folder / f"{name}_ps.sl1")
                setup = ["--datadir", str(folder / "dd"), "--loglevel", "1", "--load", str(ini)]
                commands["peer"] = [prusa, *setup, "--export-sla", "-o", out, str(models[name])]
            medians = _in_turn(commands, reps)
            rows.append(_row(label, "PrusaSlicer 2.5", medians))
        size = ["--width-mm", "10", "--depth-mm", "0.2", "--pitch-mm", str(10.0 / 1023)]
        emboss = [*PRINTAPP, "emboss", str(models["map"]), *size, "-o", str(folder / "ours.stl")]
        commands = {"printapp": emboss}
        if blender:
            setup = ["-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script)]
            arguments = ["--", str(models["map"]), "1024", str(folder / "blender.stl"), "10", "0.2"]
            commands["peer"] = [blender, *setup, *arguments]
        rows.append(
            _row("emboss: 1024^2 map at its own resolution", "Blender 3.4 Displace", _in_turn(commands, reps))
        )
        demo = [*PRINTAPP, "demo", "-o", str(folder / "demo"), "--quiet"]
        warm = statistics.median(_seconds(demo) for _ in range(reps))
        cold = []
        for _ in range(max(1, reps // 2)):
            with tempfile.TemporaryDirectory() as cache:
                cold.append(_seconds(demo, env={**os.environ, "NUMBA_CACHE_DIR": cache}))
        # What `make demo` does on a fresh install: `printapp warmup`, then the first demo.
        warmup, after = [], []
        for _ in range(max(1, reps // 2)):
            with tempfile.TemporaryDirectory() as cache:
                env = {**os.environ, "NUMBA_CACHE_DIR": cache}
                warmup.append(_seconds([*PRINTAPP, "warmup", "--quiet"], env=env))
                after.append(_seconds(demo, env=env))
        rows.append({"command": "demo, warm", "printapp_s": round(warm, 3)})
        rows.append(
            {
                "command": "demo, first run (empty numba cache)",
                "printapp_s": round(statistics.median(cold), 3),
            }
        )
        warmup_s = round(statistics.median(warmup), 3)
        rows.append({"command": "warmup (empty numba cache)", "printapp_s": warmup_s})
        rows.append(
            {"command": "demo, first run after warmup", "printapp_s": round(statistics.median(after), 3)}
        )
        example_files = sorted((Path.cwd() / "examples").glob("*.toml"))
        if not example_files:
            notes.append(
                "no examples/ folder in the working directory (run from a checkout): no example rows"
            )
        for example in example_files:
            # A design for `printapp solve` misses its targets by design: time the one it solved to.
            solved = example.parent / "solved" / f"{example.stem}.solved.toml"
            design = solved if solved.exists() else example
            command = [
                *PRINTAPP,
                "design",
                str(design),
                "-o",
                str(folder / example.stem),
                "--quiet",
                "--force",
            ]
            runs = [_run(command) for _ in range(max(1, reps // 2))]
            codes = sorted({code for _, code in runs})
            if codes not in ([0], [3]):
                notes.append(f"{example.name}: exit {', '.join(map(str, codes))}")
                continue
            label = f"design {design.name}, warm" + (" (exit 3: verification failed)" if codes == [3] else "")
            rows.append({"command": label, "printapp_s": round(statistics.median(s for s, _ in runs), 3)})
    for peer, name in ((prusa, "prusa-slicer"), (blender, "blender")):
        if peer is None:
            notes.append(f"{name} is not installed (Debian: apt-get install {name}): no peer in this run")

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(9, 0.35 * len(rows) + 1.5), dpi=110)
        labels = [r["command"] for r in rows][::-1]
        ours = [r["printapp_s"] for r in rows][::-1]
        peers = [r.get("peer_s", np.nan) for r in rows][::-1]
        y = np.arange(len(rows))
        ax.barh(y + 0.2, ours, 0.4, label="printapp (whole command)")
        ax.barh(y - 0.2, peers, 0.4, label="peer (whole command)")
        ax.set_yticks(y, labels, fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("seconds (median, start-up included)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult("commands", "whole commands as users time them, beside the peers'", rows, chart, notes)


def _row(label: str, peer_name: str, medians: dict[str, float]) -> dict[str, Any]:
    row: dict[str, Any] = {"command": label, "printapp_s": round(medians["printapp"], 3)}
    if "peer" in medians:
        row |= {
            "peer": peer_name,
            "peer_s": round(medians["peer"], 3),
            "speedup": round(medians["peer"] / medians["printapp"], 2),
        }
    return row
