"""The bench's peers see the tracer's surface and the estimator's rays (no timings here).

``printapp bench brdf`` compares the gonioreflectometer with Embree on "the same geometry
and rays"; these tests make that claim checkable: the mesh built for the peers has, ray
for ray, the tracer's first hits (against a float64 brute-force reference, and against
Embree in float32), and the regenerated primary rays are the estimator's own.
"""

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from printapp.bench.brdf import tracer_slopes
from printapp.bench.brdf_hits import (
    TracerFirstHit,
    face_cells,
    mesh_margin_cells,
    periodic_mesh,
    primary_rays,
)
from printapp.bench.reference.ray_triangles import first_hits
from render.gonio import direction_from_angles, estimate_brdf, lobe_bins, lobe_error

NY, NX = 24, 30  # not square, and different pitches, so that x and y cannot be swapped unnoticed
PX, PY = 0.05, 0.04


def rough_tile(rms_slope: float, seed: int = 3) -> np.ndarray:
    h = gaussian_filter(np.random.default_rng(seed).normal(size=(NY, NX)), 1.5, mode="wrap")
    gx, gy = tracer_slopes(h, PX, PY)
    return h * rms_slope / math.sqrt(np.mean(gx * gx + gy * gy))


def directions() -> np.ndarray:
    theta = np.radians([0.0, 30.0, 60.0, 60.0, 85.0, 85.0, 89.0, 45.0])
    phi = np.radians([0.0, 17.0, 0.0, 90.0, 200.0, 315.0, 123.0, 45.0])  # axis and diagonal cases too
    return direction_from_angles(theta, phi)


@pytest.mark.slow
@pytest.mark.parametrize("periodic", [True, False])
def test_peer_mesh_has_the_tracers_first_hits(periodic):
    h = rough_tile(0.8)
    wi = directions()
    origins, dirs = primary_rays(h, PX, PY, wi, 40, seed=5, periodic=periodic)
    t_tracer, cells = TracerFirstHit(h, PX, PY)(origins, dirs)
    assert np.all(np.isfinite(t_tracer))
    # The ray moves monotonically in x and y, so any nearer hit the tracer might have missed
    # lies in the cells between its origin and the tracer's hit: a ring reaching every hit
    # cell is enough for the brute force (and keeps it fast). The bench's ring holds them all.
    mx = int(max(-cells[:, 0].min(), cells[:, 0].max() - NX + 1, 0)) + 1
    my = int(max(-cells[:, 1].min(), cells[:, 1].max() - NY + 1, 0)) + 1
    assert mx <= mesh_margin_cells(h, PX, 89.0) and my <= mesh_margin_cells(h, PY, 89.0)
    vertices, faces = periodic_mesh(h, PX, PY, mx, my)
    t_ref, prim = first_hits(vertices, faces, origins, dirs)
    assert np.all(prim >= 0), "a first hit fell outside the peers' mesh"
    # Same distance to 1e-9 relative: the mesh is the tracer's surface, hit for hit.
    np.testing.assert_allclose(t_tracer, t_ref, rtol=1e-9)
    ci, cj, tri = face_cells(prim, h.shape, mx, my)
    same = (ci == cells[:, 0]) & (cj == cells[:, 1]) & (tri == cells[:, 2])
    # Only a ray through a shared edge may name the other triangle, at the same distance.
    assert np.mean(same) >= 0.99


@pytest.mark.slow
def test_embree_agrees_with_the_tracer_in_single_precision():
    pytest.importorskip("embreex")
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    h = rough_tile(0.8)
    wi = directions()
    origins, dirs = primary_rays(h, PX, PY, wi, 50, seed=6, periodic=True)
    t_tracer, cells = TracerFirstHit(h, PX, PY)(origins, dirs)
    mx = mesh_margin_cells(h, PX, 89.0)
    my = mesh_margin_cells(h, PY, 89.0)
    vertices, faces = periodic_mesh(h, PX, PY, mx, my)
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, vertices.astype(np.float32), faces)
    out = scene.run(origins.astype(np.float32), dirs.astype(np.float32), output=1)
    assert np.all(out["primID"] >= 0)
    ci, cj, tri = face_cells(out["primID"], h.shape, mx, my)
    same = (ci == cells[:, 0]) & (cj == cells[:, 1]) & (tri == cells[:, 2])
    assert np.mean(same) >= 0.99
    # float32 coordinates of a few mm: distances agree to a few 1e-7 mm of the tile's size.
    extent = max(NX * PX, NY * PY) + 2 * (mx * PX + my * PY)
    np.testing.assert_allclose(out["tfar"], t_tracer, rtol=0, atol=2e-6 * extent)


@pytest.mark.parametrize("periodic", [True, False])
def test_primary_rays_are_the_estimators_own(periodic):
    # With ior = 1 nothing reflects and a black body returns nothing, so the estimator traces
    # exactly one segment per primary ray; its count of grid steps is then the sum of the
    # first-hit steps of its rays, which depends on every origin to the last bit.
    h = rough_tile(0.5)
    wi = directions()[:6]
    rays = 300
    table = estimate_brdf(h, PX, PY, wi, rays=rays, ior=1.0, body_albedo=0.0, n_theta=9, n_phi=8, seed=11,
                          periodic=periodic)  # fmt: skip
    np.testing.assert_array_equal(table.extra["segments"], rays)
    origins, dirs = primary_rays(h, PX, PY, wi, rays, seed=11, periodic=periodic)
    _, cells = TracerFirstHit(h, PX, PY)(origins, dirs)
    steps = cells[:, 3].reshape(len(wi), rays).sum(axis=1)
    np.testing.assert_array_equal(table.extra["steps"], steps)
    # A different seed gives different rays (the check above is not vacuous).
    other, _ = primary_rays(h, PX, PY, wi, rays, seed=12, periodic=periodic)
    assert not np.array_equal(other, origins)


def test_lobe_error_weights_bins_by_energy():
    omega = np.array([[1.0, 2.0, 1.0, 4.0]])
    f = np.array([[10.0, 0.5, 5.0, 0.0]])
    stderr = np.array([[1.0, 0.5, 0.25, 0.0]])
    # Energies 10, 1, 5, 0: the top 90 % of 16 is the first and third bins (15 of 16).
    assert sorted(lobe_bins(f, omega).tolist()) == [0, 2]
    # sum_b E_b (s_b / f_b) / sum_b E_b = (10 * 0.1 + 5 * 0.05) / 15
    assert lobe_error(f, stderr, omega) == pytest.approx((10 * 0.1 + 5 * 0.05) / 15, rel=1e-15)
