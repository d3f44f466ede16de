"""``printapp bench frames``: orthonormal bases, and noise in tangent frames against the flat noise.

Bases: normals per second for Duff's and Frisvad's bases, and their orthonormality error
against 1 + n.z, where Frisvad's fails.

Framed noise (issue #22): the cost per sample of fBm stretched along each vertex's
tangent frame (:func:`printapp.texture.evaluate_texture_on_mesh`) against the flat
evaluation a mesh had before (its world coordinates stretched, then the flat fBm), on
the 10^6 vertices of a closed tube, for a field along the tube's axis (the needles lie
along a lattice axis), around it, and oblique to it; the two are timed in turn within
each repeat, and the ratio is of medians of the same run. Then the anisotropy the
relief gets on a closed cylinder against the stretch asked for: the correlation length
along the axis over the one around it, on the unrolled side, for the relief as sampled
on the mesh and for the noise alone on a fine grid of the exact cylinder, with the
worst orientation error over 24 windows of the side.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.timing import StageResult, interleaved_seconds, median_seconds

FIELDS = {"along the axis": "direction:0,0,1", "around it": "axis:0,0,1", "oblique": "direction:1,1,1"}
TUBE_VERTICES = 1_000_000
"""Vertices of the tube the framed and flat fBm are timed on (the issue's 10^6)."""
STRETCHES = (1.0, 2.0, 4.0, 6.0, 8.0, 12.0)
SEEDS = (1, 2, 3)
"""Seeds the anisotropy is averaged over: one realisation's correlation lengths scatter by about 8 %."""


# ---------------------------------------------------------------------------------------------
# Measuring a relief on a cylinder (the tests use these too)


def closed_cylinder(radius: float, height: float, edge: float):
    """A closed cylinder about the z axis from z = 0 to ``height``, triangles about ``edge`` across.

    The side is rings of vertices, every other ring turned by half a step (near-equilateral
    triangles); the ends are Delaunay triangulations of a hexagonal grid inside the rim.
    """
    import trimesh
    from scipy.spatial import Delaunay

    sections = max(8, round(2 * math.pi * radius / edge))
    rings = max(2, round(height / (edge * math.sqrt(3) / 2)) + 1)
    z = np.linspace(0.0, height, rings)
    turn = (np.arange(rings) % 2) * (math.pi / sections)
    angle = np.arange(sections)[None, :] * (2 * math.pi / sections) + turn[:, None]
    side = np.column_stack(
        [radius * np.cos(angle).ravel(), radius * np.sin(angle).ravel(), np.repeat(z, sections)]
    )
    faces = []
    i = np.arange(sections)
    for j in range(rings - 1):
        a, b = j * sections + i, j * sections + (i + 1) % sections
        c, d = a + sections, b + sections
        # Odd rings are turned forward: split each quad along the shorter diagonal.
        faces += (
            [np.column_stack([a, b, c]), np.column_stack([b, d, c])]
            if j % 2 == 0
            else [
                np.column_stack([a, b, d]),
                np.column_stack([a, d, c]),
            ]
        )
    vertices = [side]
    step = 2 * math.pi * radius / sections
    for end, ring in ((0.0, 0), (height, rings - 1)):
        rim = side[ring * sections : (ring + 1) * sections, :2]
        ys = np.arange(-radius, radius + step, step * math.sqrt(3) / 2)
        grid = [
            (x + (k % 2) * step / 2, y)
            for k, y in enumerate(ys)
            for x in np.arange(-radius, radius + step, step)
            if math.hypot(x + (k % 2) * step / 2, y) < radius - 0.6 * step
        ]
        points = np.concatenate([rim, np.array(grid).reshape(-1, 2)])
        index = np.concatenate(
            [ring * sections + i, sum(len(v) for v in vertices) + np.arange(len(points) - sections)]
        )
        vertices.append(np.column_stack([points[sections:], np.full(len(points) - sections, end)]))
        simplices = Delaunay(points).simplices
        tri, p = index[simplices], points[simplices]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        upward = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0
        outward = upward if end > 0 else ~upward
        faces.append(np.where(outward[:, None], tri, tri[:, ::-1]))
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)


