"""Vertex normals in numpy: the reference for :func:`noise.frames.angle_weighted_normals`.

The corner's angle is the arc cosine of its cosine (the kernel takes ``atan2``), and the
sums are numpy's ``add.at``: the same definition (Thürmer & Wüthrich 1998) by another road.
"""

from __future__ import annotations

import numpy as np


def angle_weighted_normals_plain(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) unit pseudo-normals; vertices used by no face get (0, 0, 0)."""
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    tri = verts[tris]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_n /= np.maximum(np.linalg.norm(face_n, axis=1, keepdims=True), 1e-300)
    normals = np.zeros_like(verts)
    for k in range(3):
        e1 = tri[:, (k + 1) % 3] - tri[:, k]
        e2 = tri[:, (k + 2) % 3] - tri[:, k]
        cos = np.einsum("ij,ij->i", e1, e2) / np.maximum(
            np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300
        )
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
        np.add.at(normals, tris[:, k], face_n * angle[:, None])
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
