"""Printable meshes: closed slabs from height fields, relief on closed meshes, solidity checks."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from numba import njit, prange

from noise.frames import angle_weighted_normals
from noise.heightfield import HeightField
from printapp.bisection import bisect_long_edges
from printapp.errors import DesignError
from printapp.slab import slab_arrays


def slab_from_heightfield(field: HeightField, base_thickness_mm: float) -> trimesh.Trimesh:
    """The closed slab of :func:`printapp.slab.slab_arrays` as a trimesh (``process=False``)."""
    vertices, faces = slab_arrays(field, base_thickness_mm)
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def read_mesh(path: str | Path, *, merge: bool = False) -> trimesh.Trimesh:
    """Read a triangle mesh file (any format trimesh reads), as it is or with duplicate vertices merged.

    Raises
    ------
    DesignError
        If the file is missing, not a regular file, larger than the memory budget holds
        (a mesh costs about ten times its file's bytes once read), unreadable, or holds
        no triangles.
    """
    from printapp.inputs import regular_file
    from printapp.memory import require

    path = regular_file(path, "mesh")
    require(10.0 * path.stat().st_size, what="reading this mesh", setting=str(path))
    try:
        loaded = trimesh.load(path, force="mesh", process=merge)
    except MemoryError:
        raise DesignError(f"{path}: the mesh does not fit in memory") from None
    except Exception as exc:  # trimesh raises many kinds for malformed files
        raise DesignError(f"{path}: cannot read the mesh ({type(exc).__name__}: {exc})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise DesignError(f"{path}: expected a triangle mesh, found no triangles")
    vertices = np.asarray(loaded.vertices)
    if not np.all(np.isfinite(vertices)):
        raise DesignError(f"{path}: the mesh has vertices at NaN or infinity")
    return loaded


def load_closed_mesh(path: str | Path, scale: float = 1.0, repair: bool = False) -> trimesh.Trimesh:
    """Read a mesh file, merge duplicate vertices, scale it to mm, and insist that it is closed.

    With ``repair``, an open or inconsistently oriented mesh is first closed part by part
    (:func:`repair_mesh`); the result's ``metadata["repair"]`` is its :class:`RepairReport`.

    Raises
    ------
    DesignError
        If the file is missing, unreadable, empty, or not a closed surface.
    """
    loaded = read_mesh(path, merge=True)
    mesh = trimesh.Trimesh(vertices=loaded.vertices * scale, faces=loaded.faces, process=False)
    if repair and not (mesh.is_watertight and mesh.is_winding_consistent):
        mesh, report = repair_mesh(mesh, str(path))
        mesh.metadata["repair"] = report
    if not mesh.is_watertight:
        open_edges = int(np.sum(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1).shape[0]))
        raise DesignError(
            f"{path}: expected a closed (watertight) mesh, found {open_edges} open edges; "
            "`printapp displace --repair` can close it"
        )
    if not mesh.is_winding_consistent:
        raise DesignError(f"{path}: expected consistently oriented triangles, found flipped ones")
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def refined_triangle_bound(mesh: trimesh.Trimesh, max_edge_mm: float) -> int:
    """An upper bound on the triangles :func:`refine_to_edge_length` makes: as if every face
    were split 4-way until its longest edge L is at most ``max_edge_mm``
    (``4^ceil(log2(L / max_edge))`` faces); bisecting only the long edges makes fewer."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    edges = np.stack([v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 1]], v[f[:, 0]] - v[f[:, 2]]], axis=1)
    longest = np.linalg.norm(edges, axis=2).max(axis=1)
    splits = np.ceil(np.log2(np.maximum(longest / max_edge_mm, 1.0)))
    return int(np.sum(4.0 ** np.minimum(splits, 40)))


_GROWTH_PER_HALVING = 4.3
"""Triangles gained by halving the edge length (measured on the CAD part: 4.27; 4 on smooth meshes)."""


def _subdivide(mesh: trimesh.Trimesh, max_edge_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, faces and each face's input face after :func:`bisect_long_edges` (at most 40 rounds)."""
    return bisect_long_edges(np.asarray(mesh.vertices), np.asarray(mesh.faces), max_edge_mm, max_rounds=40)


@dataclass(frozen=True)
class RepairReport:
    """What :func:`repair_mesh` did: parts found, parts closed, solids left after their union."""

    parts_in: int
    closed: int
    solids_out: int

    def sentence(self) -> str:
        parts = "part" if self.parts_in == 1 else "parts"
        solids = "solid" if self.solids_out == 1 else "solids"
        return (
            f"repaired {self.parts_in} {parts}: every one closed ({self.closed} needed it), "
            f"united into {self.solids_out} {solids}"
        )


def repair_mesh(mesh: trimesh.Trimesh, label: str) -> tuple[trimesh.Trimesh, RepairReport]:
    """Close an open mesh part by part, never dropping a part, and unite the parts into one solid.

    Each connected part that is not already closed and consistently oriented is given to
    pymeshfix on its own (Attene's MeshFix fills its holes and removes its degenerate
    and self-intersecting triangles; with several parts at once it keeps only the
    largest, which is how a teapot lost its spout, handle and lid). The closed parts are
    then united with manifold3d, so parts that overlap (a spout through the body) become
    one solid.

    Raises
    ------
    DesignError
        Naming the part (its number, triangles and centre) that cannot be closed, or if
        the union is not a valid solid.
    """
    import manifold3d
    import pymeshfix

    parts = mesh.split(only_watertight=False)
    solids = []
    closed = 0
    for k, part in enumerate(parts, start=1):
        if not (part.is_watertight and part.is_winding_consistent):
            fixer = pymeshfix.MeshFix(np.asarray(part.vertices, np.float64), np.asarray(part.faces, np.int32))
            fixer.repair(remove_smallest_components=False)
            fixed = trimesh.Trimesh(vertices=fixer.points, faces=fixer.faces, process=False)
            if len(fixed.faces) == 0 or not (fixed.is_watertight and fixed.is_winding_consistent):
                centre = ", ".join(f"{c:.3g}" for c in part.bounds.mean(axis=0))
                raise DesignError(
                    f"{label}: part {k} of {len(parts)} ({len(part.faces):,} triangles around ({centre}) mm) "
                    "cannot be closed by the repair; expected parts that enclose a volume"
                )
            closed += 1
            part = fixed
        if part.volume < 0:
            part.invert()
        solids.append(_to_manifold(part))
    united = (
        manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add) if len(solids) > 1 else solids[0]
    )
    status = getattr(united.status(), "name", str(united.status()))
    if not status.endswith("NoError") or united.num_tri() == 0:
        raise DesignError(f"{label}: the repaired parts do not unite into a valid solid ({status})")
    out = united.to_mesh()
    result = trimesh.Trimesh(
        vertices=np.asarray(out.vert_properties)[:, :3].astype(np.float64), faces=out.tri_verts, process=False
    )
    solids_out = len(result.split(only_watertight=False))
    return result, RepairReport(len(parts), closed, solids_out)


def refine_to_edge_length(
    mesh: trimesh.Trimesh, max_edge_mm: float, setting: tuple[str, float] = ("the edge length", 1.0)
) -> trimesh.Trimesh:
    """Split triangles until no edge is longer than ``max_edge_mm``; shared vertices stay shared.

    The result's ``metadata["parent_face"]`` holds, per new triangle, the index of the
    input triangle it lies in. The size is checked against the memory budget first:
    when the upper bound :func:`refined_triangle_bound` does not fit, the mesh is
    refined at twice the edge (a quarter of the work) and the count extrapolated.
    ``setting`` is the design key that set the edge length and its value per millimetre
    of edge, for the refusal's "the largest that fits".

    Raises
    ------
    DesignError
        If the refined mesh would not fit the memory budget (with the finest edge that does).
    """
    from printapp.memory import BASE_BYTES, MESH_BYTES_PER_TRIANGLE, fits, require

    room = fits(MESH_BYTES_PER_TRIANGLE)
    if refined_triangle_bound(mesh, max_edge_mm) > room:
        # Refine a coarser copy (at most about two million triangles) and extrapolate.
        halvings = 1
        while halvings < 20 and refined_triangle_bound(mesh, max_edge_mm * 2.0**halvings) > 2_000_000:
            halvings += 1
        coarse = len(_subdivide(mesh, max_edge_mm * 2.0**halvings)[1])
        expected = coarse * _GROWTH_PER_HALVING**halvings
        finest = max_edge_mm * math.sqrt(expected / max(room, 1.0))
        require(
            BASE_BYTES + expected * MESH_BYTES_PER_TRIANGLE,
            what=f"a relief mesh of about {expected:,.0f} triangles (edges of {max_edge_mm:.4g} mm)",
            setting=setting[0],
            fitting=f"{setting[0]} = {finest * setting[1]:.4g} fits",
        )
    # Merged before, not after: the bisection then makes no duplicate (each midpoint is one
    # edge's), and merging the input's thousands of vertices costs nothing beside the output's
    # (0.46 s on brushed_part's 684k). Merging keeps the faces and their order.
    base = trimesh.Trimesh(vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces), process=False)
    base.merge_vertices()
    vertices, faces, parent = _subdivide(base, max_edge_mm)
    out = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    out.metadata["parent_face"] = np.asarray(parent, dtype=np.int64)
    return out


