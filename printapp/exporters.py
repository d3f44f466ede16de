"""Output formats: binary STL, 3MF, PLY, OBJ with its MTL, PNG; meshes written by their suffix."""

from __future__ import annotations

import functools
import struct
import zlib
from pathlib import Path
from typing import BinaryIO

import numpy as np

from printapp.errors import DesignError
from printapp.outputs import FileContent

_STL_HEADER = b"printapp binary STL; units: mm".ljust(80, b" ")
STL_RECORD = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])
"""One binary STL triangle: facet normal, three corners (float32, mm), attribute bytes."""


def _stl_chunks(vertices: np.ndarray, faces: np.ndarray, chunk: int = 1 << 15):
    """The records of a binary STL in chunks: ``(first triangle, records)``, facet normals unit
    vectors computed in float64. Two buffers take turns, so a chunk stays valid while the next
    is built (a writer thread may still be writing it)."""
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    n = len(tris)
    buffers = [np.zeros(min(chunk, max(n, 1)), dtype=STL_RECORD) for _ in range(2)]
    for index, start in enumerate(range(0, n, chunk)):
        part = tris[start : start + chunk]
        a, b, c = verts[part[:, 0]], verts[part[:, 1]], verts[part[:, 2]]
        e1, e2 = b - a, c - a
        normal = np.empty_like(a)
        normal[:, 0] = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
        normal[:, 1] = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
        normal[:, 2] = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        length = np.sqrt(
            normal[:, 0] * normal[:, 0] + normal[:, 1] * normal[:, 1] + normal[:, 2] * normal[:, 2]
        )
        np.divide(normal, length[:, None], out=normal, where=length[:, None] > 0)
        rows = buffers[index % 2][: len(part)]
        rows["normal"] = normal
        corners = rows["vertices"]
        corners[:, 0], corners[:, 1], corners[:, 2] = a, b, c
        yield start, rows


def _stl_header(n: int) -> bytes:
    return _STL_HEADER + n.to_bytes(4, "little")


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytearray:
    """A binary STL of a triangle mesh (mm), with unit facet normals computed in float64.

    The header is fixed, so the same mesh always gives the same bytes. Plain numpy, in
    chunks that stay in cache: loading a numba kernel would cost `printapp emboss` more
    (0.5 s) than the whole of this.
    """
    n = len(faces)
    buffer = bytearray(84 + 50 * n)
    buffer[:84] = _stl_header(n)
    records = np.frombuffer(buffer, dtype=STL_RECORD, offset=84)
    for start, rows in _stl_chunks(vertices, faces):
        records[start : start + len(rows)] = rows
    return buffer


def write_stl(handle: BinaryIO, vertices: np.ndarray, faces: np.ndarray) -> None:
    """:func:`stl_bytes`, written to ``handle`` chunk by chunk as it is built: a thread writes one
    chunk while the next is computed, and the whole file is never held in memory (for
    `emboss`'s 2-million-triangle slabs, 105 MB)."""
    from concurrent.futures import ThreadPoolExecutor

    handle.write(_stl_header(len(faces)))
    with ThreadPoolExecutor(max_workers=1) as writer:
        pending = None
        for _, rows in _stl_chunks(vertices, faces):
            if pending is not None:
                pending.result()  # the buffer about to be reused has been written
            pending = writer.submit(handle.write, memoryview(rows).cast("B"))
        if pending is not None:
            pending.result()


def threemf_bytes(vertices: np.ndarray, faces: np.ndarray, name: str = "printapp model") -> bytes:
    """A 3MF package (3MF Core Specification 1.3) holding one mesh object in mm.

    Zip entries carry a fixed timestamp and no random ids, so output is deterministic.
    """
    from printapp.decimal_text import triangle_elements

    verts = np.asarray(vertices, dtype=np.float32)
    # One %-format over many vertices is several times faster than a per-element f-string; a few
    # thousand at a time, because one such call holds the GIL throughout (a whole 1.4 M-triangle
    # part's took 1 s, stalling the light sweep that the model files are written beside).
    vertex_xml = [
        (('<vertex x="%.9g" y="%.9g" z="%.9g"/>' * len(part)) % tuple(part.ravel().tolist())).encode()
        for part in np.array_split(verts, max(1, len(verts) // 4096))
    ]
    safe_name = name.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
    model = b"".join(
        [
            (
                '<?xml version="1.0" encoding="UTF-8"?>\n'
                '<model unit="millimeter" xml:lang="en-US" '
                'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
                '<metadata name="Application">printapp</metadata>'
                f'<resources><object id="1" type="model" name="{safe_name}"><mesh><vertices>'
            ).encode(),
            *vertex_xml,
            b"</vertices><triangles>",
            triangle_elements(faces),
            b'</triangles></mesh></object></resources><build><item objectid="1"/></build></model>',
        ]
    )
    content_types = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
        '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
        '<Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
        "</Types>"
    )
    rels = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
        '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
        'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
        "</Relationships>"
    )
    return zip_bytes(
        [
            ("[Content_Types].xml", content_types.encode("utf-8")),
            ("_rels/.rels", rels.encode("utf-8")),
            ("3D/3dmodel.model", model),
        ]
    )


