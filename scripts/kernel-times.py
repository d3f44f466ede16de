"""First-call (compile) and warm run times of the kernels the thirteenth run changed, with a digest.

    NUMBA_CACHE_DIR=$(mktemp -d) .venv/bin/python scripts/kernel-times.py

Run it from a folder outside the checkout, once with an older commit's checkout first on
``PYTHONPATH`` and once with this one, each into an empty cache: the first-call column is
then numba's compilation, the run column the median of five warm calls, and equal digests
mean the same results to the bit (docs/benchmarks.md, "commands", thirteenth run).
``principal curvature`` prints the digest of the directions' absolute values (a direction has
no sign); it differs between LAPACK and the hand-written solver at rounding level (1e-15).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:12]


def _timed(
    name: str, first: Callable[[], object], run: Callable[[], np.ndarray], sign_free: bool = False
) -> None:
    start = time.perf_counter()
    first()
    first_s = time.perf_counter() - start
    times = []
    for _ in range(5):
        start = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - start)
    out = np.abs(out) if sign_free else out
    print(f"{name:<28} first {first_s:6.2f} s   run {sorted(times)[2]:7.4f} s   {_digest(out)}")


def main() -> None:
    rng = np.random.default_rng(5)

    from render.diffusion import _conjugate_gradients

    diag_small = 6.0 + rng.random((4, 5, 6))
    shape = (40, 120, 120)
    diag, rhs = 6.0 + rng.random(shape), rng.random(shape)
    couple = np.array([1.0, 0.9, 0.8])
    _timed(
        "diffusion CG",
        lambda: _conjugate_gradients(diag_small, couple, rng.random((4, 5, 6)), 1e-10, 5000),
        lambda: _conjugate_gradients(diag, couple, rhs, 1e-10, 5000)[0],
    )

    from noise.surface import field_principal_curvature, field_rotation, lic_surface

    part = trimesh.load(ROOT / "printapp" / "samples" / "meshes" / "featuretype.STL").subdivide().subdivide()
    pv, pf = np.asarray(part.vertices), np.asarray(part.faces)
    box = trimesh.creation.box((2.0, 2.0, 1.0)).subdivide()
    _timed(
        "principal curvature",
        lambda: field_principal_curvature(np.asarray(box.vertices), np.asarray(box.faces), "max"),
        lambda: field_principal_curvature(pv, pf, "max"),
        sign_free=True,
    )

    from noise.framed import sparse_convolution_framed

    n = 200_000
    points = rng.random((n, 3)) * 20.0
    tangents = rng.normal(size=(n, 3))
    tangents /= np.linalg.norm(tangents, axis=1)[:, None]
    normals = np.cross(tangents, rng.normal(size=(n, 3)))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    _timed(
        "framed noise",
        lambda: sparse_convolution_framed(points[:100], tangents[:100], normals[:100], stretch=6.0, seed=3),
        lambda: sparse_convolution_framed(points, tangents, normals, stretch=6.0, seed=3),
    )

    from noise.lic import lic2d

    tex = rng.random((512, 512))
    u = np.cos(np.linspace(0.0, 6.0, 512))[None, :] * np.ones((512, 1))
    v = np.sin(np.linspace(0.0, 6.0, 512))[:, None] * np.ones((1, 512))
    small = rng.random((64, 64))
    for method in ("exact", "stalling-hege"):
        _timed(
            f"2-D LIC {method}",
            lambda m=method: lic2d(np.ones((64, 64)), np.zeros((64, 64)), small, length=10, method=m),
            lambda m=method: lic2d(u, v, tex, length=20, method=m),
        )

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=10.0)
    sv, sf = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    field = field_rotation(sv, sf, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0])
    kwargs = dict(length=3.0, step=0.1, noise_scale=1.0)
    for method in ("per_vertex", "reuse"):
        extra = {"method": "per_vertex"} if method == "per_vertex" else {}
        _timed(
            f"surface LIC {method}",
            lambda e=extra: lic_surface(sv, sf, field, **kwargs, **e),
            lambda e=extra: lic_surface(sv, sf, field, **kwargs, **e),
        )

    from slicing.raster import section_segments, slice_heights

    part_mm = (pv * 20.0) - (pv * 20.0).min(axis=0) + [1.0, 1.0, 0.0]
    heights = slice_heights(float(part_mm[:, 2].max()), 0.05, 0.05)
    tiny = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    tiny_v = np.asarray(tiny.vertices) + [3.0, 3.0, 2.0]
    tiny_f, part_f = np.asarray(tiny.faces, dtype=np.int64), pf.astype(np.int64)
    _timed(
        "slicer segments",
        lambda: section_segments(tiny_v, tiny_f, slice_heights(4.0, 0.05, 0.05)),
        lambda: np.concatenate(
            [a.reshape(-1).astype(np.float64) for a in section_segments(part_mm, part_f, heights)]
        ),
    )


if __name__ == "__main__":
    main()