CREASE_FULL_DEG = 10.0
CREASE_NONE_DEG = 30.0


def crease_weights(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """1 where the surface is smooth around a vertex, fading to 0 at sharp creases and corners.

    A vertex whose normal is within 10 degrees of every incident face keeps the whole
    relief; one that is 30 degrees or more off some face (a CAD part's edges and corners)
    gets none, with a smoothstep between. On a crease the averaged normal points between
    the faces, so moving a crease vertex along it slides it sideways over its neighbours
    and folds thin triangles; moving it not at all cannot.
    """
    worst = np.ones(len(vertices))
    _worst_face_cosine(
        np.ascontiguousarray(vertices, dtype=np.float64),
        np.ascontiguousarray(faces, dtype=np.int64),
        np.ascontiguousarray(normals, dtype=np.float64),
        worst,
    )
    full, none = np.cos(np.radians(CREASE_FULL_DEG)), np.cos(np.radians(CREASE_NONE_DEG))
    t = np.clip((worst - none) / (full - none), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def displace_along_normals(mesh: trimesh.Trimesh, offsets_mm: np.ndarray) -> tuple[trimesh.Trimesh, int]:
    """Move each vertex outward along its angle-weighted normal by ``offsets_mm`` (mm), without folds.

    The offsets fade out at sharp creases (see :func:`crease_weights`), over twice the
    largest offset around them (so that reliefs on the two sides of a concave edge cannot
    meet). Where a triangle
    would still turn over (thin triangles where the normals turn, as on the fillets of a
    CAD mesh, or concave regions tighter than the relief is deep), the offsets of its
    vertices are halved until it does not, and zeroed after twelve halvings; the number of
    vertices so softened is returned, to be reported. Connectivity is unchanged, so a
    closed mesh stays closed.
    """
    vertices = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    normals = angle_weighted_normals(vertices, faces)
    weights = crease_weights(vertices, faces, normals)
    reach = 2.0 * float(np.max(offsets_mm)) if len(offsets_mm) else 0.0
    sharp = weights < 1.0
    if reach > 0 and sharp.any() and not sharp.all():
        # Fade over twice the relief's height around sharp creases: in a concave corner the
        # two faces' reliefs then grow towards each other with a slope below one, and
        # cannot pass through each other.
        from scipy.spatial import cKDTree

        # Only distances within the fade matter: farther ones come back infinite, which the
        # search then need not find.
        distance, _ = cKDTree(vertices[sharp]).query(vertices, distance_upper_bound=reach, workers=-1)
        t = np.clip(distance / reach, 0.0, 1.0)
        weights = np.minimum(weights, t * t * (3.0 - 2.0 * t))
    offsets = offsets_mm * weights
    before = _face_normals_unnormalised(vertices, faces)
    softened = np.zeros(len(vertices), dtype=bool)
    flipped = np.empty(len(faces), dtype=np.bool_)
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    for attempt in range(13):
        moved = vertices + normals * offsets[:, None]
        _turned_over(before, moved, tris, flipped)
        if not flipped.any():
            break
        corners = np.unique(faces[flipped])
        softened[corners] = True
        offsets[corners] = 0.0 if attempt == 11 else offsets[corners] * 0.5
    return trimesh.Trimesh(vertices=moved, faces=mesh.faces, process=False), int(softened.sum())


@njit(cache=True)
def _corner_cross(vertices, a, b, c):
    """``(v_b - v_a) x (v_c - v_a)`` as three floats (no array is made)."""
    e1x, e1y, e1z = (
        vertices[b, 0] - vertices[a, 0],
        vertices[b, 1] - vertices[a, 1],
        vertices[b, 2] - vertices[a, 2],
    )
    e2x, e2y, e2z = (
        vertices[c, 0] - vertices[a, 0],
        vertices[c, 1] - vertices[a, 1],
        vertices[c, 2] - vertices[a, 2],
    )
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True)
def _worst_face_cosine(vertices, faces, normals, worst) -> None:
    """``worst[v]``: the least cosine between vertex v's normal and the unit normals of its faces."""
    for f in range(faces.shape[0]):
        nx, ny, nz = _corner_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        length = max(math.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
        for k in range(3):
            v = faces[f, k]
            cos = (normals[v, 0] * nx + normals[v, 1] * ny + normals[v, 2] * nz) / length
            if cos < worst[v]:
                worst[v] = cos


@njit(cache=True, parallel=True)
def _face_cross(vertices, faces, out) -> None:
    for f in prange(faces.shape[0]):
        out[f, 0], out[f, 1], out[f, 2] = _corner_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])