def zip_bytes(entries: list[tuple[str, bytes]]) -> bytes:
    """A zip archive (PKWARE APPNOTE 6.3) of ``(name, data)`` entries, each deflated by ISA-L.

    Written here rather than through :mod:`zipfile` for the compressor: ISA-L's level 3
    deflates a 26 MB 3MF model in 0.06 s, to a smaller file than zlib's level 6 does in 0.29 s.
    Every entry is dated 1980-01-01 00:00, so the same entries give the same bytes.
    """
    from isal import isal_zlib

    archive, directory = bytearray(), bytearray()
    date = (1 << 5) | 1  # 1980-01-01 in MS-DOS format; the time is 00:00
    for name, data in entries:
        raw_name = name.encode("ascii")
        packer = isal_zlib.compressobj(3, isal_zlib.DEFLATED, -15)
        deflated = packer.compress(data) + packer.flush()
        crc = zlib.crc32(data) & 0xFFFFFFFF
        offset = len(archive)
        if max(len(data), len(deflated), offset) >= 0xFFFFFFFF:
            raise DesignError(f"{name}: over 4 GB, more than a zip without ZIP64 extensions holds")
        sizes = (crc, len(deflated), len(data), len(raw_name), 0)
        archive += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, date, *sizes) + raw_name + deflated
        directory += struct.pack(
            "<IHHHHHHIIIHHHHHII", 0x02014B50, 0x0314, 20, 0, 8, 0, date, *sizes, 0, 0, 0, 0, offset
        )
        directory += raw_name
    end = struct.pack(
        "<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries), len(directory), len(archive), 0
    )
    return bytes(archive + directory + end)


def ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary little-endian PLY (float32 vertices in mm, int32 triangle lists)."""
    verts = np.asarray(vertices, dtype="<f4")
    tris = np.asarray(faces)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment printapp, units: mm\n"
        f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    record = np.dtype([("n", "u1"), ("v", "<i4", 3)])
    face_data = np.zeros(len(tris), dtype=record)
    face_data["n"] = 3
    face_data["v"] = tris
    return header + verts.tobytes() + face_data.tobytes()


def obj_files(vertices: np.ndarray, faces: np.ndarray, stem: str, refractive_index: float) -> tuple[str, str]:
    """A Wavefront OBJ with smooth (angle-weighted) vertex normals, and its .mtl.

    The material is the talk's edit, done for the user: ``Ni`` is the resin's refractive
    index and ``illum 4`` asks renderers for reflection and refraction (glass).
    """
    from noise.frames import angle_weighted_normals

    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64) + 1
    normals = angle_weighted_normals(verts, tris - 1)
    lines = [f"# printapp, units: mm\nmtllib {stem}.mtl\nusemtl resin\n"]
    lines.append(("v %.9g %.9g %.9g\n" * len(verts)) % tuple(verts.ravel().tolist()))
    lines.append(("vn %.6f %.6f %.6f\n" * len(verts)) % tuple(normals.ravel().tolist()))
    face_rows = np.repeat(tris, 2, axis=1).ravel().tolist()
    lines.append(("f %d//%d %d//%d %d//%d\n" * len(tris)) % tuple(face_rows))
    mtl = (
        "# printapp resin\nnewmtl resin\nKa 0 0 0\nKd 0.8 0.8 0.8\nKs 1 1 1\nNs 500\n"
        f"Ni {refractive_index:g}\nd 1\nillum 4\n"
    )
    return "".join(lines), mtl


MESH_SUFFIXES = (".stl", ".3mf", ".ply", ".obj")
"""Mesh files printapp writes, chosen by the output's suffix."""


def check_mesh_output(out: Path) -> None:
    """Refuse an output name whose suffix is not a mesh format printapp writes.

    Raises
    ------
    DesignError
        Naming the file and the suffixes expected.
    """
    if out.suffix.lower() not in MESH_SUFFIXES:
        raise DesignError(f"{out}: expected an output file ending in .stl, .3mf, .ply or .obj")


def mesh_files(
    out: Path,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    name: str | None = None,
    refractive_index: float = 1.5,
) -> list[tuple[Path, FileContent]]:
    """The file(s) that hold a mesh written as ``out``, by its suffix: ``(path, content)`` pairs
    (an STL is streamed: its content writes it to an open file).

    ``.stl`` (binary), ``.3mf``, ``.ply`` (binary), or ``.obj`` with its ``.mtl`` beside it
    (the resin's ``refractive_index`` as ``Ni``). ``name`` names the 3MF object (default:
    the file's stem).
    """
    check_mesh_output(out)
    suffix = out.suffix.lower()
    if suffix == ".stl":
        return [(out, functools.partial(write_stl, vertices=vertices, faces=faces))]
    if suffix == ".3mf":
        return [(out, threemf_bytes(vertices, faces, name or out.stem))]
    if suffix == ".ply":
        return [(out, ply_bytes(vertices, faces))]
    obj, mtl = obj_files(vertices, faces, out.stem, refractive_index)
    return [(out, obj.encode("utf-8")), (out.with_suffix(".mtl"), mtl.encode("utf-8"))]


def write_mesh(
    out: Path,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    name: str | None = None,
    refractive_index: float = 1.5,
) -> list[Path]:
    """Write a mesh by the output's suffix (see :func:`mesh_files`), all files or none."""
    from printapp.outputs import atomic_write_files

    return atomic_write_files(mesh_files(out, vertices, faces, name=name, refractive_index=refractive_index))


def png_bytes(image_srgb8: np.ndarray) -> bytes:
    """An 8-bit RGB (or grey) image as PNG bytes (same pixels, same bytes)."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.asarray(image_srgb8, dtype=np.uint8)).save(
        buffer, format="png", optimize=False, compress_level=6
    )
    return buffer.getvalue()
