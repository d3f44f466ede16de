"""Orthonormal bases from unit normals, and vertex normals and frames on triangle meshes.

Two bases (both right-handed: b1 x b2 = n):

* ``"frisvad"``: Frisvad (2012), "Building an orthonormal basis from a 3D unit vector
  without normalization", JGT 16(3). Branch-free except for the singularity at
  n = (0, 0, -1), which it handles with a threshold on n.z.
* ``"duff"``: Duff et al. (2017), "Building an orthonormal basis, revisited", JCGT 6(1).
  The default. Frisvad's ``a = 1 / (1 + n.z)`` cancels catastrophically as n.z -> -1
  (near the threshold, in float32 from about 1 + n.z < 1e-3), and the basis loses its
  orthonormality; Duff et al. choose the sign s = copysign(1, n.z) so that the
  denominator ``s + n.z`` never cancels, which is exact to rounding everywhere.

On meshes: angle-weighted vertex normals, per-vertex and per-face frames, and frames
that follow a direction field (:func:`surface_frames`), isotropic around the field's
singular points (:func:`singular_faces`), for the noise of :mod:`noise.framed`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

ONB_METHODS = ("duff", "frisvad")


# The constant ``one`` is passed in the array's own dtype, so that float32 input is
# computed in float32 throughout (a float64 literal would silently widen it).


@njit(cache=True, parallel=True)
def _onb_frisvad(n: np.ndarray, b1: np.ndarray, b2: np.ndarray, one, threshold) -> None:
    for k in prange(n.shape[0]):
        x, y, z = n[k, 0], n[k, 1], n[k, 2]
        if z < threshold:
            b1[k, 0], b1[k, 1], b1[k, 2] = 0.0, -1.0, 0.0
            b2[k, 0], b2[k, 1], b2[k, 2] = -1.0, 0.0, 0.0
            continue
        a = one / (one + z)
        b = -x * y * a
        b1[k, 0], b1[k, 1], b1[k, 2] = one - x * x * a, b, -x
        b2[k, 0], b2[k, 1], b2[k, 2] = b, one - y * y * a, -y


@njit(cache=True, parallel=True)
def _onb_duff(n: np.ndarray, b1: np.ndarray, b2: np.ndarray, one) -> None:
    for k in prange(n.shape[0]):
        x, y, z = n[k, 0], n[k, 1], n[k, 2]
        s = np.copysign(one, z)  # not sign(z), which is 0 at z = 0
        a = -one / (s + z)
        b = x * y * a
        b1[k, 0], b1[k, 1], b1[k, 2] = one + s * x * x * a, s * b, -s * x
        b2[k, 0], b2[k, 1], b2[k, 2] = b, s + y * y * a, -y


def _as_normals(normals: np.ndarray, normalize: bool) -> np.ndarray:
    arr = np.asarray(normals)
    if arr.dtype not in (np.float32, np.float64):
        arr = arr.astype(np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"normals: expected an (n, 3) array, got shape {np.shape(normals)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("normals: expected finite values, found NaN or infinity")
    length = np.linalg.norm(arr.astype(np.float64), axis=1)
    if np.any(length < 1e-12):
        raise ValueError(f"normals: {int(np.sum(length < 1e-12))} zero-length vectors have no direction")
    if normalize:
        arr = (arr / length[:, None]).astype(arr.dtype)
    else:
        tolerance = 1e-3 if arr.dtype == np.float32 else 1e-6
        worst = float(np.max(np.abs(length - 1.0)))
        if worst > tolerance:
            raise ValueError(
                f"normals: expected unit vectors, found a length off by {worst:.3g}; pass normalize=True"
            )
    arr = np.ascontiguousarray(arr)
    # A read-only array (trimesh's cached normals) is another type to numba: a compilation.
    return arr if arr.flags.writeable else arr.copy()


def onb(
    normals: np.ndarray, method: str = "duff", *, normalize: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Tangent vectors completing each unit normal to a right-handed orthonormal basis.

    Parameters
    ----------
    normals : (n, 3) or (3,) float32 or float64 array
        Unit normals. The dtype is kept (other dtypes become float64).
    method : {"duff", "frisvad"}
        Duff et al. (2017), the default, or Frisvad (2012); see the module docstring
        for why Frisvad's fails near n = (0, 0, -1).
    normalize : bool
        Normalise the input first instead of requiring unit length.

    Returns
    -------
    b1, b2 : arrays shaped like ``normals``
        With (b1, b2, n) orthonormal and b1 x b2 = n.

    Raises
    ------
    ValueError
        For non-finite, zero-length or (without ``normalize``) non-unit normals.
    """
    if method not in ONB_METHODS:
        raise ValueError(f"method: expected one of {ONB_METHODS}, got {method!r}")
    single = np.ndim(normals) == 1
    n = _as_normals(normals, normalize)
    b1 = np.empty_like(n)
    b2 = np.empty_like(n)
    one = n.dtype.type(1.0)
    if method == "duff":
        _onb_duff(n, b1, b2, one)
    else:
        _onb_frisvad(n, b1, b2, one, n.dtype.type(-0.9999999))
    return (b1[0], b2[0]) if single else (b1, b2)