@njit(cache=True, parallel=True)
def _turned_over(before, vertices, faces, out) -> None:
    """``out[f]``: whether face f's normal at ``vertices`` points against ``before[f]`` (or vanishes)."""
    for f in prange(faces.shape[0]):
        nx, ny, nz = _corner_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        out[f] = before[f, 0] * nx + before[f, 1] * ny + before[f, 2] * nz <= 0.0


def _face_normals_unnormalised(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each face's ``(v1 - v0) x (v2 - v0)`` (twice its area along its normal), float64."""
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    out = np.empty((len(tris), 3))
    _face_cross(np.ascontiguousarray(vertices, dtype=np.float64), tris, out)
    return out


def folded_triangles(before: trimesh.Trimesh, after: trimesh.Trimesh) -> int:
    """How many triangles turned over (normal reversed) between two meshes with the same faces.

    A fold is what a displacement larger than the local radius of curvature makes, and a
    slicer would see it as a self-intersection.
    """
    a = _face_normals_unnormalised(np.asarray(before.vertices), np.asarray(before.faces))
    turned = np.empty(len(a), dtype=np.bool_)
    _turned_over(
        a,
        np.ascontiguousarray(after.vertices, dtype=np.float64),
        np.ascontiguousarray(after.faces, dtype=np.int64),
        turned,
    )
    return int(np.count_nonzero(turned))


def _to_manifold(mesh: trimesh.Trimesh):
    import manifold3d

    return manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )


