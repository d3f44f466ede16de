"""``printapp bench mesh``: height map to printable model, beside the talk's Blender workflow.

The same 1024 x 1024 16-bit height map (smooth fBm), 10 mm wide, 0.2 mm deep:

* Blender (Debian's 3.4, background mode, ``printapp/bench/peers/blender_displace.py``): a 1024 x 1024
  quad grid, the Displace modifier, binary STL; an open sheet.
* ``printapp emboss`` at the same resolution (1024^2 samples): a closed slab, binary STL.
* ``printapp emboss`` at the printer's pixel pitch (the default): what a print needs.

Both run as commands (start-up included), medians over repeats, in the same run. The STLs
are then checked: open edges (trimesh), triangle counts, and the height difference between
the two tops at Blender's vertices.
"""

from __future__ import annotations

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


def _run(command: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, timeout=600)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench_mesh(repeats: int) -> StageResult:
    """Height map to STL with ``printapp emboss`` beside Blender's Displace workflow."""
    import trimesh
    from PIL import Image

    import noise

    reps = max(1, min(repeats, 3))
    blender = shutil.which("blender")
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp, peer_file("blender_displace.py") as peer_script:
        folder = Path(tmp)
        axis = np.linspace(0.0, 6.0, 1024)
        relief = noise.fbm_grid(axis, axis, octaves=5, seed=3)
        relief = (relief - relief.min()) / (relief.max() - relief.min())
        height_map = folder / "map1024.png"
        Image.fromarray(np.round(relief * 65535).astype(np.uint16)).save(height_map)
        ours = [
            sys.executable,
            "-m",
            "printapp",
            "emboss",
            str(height_map),
            "--width-mm",
            "10",
            "--depth-mm",
            "0.2",
        ]
        full = folder / "ours_full.stl"
        pitch = folder / "ours_pitch.stl"
        full_s = _run([*ours, "--pitch-mm", str(10.0 / 1023), "-o", str(full)], reps)
        pitch_s = _run([*ours, "-o", str(pitch)], reps)
        ours_full = trimesh.load(full)
        ours_pitch = trimesh.load(pitch)
        rows.append(
            {
                "method": "printapp emboss, 1024^2 samples",
                "median_s": round(full_s, 3),
                "triangles": len(ours_full.faces),
                "closed": bool(ours_full.is_watertight and ours_full.is_winding_consistent),
            }
        )
        rows.append(
            {
                "method": "printapp emboss, printer pitch (47 um)",
                "median_s": round(pitch_s, 3),
                "triangles": len(ours_pitch.faces),
                "closed": bool(ours_pitch.is_watertight and ours_pitch.is_winding_consistent),
            }
        )
        if blender is not None:
            peer = folder / "blender.stl"
            command = [
                blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(peer_script),
                "--", str(height_map), "1024", str(peer), "10", "0.2",
            ]  # fmt: skip
            peer_s = _run(command, reps)
            theirs = trimesh.load(peer)
            open_edges = int(trimesh.grouping.group_rows(theirs.edges_sorted, require_count=1).shape[0])
            # Blender's grid is centred on the origin; ours starts at (0, 0) and stands on a 2 mm base.
            top = ours_full.vertices[ours_full.vertices[:, 2] > 1.0]
            from scipy.interpolate import griddata

            sample = theirs.vertices[:: max(1, len(theirs.vertices) // 20000)]
            ours_z = griddata(top[:, :2] - 5.0, top[:, 2] - 2.0, sample[:, :2], method="linear")
            diff = (ours_z - sample[:, 2])[np.isfinite(ours_z)]
            rows.append(
                {
                    "method": "Blender 3.4 Displace, 1024^2 quads",
                    "median_s": round(peer_s, 3),
                    "triangles": len(theirs.faces),
                    "closed": bool(theirs.is_watertight),
                    "open_edges": open_edges,
                    "top_height_rms_diff_um": round(float(np.sqrt(np.mean(diff**2))) * 1000, 3),
                }
            )
            for row in rows[:2]:
                row["speedup_vs_blender"] = round(peer_s / row["median_s"], 2)

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.2), dpi=110)
        ax.barh([r["method"] for r in rows], [r["median_s"] for r in rows])
        for i, r in enumerate(rows):
            ax.annotate(
                f"{r['triangles']:,} tris, {'closed' if r['closed'] else 'open sheet'}",
                (r["median_s"], i),
                fontsize=8,
            )
        ax.set_xlabel("median seconds (command, start-up included)")
        ax.set_title("height map (1024^2, 10 mm) to STL")
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    notes = (
        [] if blender is not None else ["blender is not installed (Debian: apt-get install blender): no peer"]
    )
    return StageResult(
        "mesh", "height map to printable STL beside Blender's Displace workflow", rows, chart, notes
    )
