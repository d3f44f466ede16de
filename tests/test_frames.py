"""Orthonormal bases and mesh frames, including where Frisvad's basis fails."""

import numpy as np
import pytest
import trimesh

from noise.frames import angle_weighted_normals, face_frames, onb, vertex_frames


def normals_with_a_cluster_at_the_south_pole(n: int, dtype, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Half uniform on the sphere, half with 1 + n.z log-uniform in [1e-9, 1e-2]; and 1 + n.z."""
    rng = np.random.default_rng(seed)
    uniform = rng.normal(size=(n // 2, 3))
    uniform /= np.linalg.norm(uniform, axis=1, keepdims=True)
    eps = 10 ** rng.uniform(-9, -2, n - n // 2)
    z = -1 + eps
    r = np.sqrt(eps * (2 - eps))
    phi = rng.uniform(0, 2 * np.pi, eps.size)
    clustered = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    normals = np.concatenate([uniform, clustered])
    return normals.astype(dtype), 1 + normals[:, 2]


def orthonormality_error(n, b1, b2) -> np.ndarray:
    basis = np.stack([b1, b2, n], axis=1).astype(np.float64)
    return np.abs(np.einsum("kij,klj->kil", basis, basis) - np.eye(3)).max(axis=(1, 2))


@pytest.mark.parametrize(("dtype", "tolerance"), [(np.float32, 1e-6), (np.float64, 1e-14)])
def test_duff_is_orthonormal_and_right_handed_everywhere(dtype, tolerance):
    n, _ = normals_with_a_cluster_at_the_south_pole(1_000_000, dtype)
    b1, b2 = onb(n)
    assert b1.dtype == dtype
    assert orthonormality_error(n, b1, b2).max() <= tolerance
    handed = np.cross(b1.astype(np.float64), b2.astype(np.float64))
    assert np.abs(handed - n).max() <= 10 * tolerance


@pytest.mark.parametrize(("dtype", "measured"), [(np.float32, 1e-3), (np.float64, 1e-5)])
def test_frisvad_loses_orthonormality_near_the_south_pole(dtype, measured):
    # Regression test documenting the failure Duff et al. fixed: a = 1 / (1 + n.z) cancels.
    n, one_plus_z = normals_with_a_cluster_at_the_south_pole(200_000, dtype)
    error = orthonormality_error(n, *onb(n, "frisvad"))
    near = one_plus_z < 1e-6
    assert error[near].max() > measured  # measured: about 6e-3 in float32, 9e-5 in float64
    far = one_plus_z > 0.5
    assert error[far].max() < (1e-6 if dtype == np.float32 else 1e-14)


def test_both_bases_agree_away_from_the_pole():
    n, one_plus_z = normals_with_a_cluster_at_the_south_pole(100_000, np.float64)
    keep = n[:, 2] > 0  # Duff's s = +1 there: the same formula as Frisvad's
    d1, d2 = onb(n[keep])
    f1, f2 = onb(n[keep], "frisvad")
    np.testing.assert_allclose(d1, f1, atol=1e-12)
    np.testing.assert_allclose(d2, f2, atol=1e-12)


def test_equator_and_poles():
    n = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, -0.0]])
    n[4] = [0.6, 0.8, 0.0]
    b1, b2 = onb(n)
    assert orthonormality_error(n, b1, b2).max() < 1e-15


@pytest.mark.parametrize(
    ("normals", "kwargs", "message"),
    [
        (np.zeros((2, 3)), {}, "zero-length"),
        (np.array([[0, 0, 2.0]]), {}, "expected unit vectors"),
        (np.array([[np.nan, 0, 1.0]]), {}, "finite"),
        (np.zeros((2, 2)), {}, "expected an \\(n, 3\\) array"),
        (np.array([[0, 0, 1.0]]), {"method": "hughes"}, "method"),
    ],
)
def test_bad_normals(normals, kwargs, message):
    with pytest.raises(ValueError, match=message):
        onb(normals, **kwargs)


def test_normalize_repairs_lengths():
    b1, b2 = onb(np.array([0, 0, 2.0]), normalize=True)
    np.testing.assert_allclose(np.cross(b1, b2), [0, 0, 1], atol=1e-15)


def test_pseudo_normals_are_exact_on_faces_and_diagonal_at_corners():
    cube = trimesh.creation.box(extents=(2, 2, 2)).subdivide().subdivide()
    normals = angle_weighted_normals(cube.vertices, cube.faces)
    on_face = np.sum(np.isclose(np.abs(cube.vertices), 1.0), axis=1) == 1
    axis = np.where(np.isclose(np.abs(cube.vertices), 1.0), np.sign(cube.vertices), 0.0)
    np.testing.assert_allclose(normals[on_face], axis[on_face], atol=1e-12)
    corner = np.sum(np.isclose(np.abs(cube.vertices), 1.0), axis=1) == 3
    np.testing.assert_allclose(normals[corner], cube.vertices[corner] / np.sqrt(3), atol=1e-12)


def test_vertex_and_face_frames_are_orthonormal():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    for frames in (vertex_frames(sphere.vertices, sphere.faces), face_frames(sphere.vertices, sphere.faces)):
        n, b1, b2 = frames
        assert orthonormality_error(n, b1, b2).max() < 1e-12
    n, _, _ = vertex_frames(sphere.vertices, sphere.faces)
    radial = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    assert np.min(np.einsum("ij,ij->i", n, radial)) > 0.999
