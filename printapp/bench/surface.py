"""``printapp bench surface``: line integral convolution on a mesh, streamline reuse beside the
per-vertex walk (the reference), in the same run.

Two meshes: ``examples/brushed_part.toml``'s refined CAD part (its design rebuilt here from
the packaged sample mesh, 0.3 mm noise smeared 1.5 mm each way along circles about the
vertical axis, a quarter-feature step), and an icosphere with the same swirl, where every
streamline is smooth. Reported per mesh: the median time of each method (timed in turn within
every repeat, after a warm-up call), the ratio, and how the reused values compare with the
per-vertex ones (correlation, spread). The per-vertex walk is compared with itself with every
vertex moved by a nanometre, which says how well posed the pointwise comparison is.
"""

from __future__ import annotations

import tempfile
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, interleaved_seconds

TARGET_RATIO = 5.0
_PART = """
[base]
shape = "mesh"
path = "{path}"
scale = 6.0
[texture]
kind = "lic"
field = "swirl"
feature_size_mm = 0.3
length_mm = 1.5
seed = 2
[relief]
amplitude_um = 120
[printer]
name = "prusa-sl1"
"""


def _part() -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    from printapp.design_io import load_design
    from printapp.fields import field_on_mesh, lic_field
    from printapp.relief import build_relief

    with (
        as_file(files("printapp") / "samples" / "meshes" / "featuretype.STL") as sample,
        tempfile.TemporaryDirectory() as tmp,
    ):
        design_path = Path(tmp) / "part.toml"
        design_path.write_text(_PART.format(path=Path(sample).as_posix()))
        design = load_design(design_path)
        relief = build_relief(design)
    mesh = relief.undisplaced
    assert mesh is not None
    texture = design.texture
    field = field_on_mesh(lic_field(texture), mesh, None)
    step = max(design.pitch_mm, texture.feature_size_mm / 4.0)
    kwargs = dict(length=texture.length_mm, step=step, noise_scale=texture.feature_size_mm, seed=texture.seed)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces), field, kwargs


def _sphere() -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    import trimesh

    from noise.surface import field_rotation

    sphere = trimesh.creation.icosphere(subdivisions=7, radius=10.0)
    vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    field = field_rotation(vertices, faces, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0])
    return vertices, faces, field, dict(length=1.5, step=0.075, noise_scale=0.3, seed=2)


def bench_surface(repeats: int) -> StageResult:
    """Surface LIC: streamline reuse against the per-vertex walk, time and agreement."""
    from noise.surface import lic_surface

    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    for label, build in (("brushed_part's CAD part", _part), ("icosphere, swirl", _sphere)):
        vertices, faces, field, kwargs = build()
        fns = {
            method: (
                lambda m=method, v=vertices, f=faces, t=field, kw=kwargs: lic_surface(v, f, t, method=m, **kw)
            )
            for method in ("per_vertex", "reuse")
        }
        seconds, last, cores = interleaved_seconds(fns, max(1, min(repeats, 5)))
        reference, reused = last["per_vertex"], last["reuse"]
        nudged = lic_surface(
            vertices + np.random.default_rng(0).normal(scale=1e-6, size=vertices.shape),
            faces,
            field,
            method="per_vertex",
            **kwargs,
        )
        rows.append(
            {
                "mesh": label,
                "vertices": len(vertices),
                "per_vertex_s": round(seconds["per_vertex"], 3),
                "reuse_s": round(seconds["reuse"], 3),
                "reuse_faster_by": round(seconds["per_vertex"] / seconds["reuse"], 2),
                "reuse_cores": round(cores["reuse"], 2),
                "correlation": round(float(np.corrcoef(reused, reference)[0, 1]), 4),
                "spread_ratio": round(float(reused.std() / reference.std()), 4),
                "per_vertex_vs_itself_moved_1nm": round(float(np.corrcoef(nudged, reference)[0, 1]), 4),
            }
        )
    worst = min(r["reuse_faster_by"] for r in rows)
    notes.append(
        f"target (issue #20: the surface LIC of brushed_part >= {TARGET_RATIO:g}x faster): "
        f"{'met' if rows[0]['reuse_faster_by'] >= TARGET_RATIO else 'not met'} "
        f"({rows[0]['reuse_faster_by']}x on the part, {worst}x worst)"
    )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7.0, 3.6), dpi=110)
        x = np.arange(len(rows))
        ax.bar(x - 0.2, [r["per_vertex_s"] for r in rows], 0.4, label="per-vertex walk (reference)")
        ax.bar(x + 0.2, [r["reuse_s"] for r in rows], 0.4, label="streamline reuse")
        for i, r in enumerate(rows):
            ax.annotate(
                f"{r['reuse_faster_by']}x, corr {r['correlation']}\n(reference vs itself moved 1 nm: "
                f"{r['per_vertex_vs_itself_moved_1nm']})",
                (i + 0.2, r["reuse_s"]),
                ha="center",
                va="bottom",
                fontsize=7,
            )
        ax.set_xticks(x, [f"{r['mesh']}\n{r['vertices']:,} vertices" for r in rows])
        ax.set_ylabel("seconds (median)")
        ax.set_title("surface LIC, 2 threads")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "surface", "surface LIC: streamline reuse beside the per-vertex walk", rows, chart, notes
    )