def unrolled_side(
    mesh, values: np.ndarray, radius: float, z_lo: float, z_hi: float, pitch: float
) -> np.ndarray:
    """Values on the side of a z-axis cylinder, unrolled onto a grid: rows along the axis, columns around.

    Interpolated linearly in the mesh's own triangles (as the relief is), seam excluded.
    """
    import matplotlib.tri as mtri

    v = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    u = radius * np.arctan2(v[:, 1], v[:, 0])
    side = np.hypot(v[:, 0], v[:, 1]) > 0.995 * radius
    f = faces[side[faces].all(axis=1)]
    f = f[np.ptp(u[f], axis=1) < np.pi * radius]  # not across the seam
    interpolate = mtri.LinearTriInterpolator(mtri.Triangulation(u, v[:, 2], f), values)
    uu, vv = np.meshgrid(
        np.arange(-np.pi * radius + 0.5, np.pi * radius - 0.5, pitch), np.arange(z_lo, z_hi, pitch)
    )
    return np.asarray(interpolate(uu, vv).filled(np.nan))


def streak_angle_deg(image: np.ndarray) -> float:
    """Direction the streaks of an image run along, by its structure tensor (degrees from x, in [0, 180))."""
    gy, gx = np.gradient(image)
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    return float(np.degrees(0.5 * np.arctan2(2 * jxy, jxx - jyy) + np.pi / 2) % 180.0)


def _autocorrelation(image: np.ndarray) -> np.ndarray:
    a = image - image.mean()
    shape = (2 * a.shape[0], 2 * a.shape[1])
    raw = np.fft.ifft2(np.abs(np.fft.fft2(a, s=shape)) ** 2).real
    overlap = np.fft.ifft2(np.abs(np.fft.fft2(np.ones_like(a), s=shape)) ** 2).real
    acf = raw / np.maximum(overlap, 1.0)
    return acf / acf[0, 0]


def _half_lag(line: np.ndarray) -> float:
    i = int(np.argmax(line < 0.5))
    return (i - 1) + (line[i - 1] - 0.5) / (line[i - 1] - line[i])


def correlation_ratio(image: np.ndarray) -> float:
    """Correlation length along the image's y over the one along its x (lags where the correlation is 1/2)."""
    acf = _autocorrelation(image)
    return _half_lag(acf[: image.shape[0], 0]) / _half_lag(acf[0, : image.shape[1]])