@njit(cache=True, parallel=True)
def _face_normals_and_angles(
    verts: np.ndarray, tris: np.ndarray, normal: np.ndarray, angle: np.ndarray
) -> None:
    for f in prange(tris.shape[0]):
        for k in range(3):
            a, b, c = tris[f, k], tris[f, (k + 1) % 3], tris[f, (k + 2) % 3]
            e1x, e1y, e1z = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
            e2x, e2y, e2z = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
            cx, cy, cz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
            sine = math.sqrt(cx * cx + cy * cy + cz * cz)
            if k == 0:  # the face's normal, from its first corner (as the faces' own orientation)
                length = max(sine, 1e-300)
                normal[f, 0], normal[f, 1], normal[f, 2] = cx / length, cy / length, cz / length
            # The corner's angle from both its sine and cosine: exact for slivers too, where the
            # arc cosine of a cosine near 1 loses half its digits.
            angle[f, k] = math.atan2(sine, e1x * e2x + e1y * e2y + e1z * e2z)


@njit(cache=True)
def _accumulate_normals(tris: np.ndarray, normal: np.ndarray, angle: np.ndarray, out: np.ndarray) -> None:
    # Serial, in face order: a vertex's sum is added up in the same order on any thread count.
    for f in range(tris.shape[0]):
        for k in range(3):
            v = tris[f, k]
            out[v, 0] += normal[f, 0] * angle[f, k]
            out[v, 1] += normal[f, 1] * angle[f, k]
            out[v, 2] += normal[f, 2] * angle[f, k]
    for v in range(out.shape[0]):
        length = max(math.sqrt(out[v, 0] ** 2 + out[v, 1] ** 2 + out[v, 2] ** 2), 1e-300)
        out[v, 0] /= length
        out[v, 1] /= length
        out[v, 2] /= length


