"""Whether a mesh is a printable solid: closed, consistently oriented, manifold, its volume and genus.

Two independent tools look at every mesh: its edges counted here (:func:`edge_topology`, in
trimesh's definitions) and manifold3d's own construction of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from numba import njit


@dataclass(frozen=True)
class SolidCheck:
    """What a slicer will ask of a mesh: closed, consistently oriented, manifold, positive volume."""

    watertight: bool
    winding_consistent: bool
    manifold: bool
    manifold_status: str
    volume_mm3: float
    genus: int
    triangles: int
    bbox_min_mm: tuple[float, float, float]
    bbox_max_mm: tuple[float, float, float]

    @property
    def ok(self) -> bool:
        return self.watertight and self.winding_consistent and self.manifold and self.volume_mm3 > 0

    @property
    def size_mm(self) -> tuple[float, float, float]:
        return tuple(float(b - a) for a, b in zip(self.bbox_min_mm, self.bbox_max_mm, strict=True))  # type: ignore[return-value]


def enclosed_volume_mm3(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume a closed, outward-oriented triangle mesh encloses (mm^3): the divergence
    theorem, the sum of ``a . (b x c) / 6`` over the triangles, in float64.

    trimesh's ``volume`` is the same integral, but reached through its mass properties
    (the inertia tensor too): 1.2 s on a 1.4 M-triangle part, against 0.1 s for this.
    """
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    total = 0.0
    for start in range(0, len(tris), 1 << 18):
        part = tris[start : start + (1 << 18)]
        a, b, c = verts[part[:, 0]], verts[part[:, 1]], verts[part[:, 2]]
        total += float(np.einsum("ij,ij->", a, np.cross(b, c)))
    return total / 6.0


@dataclass(frozen=True)
class EdgeTopology:
    """A triangle mesh's edges as trimesh counts them (:func:`edge_topology`)."""

    watertight: bool
    """Every edge (vertex pair, either direction) is in exactly two faces."""
    winding_consistent: bool
    """Every edge in exactly two faces runs one way in one and the other way in the other."""
    euler_number: int
    """Vertices used by a face, minus edges, plus faces."""
    referenced: np.ndarray
    """Which vertices a face uses, ``(n_vertices,)`` bool."""


@njit(cache=True, nogil=True)  # (on the background thread: the main one goes on meanwhile)
def _edge_topology(faces, n_vertices):
    """One pass of an open-addressing hash table over the faces' edges, keyed by their vertex pair."""
    n_edges = 3 * faces.shape[0]
    size = 1
    while size < 2 * n_edges:
        size *= 2
    mask = size - 1
    keys = np.full(size, -1, dtype=np.int64)
    count = np.zeros(size, dtype=np.int32)
    first_to = np.empty(size, dtype=np.int64)  # where the edge's first listing ends
    reversed_pair = np.zeros(size, dtype=np.bool_)  # its second listing starts there
    referenced = np.zeros(n_vertices, dtype=np.bool_)
    unique = 0
    for f in range(faces.shape[0]):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            referenced[a] = True
            key = min(a, b) * n_vertices + max(a, b)
            h = np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)
            slot = np.int64((h ^ (h >> np.uint64(31))) & np.uint64(mask))
            while keys[slot] >= 0 and keys[slot] != key:
                slot = (slot + 1) & mask
            if keys[slot] < 0:
                keys[slot] = key
                first_to[slot] = b
                unique += 1
            elif count[slot] == 1:
                reversed_pair[slot] = first_to[slot] == a
            count[slot] += 1
    watertight = True
    winding = True
    for slot in range(size):
        if count[slot] != 0 and count[slot] != 2:
            watertight = False
        elif count[slot] == 2 and not reversed_pair[slot]:
            winding = False
    used = 0
    for v in range(n_vertices):
        if referenced[v]:
            used += 1
    return watertight, winding, used - unique + faces.shape[0], referenced


def edge_topology(faces: np.ndarray, n_vertices: int) -> EdgeTopology:
    """Whether a triangle mesh is closed and consistently oriented, and its Euler number.

    The definitions are trimesh's (``trimesh.graph.is_watertight`` and ``Trimesh.euler_number``;
    tests/test_mesh.py holds the two equal on closed, open, flipped, non-manifold, degenerate and
    multi-part meshes), counted in one pass of a hash table over the ``3 F`` edges instead of
    sorting and grouping them: 1.5 s of the solid checks on a 1.4 M-triangle part.

    Parameters
    ----------
    faces : (F, 3) int array
        Vertex indices, each in ``[0, n_vertices)``.
    n_vertices : int
        How many vertices the mesh has (used by a face or not).
    """
    tris = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(tris) and (int(tris.min()) < 0 or int(tris.max()) >= n_vertices):
        raise ValueError(
            f"faces: expected vertex indices in [0, {n_vertices}), got {tris.min()}..{tris.max()}"
        )
    watertight, winding, euler, referenced = _edge_topology(tris, int(n_vertices))
    return EdgeTopology(bool(watertight) and len(tris) > 0, bool(winding), int(euler), referenced)


def check_solid(mesh: trimesh.Trimesh) -> SolidCheck:
    """Check a mesh with two independent tools: its edges counted (:func:`edge_topology`, as trimesh
    defines them) and manifold3d."""
    import manifold3d

    m = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )
    status = m.status()
    status_name = getattr(status, "name", str(status))
    manifold_ok = status_name.endswith("NoError")
    vertices = np.asarray(mesh.vertices)
    topology = edge_topology(np.asarray(mesh.faces), len(vertices))
    euler = topology.euler_number
    used = vertices[topology.referenced]
    lo, hi = (used.min(axis=0), used.max(axis=0)) if len(used) else (np.zeros(3), np.zeros(3))
    return SolidCheck(
        watertight=topology.watertight,
        winding_consistent=topology.winding_consistent,
        manifold=manifold_ok,
        manifold_status=status_name.split(".")[-1],
        volume_mm3=enclosed_volume_mm3(mesh.vertices, mesh.faces),
        genus=(2 - euler) // 2,
        triangles=int(len(mesh.faces)),
        bbox_min_mm=tuple(float(v) for v in lo),  # type: ignore[arg-type]
        bbox_max_mm=tuple(float(v) for v in hi),  # type: ignore[arg-type]
    )