def worst_angle_error_deg(image: np.ndarray, expected_deg: float, rows: int = 3, cols: int = 8) -> float:
    """The largest error of the streaks' direction over a rows x cols grid of windows."""
    ny, nx = image.shape
    worst = 0.0
    for i in range(rows):
        for j in range(cols):
            window = image[i * ny // rows : (i + 1) * ny // rows, j * nx // cols : (j + 1) * nx // cols]
            worst = max(worst, abs((streak_angle_deg(window) - expected_deg + 90.0) % 180.0 - 90.0))
    return worst


# ---------------------------------------------------------------------------------------------
# The stage


def _texture(stretch: float, field: str | None = None, feature_size_mm: float = 1.0, octaves: int = 4):
    from printapp.design import Texture

    return Texture(
        kind="fbm", feature_size_mm=feature_size_mm, octaves=octaves, seed=1, stretch=stretch, field=field
    )


def framed_against_flat(repeats: int, n_vertices: float, stretch: float = 6.0) -> list[dict[str, Any]]:
    """Cost per sample of framed and flat fBm on a closed tube of about ``n_vertices`` vertices (edge F/4)."""
    import time

    from printapp.texture import evaluate_texture, evaluate_texture_in_frames, texture_frames

    edge = 0.25  # mm, with 1 mm features: the relief's sampling on meshes
    radius = 40.0 if n_vertices >= 5e5 else 8.0
    area = n_vertices * edge * edge * math.sqrt(3) / 2
    mesh = closed_cylinder(radius, (area - 2 * math.pi * radius**2) / (2 * math.pi * radius), edge)
    vertices = np.asarray(mesh.vertices)
    n = len(vertices)
    rows = []
    for name, spec in FIELDS.items():
        texture = _texture(stretch, spec)
        start = time.perf_counter()
        frames, _ = texture_frames(mesh, texture)
        frame_seconds = time.perf_counter() - start
        medians, _, cores = interleaved_seconds(
            {
                "flat": lambda t=texture: evaluate_texture(vertices, t, pitch_mm=edge),
                "framed": lambda t=texture, f=frames: evaluate_texture_in_frames(vertices, f, t, edge),
            },
            repeats,
        )
        rows.append(
            {
                "field": f"{name} ({spec})",
                "vertices": n,
                "flat_ns_per_sample": round(medians["flat"] / n * 1e9, 1),
                "framed_ns_per_sample": round(medians["framed"] / n * 1e9, 1),
                "speed_ratio": round(medians["flat"] / medians["framed"], 3),
                "frames_ns_per_vertex": round(frame_seconds / n * 1e9, 1),
                "singular_vertices": frames.singular_count,
                "cores_flat": round(cores["flat"], 2),
                "cores_framed": round(cores["framed"], 2),
            }
        )
    return rows


def anisotropy_against_stretch(stretches=STRETCHES, seeds=SEEDS) -> list[dict[str, Any]]:
    """The along/across correlation-length ratio on a closed cylinder (radius 8, 24 mm) per stretch.

    ``relief_ratio``: the fBm at the vertices of the mesh, refined to edges of at most F/4 as
    a design's mesh is, interpolated in its triangles (the relief as built); ``noise_ratio``:
    the fBm alone on a 0.05 mm grid of the exact cylinder. Both on the side 3 mm clear of
    the ends, averaged over ``seeds``; ``worst_angle_error_deg`` is the largest error of
    the strokes' direction over 24 windows of the side, over the seeds.
    """
    from noise.framed import fbm_framed
    from printapp.mesh import refine_to_edge_length
    from printapp.texture import evaluate_texture_on_mesh

    radius, height, feature = 8.0, 24.0, 1.0
    mesh = refine_to_edge_length(closed_cylinder(radius, height, 0.8), feature / 4)
    u = np.arange(-np.pi * radius + 0.5, np.pi * radius - 0.5, 0.05)
    z = np.arange(3.0, height - 3.0, 0.05)
    uu, zz = np.meshgrid(u, z)
    normals = np.column_stack([np.cos(uu.ravel() / radius), np.sin(uu.ravel() / radius), np.zeros(uu.size)])
    points = np.column_stack([radius * normals[:, :2], zz.ravel()]) / feature
    tangents = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    rows = []
    for stretch in stretches:
        relief, alone, worst = [], [], 0.0
        for seed in seeds:
            texture = _texture(stretch, "direction:0,0,1", feature, octaves=3).model_copy(
                update={"seed": seed}
            )
            values, _ = evaluate_texture_on_mesh(mesh, texture, feature / 4)
            image = unrolled_side(mesh, values, radius, 3.0, height - 3.0, 0.1)
            relief.append(correlation_ratio(image))
            if stretch > 1:
                worst = max(worst, worst_angle_error_deg(image, 90.0))
            grid = fbm_framed(
                points, tangents, normals, stretch=stretch, octaves=3, seed=seed, min_pitch=0.25
            )
            alone.append(correlation_ratio(grid.reshape(uu.shape)))
        rows.append(
            {
                "stretch": stretch,
                "relief_ratio": round(float(np.mean(relief)), 3),
                "relief_ratio_range": [round(float(min(relief)), 3), round(float(max(relief)), 3)],
                "noise_ratio": round(float(np.mean(alone)), 3),
                "worst_angle_error_deg": round(worst, 2) if stretch > 1 else None,
            }
        )
    return rows


def bench_frames(repeats: int) -> StageResult:
    """Duff's and Frisvad's bases; framed against flat noise on 1e6 vertices; anisotropy against stretch."""
    from noise.frames import onb

    rng = np.random.default_rng(0)
    n = 1_000_000
    uniform = rng.normal(size=(n // 2, 3))
    uniform /= np.linalg.norm(uniform, axis=1, keepdims=True)
    eps = 10 ** rng.uniform(-12, 0, n - n // 2)
    r = np.sqrt(eps * (2 - eps))
    phi = rng.uniform(0, 2 * np.pi, eps.size)
    clustered = np.column_stack([r * np.cos(phi), r * np.sin(phi), -1 + eps])
    normals64 = np.concatenate([uniform, clustered])
    one_plus_z = 1 + normals64[:, 2]
    rows = []
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    edges = np.logspace(-12, 0, 25)
    for dtype in (np.float32, np.float64):
        normals = normals64.astype(dtype)
        for method in ("duff", "frisvad"):
            seconds, _ = median_seconds(lambda m=method, x=normals: onb(x, m), repeats)
            b1, b2 = onb(normals, method)
            basis = np.stack([b1, b2, normals], axis=1).astype(np.float64)
            error = np.abs(np.einsum("kij,klj->kil", basis, basis) - np.eye(3)).max(axis=(1, 2))
            rows.append(
                {
                    "method": method,
                    "dtype": np.dtype(dtype).name,
                    "M_normals_s": round(n / seconds / 1e6, 1),
                    "max_error": float(f"{error.max():.3g}"),
                    "max_error_far_from_pole": float(f"{error[one_plus_z > 0.5].max():.3g}"),
                }
            )
            which = np.digitize(one_plus_z, edges)
            worst = np.array(
                [error[which == b].max() if np.any(which == b) else np.nan for b in range(1, len(edges))]
            )
            curves[f"{method} {np.dtype(dtype).name}"] = (np.sqrt(edges[1:] * edges[:-1]), worst)
    costs = framed_against_flat(repeats, TUBE_VERTICES)
    anisotropy = anisotropy_against_stretch(STRETCHES, SEEDS)

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (ax, bx, cx) = plt.subplots(1, 3, figsize=(15, 4.2), dpi=110)
        for label, (x, y) in curves.items():
            ax.loglog(x, np.maximum(y, 1e-18), "-" if "duff" in label else "--", label=label)
        ax.set_xlabel("1 + n.z (distance from the south pole)")
        ax.set_ylabel("max |B B^T - I|")
        ax.set_title("orthonormal bases near n = (0, 0, -1)")
        ax.legend(fontsize=8)
        x = np.arange(len(costs))
        bx.bar(x - 0.2, [c["flat_ns_per_sample"] for c in costs], 0.4, label="flat (world x-y stretch)")
        bx.bar(x + 0.2, [c["framed_ns_per_sample"] for c in costs], 0.4, label="framed (tangent frames)")
        for k, c in enumerate(costs):
            bx.text(k + 0.2, c["framed_ns_per_sample"], f"{c['speed_ratio']:.2f}x", ha="center", va="bottom")
        bx.set_xticks(x, [c["field"].split(" (")[0] for c in costs])
        bx.set_ylabel("ns per sample (fBm, 2 octaves at F/4)")
        bx.set_title(f"fBm, stretch 6, on {costs[0]['vertices']:,} tube vertices")
        bx.legend(fontsize=8)
        s = [a["stretch"] for a in anisotropy]
        cx.plot(s, s, "k:", label="asked (stretch)")
        cx.plot(s, [a["noise_ratio"] for a in anisotropy], "o-", label="noise alone (0.05 mm grid)")
        relief = np.array([a["relief_ratio"] for a in anisotropy])
        spread = np.array([a["relief_ratio_range"] for a in anisotropy]).T
        cx.errorbar(
            s,
            relief,
            yerr=np.abs(spread - relief),
            fmt="s-",
            capsize=3,
            label="relief on the mesh (edges <= F/4)",
        )
        cx.set_xlabel("stretch")
        cx.set_ylabel("correlation length along / across")
        cx.set_title(f"anisotropy on a closed cylinder (fBm, mean of {len(SEEDS)} seeds)")
        cx.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    notes = [
        f"framed fBm on {c['vertices']:,} vertices, {c['field']}: {c['framed_ns_per_sample']} ns/sample "
        f"against {c['flat_ns_per_sample']} flat ({c['speed_ratio']}x the flat speed); frames "
        f"{c['frames_ns_per_vertex']} ns/vertex, {c['singular_vertices']:,} singular vertices"
        for c in costs
    ] + [
        f"stretch {a['stretch']:g}: along/across {a['relief_ratio']} (relief), {a['noise_ratio']} (noise)"
        + (
            f", worst direction error {a['worst_angle_error_deg']} deg"
            if a["worst_angle_error_deg"] is not None
            else ""
        )
        for a in anisotropy
    ]
    return StageResult(
        "frames",
        "orthonormal bases from 1e6 unit normals (half near the south pole); framed against flat fBm",
        rows,
        chart,
        notes,
        {"framed_vs_flat": costs, "anisotropy": anisotropy},
    )
