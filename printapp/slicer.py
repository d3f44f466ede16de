"""``printapp slice``: a closed mesh file to a PrusaSlicer-compatible ``.sl1`` (and a PNG stack)."""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from printapp.errors import DesignError


def _png_stack_file(name: str) -> bool:
    """Files of a PNG stack that a previous ``--png-dir`` run may have left."""
    return name == "config.ini" or (len(name) == 9 and name.endswith(".png") and name[:5].isdigit())


def _load_for_slicing(model: Path) -> tuple[Any, Any]:
    """Vertices and faces of a closed mesh: binary STL straight into numpy, else through trimesh.

    The fast path keeps trimesh (a second to import) out of the common case; a binary
    STL whose vertices only nearly coincide, or any other format, takes the general path.
    """
    from printapp.inputs import regular_file
    from printapp.stl import is_binary_stl, load_closed_stl

    path = regular_file(model, "mesh")
    with open(path, "rb") as handle:
        head = handle.read(84)
    if is_binary_stl(head, path.stat().st_size):
        try:
            return load_closed_stl(path)
        except DesignError as exc:
            if "open edges" not in str(exc):
                raise
    from printapp.mesh import load_closed_mesh

    mesh = load_closed_mesh(model)
    return mesh.vertices, mesh.faces


@dataclass(frozen=True)
class Sliced:
    """The layers of a model and what was written."""

    slices: Any
    """:class:`slicing.Slices`."""
    volume_ml: float
    printer_label: str
    written: list[Path]


def slice_model_file(
    model: Path,
    out: Path,
    *,
    printer: str = "prusa-sl1",
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
    png_dir: Path | None = None,
) -> Sliced:
    """Slice a closed mesh (mm) for ``printer`` into ``out`` (``.sl1``), and optionally a PNG stack.

    The PNG stack (with the archive's ``config.ini``) is staged first and moved into
    ``png_dir`` only once the archive is written.

    Raises
    ------
    DesignError
        For an unknown printer, a wrong suffix, a mesh that is not closed, or a model
        the printer cannot hold (layer height, size).
    """
    from printapp.outputs import OutputFolder, atomic_write_bytes
    from slicing import UnknownPrinterError, find_printer, slice_mesh, write_sl1
    from slicing.sl1 import encoded_layers

    try:
        profile = find_printer(printer)
    except UnknownPrinterError as exc:
        raise DesignError(f"--printer: {exc}") from None
    if out.suffix.lower() != ".sl1":
        raise DesignError(f"{out}: expected an output file ending in .sl1")
    vertices, faces = _load_for_slicing(model)
    try:
        slices = slice_mesh(vertices, faces, profile, layer_height_mm=layer_height_mm, antialias=antialias)
    except ValueError as exc:
        raise DesignError(f"{model}: {exc}") from None
    if not any(area > 0.0 for area in slices.section_areas_mm2()):
        raise DesignError(
            f"{model}: the model cures no resin in any layer (smaller than a pixel or half a layer); "
            "expected a printable model"
        )
    buffer = io.BytesIO()
    stats = write_sl1(buffer, slices, out.stem)
    archive_bytes = buffer.getvalue()
    if png_dir is None:
        return Sliced(slices, stats.volume_ml, profile.label, [atomic_write_bytes(out, archive_bytes)])
    with OutputFolder(png_dir, owned=_png_stack_file) as folder:
        with zipfile.ZipFile(io.BytesIO(archive_bytes)) as archive:
            folder.write_bytes("config.ini", archive.read("config.ini"))
        for k, png in encoded_layers(slices):
            folder.write_bytes(f"{k:05d}.png", png)
        atomic_write_bytes(out, archive_bytes)
        folder.commit()
    return Sliced(slices, stats.volume_ml, profile.label, [out, png_dir])