def combine_solids(mesh: trimesh.Trimesh, operations) -> trimesh.Trimesh:
    """Apply booleans (union, difference, intersection) with boxes or closed meshes, in order.

    ``operations`` are :class:`printapp.design.Combine` records. manifold3d guarantees a
    manifold result (the talk's "two meshes: how to combine?").

    Raises
    ------
    DesignError
        If an operand mesh is unusable or the result is empty.
    """
    import manifold3d

    result = _to_manifold(mesh)
    for index, op in enumerate(operations):
        if op.shape == "box":
            other = manifold3d.Manifold.cube(list(op.size_mm), center=True)
        else:
            other = _to_manifold(load_closed_mesh(op.path, op.scale))
        other = other.translate(list(op.translate_mm))
        if op.op == "union":
            result = result + other
        elif op.op == "difference":
            result = result - other
        else:
            result = result ^ other
        if result.is_empty():
            raise DesignError(f"combine[{index}]: the {op.op} leaves nothing of the model")
    out = result.to_mesh()
    return trimesh.Trimesh(
        vertices=np.asarray(out.vert_properties[:, :3], dtype=np.float64),
        faces=np.asarray(out.tri_verts, dtype=np.int64),
        process=False,
    )


@dataclass(frozen=True)
class WindingVerdict:
    """What the layers' winding numbers say about a surface passing through itself."""

    ok: bool
    """False where the surface passes through itself (winding >= 1.5 in some layer)."""
    slight: bool
    """An overlap of less than half a pixel: noted, not failed (the printer cures the union)."""
    message: str


def winding_verdict(winding: float) -> WindingVerdict:
    """Judge the largest pixel-averaged winding number of a model's layers.

    Winding 1 inside a solid; 2 where the surface passes through itself. The printer
    cures the union either way, so overlaps of less than half a pixel are noted, not failed.
    """
    if winding <= 1.01:
        return WindingVerdict(True, False, "the layers show no self-overlap (winding number 1)")
    if winding < 1.5:
        return WindingVerdict(
            True,
            True,
            f"the surface overlaps itself by less than half a pixel somewhere (pixel-averaged "
            f"winding number {winding:.2f}); the printer cures the union",
        )
    return WindingVerdict(
        False,
        False,
        f"the model overlaps itself (winding number {winding:.2f} in some layer): "
        "its surface passes through itself",
    )