def angle_weighted_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex pseudo-normals: face normals weighted by the face's angle at the vertex.

    Thürmer & Wüthrich (1998); Bærentzen & Aanæs (2005) show these make inside and
    outside tests on a closed mesh consistent (the talk's choice of vertex normal).
    Numba kernels: the faces' normals and corner angles (``atan2(|e1 x e2|, e1 . e2)``) in
    parallel, then their sums in face order (the same bits on any thread count);
    ``printapp/bench/reference/vertex_normals.py`` is the plain numpy version it is tested against.

    Parameters
    ----------
    vertices : (n, 3) float array
    faces : (m, 3) int array, counter-clockwise seen from outside

    Returns
    -------
    (n, 3) float64 array; vertices used by no face get (0, 0, 0).
    """
    verts = np.ascontiguousarray(vertices, dtype=np.float64)
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise ValueError(f"vertices: expected an (n, 3) array, got shape {verts.shape}")
    if tris.ndim != 2 or tris.shape[1] != 3 or (tris.size and (tris.min() < 0 or tris.max() >= len(verts))):
        raise ValueError("faces: expected an (m, 3) array of vertex indices")
    face_normal = np.empty((len(tris), 3))
    corner_angle = np.empty((len(tris), 3))
    _face_normals_and_angles(verts, tris, face_normal, corner_angle)
    normals = np.zeros_like(verts)
    _accumulate_normals(tris, face_normal, corner_angle, normals)
    return normals


def vertex_frames(
    vertices: np.ndarray, faces: np.ndarray, method: str = "duff"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-vertex tangent frames (n, b1, b2) from angle-weighted pseudo-normals."""
    n = angle_weighted_normals(vertices, faces)
    b1, b2 = onb(n, method, normalize=True)
    return n, b1, b2


def face_frames(
    vertices: np.ndarray, faces: np.ndarray, method: str = "duff"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-triangle tangent frames (n, b1, b2) from the triangles' geometric normals."""
    verts = np.asarray(vertices, dtype=np.float64)
    tri = verts[np.asarray(faces, dtype=np.int64)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    b1, b2 = onb(n, method, normalize=True)
    return n / np.linalg.norm(n, axis=1, keepdims=True), b1, b2


# ---------------------------------------------------------------------------------------------
# Tangent frames that follow a direction field on a mesh


@dataclass(frozen=True)
class SurfaceFrames:
    """A tangent frame (t, b, n) per vertex, and how far each vertex is from the field's singular points."""

    tangent: np.ndarray
    """(n, 3) unit t: the field projected into the tangent plane; the ONB's first vector where singular."""
    bitangent: np.ndarray
    """(n, 3) unit b = n x t; the ONB's second vector where singular."""
    normal: np.ndarray
    """(n, 3) unit angle-weighted normals."""
    blend: np.ndarray
    """(n,) in [0, 1]: 0 at singular vertices, a smoothstep of the distance to the nearest one, 1 beyond
    the radius (everywhere, when there are none)."""
    singular: np.ndarray
    """(n,) bool: the field vanishes at the vertex, or turns about a triangle the vertex is a corner of."""

    @property
    def singular_count(self) -> int:
        return int(np.count_nonzero(self.singular))


@njit(cache=True, parallel=True)
def _turning_faces(vertices, faces, field, normals, crease_cos, out) -> None:
    for f in prange(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1 = vertices[b] - vertices[a]
        e2 = vertices[c] - vertices[a]
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        nn = math.sqrt(nx * nx + ny * ny + nz * nz)
        ll = math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
        if nn == 0.0 or ll == 0.0:
            out[f] = False
            continue
        nx, ny, nz = nx / nn, ny / nn, nz / nn
        crease = False
        for k in range(3):
            v = faces[f, k]
            crease = crease or normals[v, 0] * nx + normals[v, 1] * ny + normals[v, 2] * nz < crease_cos
        if crease:  # the corners' frames average differently oriented faces: their turn is the crease's
            out[f] = False
            continue
        ux, uy, uz = e1[0] / ll, e1[1] / ll, e1[2] / ll
        vx, vy, vz = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
        live = True
        angles = np.empty(3)
        for k in range(3):
            t = field[faces[f, k]]
            u = t[0] * ux + t[1] * uy + t[2] * uz
            v = t[0] * vx + t[1] * vy + t[2] * vz
            length = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
            live = live and math.hypot(u, v) > 1e-9 * max(length, 1e-300)
            angles[k] = math.atan2(v, u)
        total = 0.0
        for k in range(3):
            step = angles[(k + 1) % 3] - angles[k]
            total += (step + 0.5 * math.pi) % math.pi - 0.5 * math.pi
        out[f] = live and abs(total) > 0.5 * math.pi


CREASE_DEG = 30.0
"""A triangle with a corner normal this far from its own normal sits on a crease (see singular_faces)."""


def singular_faces(
    vertices: np.ndarray, faces: np.ndarray, field: np.ndarray, normals: np.ndarray | None = None
) -> np.ndarray:
    """Triangles around which a line field turns: its index there is not zero.

    Each corner's field vector is projected into the triangle's plane and measured as an
    angle; the angle steps along the three edges, each taken modulo pi into
    [-pi/2, pi/2) (a line field has no sign), add up to a multiple of pi: zero for a
    regular triangle, +-pi for an index +-1/2 singularity, +-2pi for +-1 (the vortex
    at a pole of circles about an axis, the two zeros every tangent field on a sphere
    has, by the hairy-ball theorem). Triangles with a corner where the field vanishes
    are not counted here (that vertex is singular itself). Neither are triangles on a
    crease (a corner's normal ``CREASE_DEG`` or more from the triangle's; ``normals``
    default to the angle-weighted ones): there each corner's field lies in a plane
    averaged over differently oriented faces, and turns with the crease, not the field.
    A CAD part's edges would otherwise all look singular.

    Returns
    -------
    (m,) bool array
    """
    verts = np.ascontiguousarray(vertices, dtype=np.float64)
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    vec = np.ascontiguousarray(field, dtype=np.float64)
    if verts.ndim != 2 or verts.shape[1] != 3 or vec.shape != verts.shape:
        raise ValueError("vertices, field: expected (n, 3) arrays of the same shape")
    if tris.ndim != 2 or tris.shape[1] != 3 or (tris.size and (tris.min() < 0 or tris.max() >= len(verts))):
        raise ValueError("faces: expected an (m, 3) array of vertex indices")
    n = (
        angle_weighted_normals(verts, tris)
        if normals is None
        else np.ascontiguousarray(normals, dtype=np.float64)
    )
    if n.shape != verts.shape:
        raise ValueError(f"normals: expected one per vertex, shape {verts.shape}, got {n.shape}")
    out = np.empty(len(tris), dtype=np.bool_)
    _turning_faces(verts, tris, vec, n, math.cos(math.radians(CREASE_DEG)), out)
    return out


def surface_frames(
    vertices: np.ndarray,
    faces: np.ndarray,
    field: np.ndarray | None,
    *,
    blend_radius: float,
    method: str = "duff",
    normals: np.ndarray | None = None,
) -> SurfaceFrames:
    """Per-vertex tangent frames that follow a direction field, isotropic around its singular points.

    The normal n is the angle-weighted pseudo-normal; the tangent t is the field
    projected into the tangent plane and normalised; the bitangent is b = n x t. Where
    the field vanishes or turns about a triangle (see :func:`singular_faces`), and
    everywhere when ``field`` is None, (t, b) is the orthonormal basis of n
    (:func:`onb`: Duff et al. 2017 by default, Frisvad 2012 selectable) and ``blend``
    is 0: the noise built on these frames is isotropic there, and the stretch returns
    over ``blend_radius`` (a smoothstep of the straight-line distance to the nearest
    singular vertex, a lower bound of the distance along the surface).

    Parameters
    ----------
    vertices : (n, 3) float array
        Positions (mm, or any unit; ``blend_radius`` is in the same unit).
    faces : (m, 3) int array
        Triangles, counter-clockwise seen from outside.
    field : (n, 3) float array or None
        A direction per vertex, of any length (zero where it vanishes); only its
        direction up to sign matters.
    blend_radius : float
        Distance from a singular vertex at which the full stretch returns, > 0.
    method : {"duff", "frisvad"}
        The orthonormal basis where the field gives no direction.
    normals : (n, 3) float array, optional
        The vertices' :func:`angle_weighted_normals`, when already computed.

    Returns
    -------
    SurfaceFrames
    """
    if method not in ONB_METHODS:
        raise ValueError(f"method: expected one of {ONB_METHODS}, got {method!r}")
    if not (np.isfinite(blend_radius) and blend_radius > 0):
        raise ValueError(f"blend_radius: expected a positive distance, got {blend_radius!r}")
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    if normals is None:
        n = angle_weighted_normals(verts, tris)
    else:
        n = np.array(normals, dtype=np.float64)
        if n.shape != verts.shape:
            raise ValueError(f"normals: expected one per vertex, shape {verts.shape}, got {n.shape}")
    unused = np.linalg.norm(n, axis=1) < 0.5
    n[unused] = (0.0, 0.0, 1.0)  # vertices of no face: any frame will do
    b1, b2 = onb(n, method, normalize=True)
    if field is None:
        t = b1.copy()
        singular = np.ones(len(verts), dtype=bool)
    else:
        vec = np.asarray(field, dtype=np.float64)
        if vec.shape != verts.shape or not np.all(np.isfinite(vec)):
            raise ValueError(f"field: expected finite vectors shaped like the vertices {verts.shape}")
        t = vec - np.einsum("ij,ij->i", vec, n)[:, None] * n
        length = np.linalg.norm(t, axis=1)
        singular = length <= 1e-9 * np.maximum(np.linalg.norm(vec, axis=1), 1e-300)
        singular |= unused
        singular[tris[singular_faces(verts, tris, t, n)].ravel()] = True
        t = np.where(singular[:, None], b1, t / np.maximum(length, 1e-300)[:, None])
    if singular.all():
        blend = np.zeros(len(verts))
    elif not singular.any():
        blend = np.ones(len(verts))
    else:
        from scipy.spatial import cKDTree

        # Bounded: beyond the radius the distance does not matter (inf), and far points cost nothing.
        distance = np.zeros(len(verts))
        distance[~singular], _ = cKDTree(verts[singular]).query(
            verts[~singular], distance_upper_bound=blend_radius, workers=-1
        )
        x = np.clip(distance / blend_radius, 0.0, 1.0)
        blend = x * x * (3.0 - 2.0 * x)
    b = np.where(singular[:, None], b2, np.cross(n, t))
    return SurfaceFrames(t, b, n, blend, singular)
