"""Relief on any closed mesh: ``printapp displace``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from printapp.errors import DesignError
from printapp.solid import SolidCheck
from printapp.texture import FrameSummary

_FLAGS = {
    "relief.amplitude_mm": "--amplitude-mm",
    "texture.feature_size_mm": "--feature-size-mm",
    "texture.kind": "--texture",
    "texture.seed": "--seed",
    "texture.octaves": "--octaves",
    "texture.field": "--field",
    "texture.length_mm": "--length-mm",
    "base.scale": "--scale",
    "base.path": "MODEL",
    "printer.name": "--printer",
}


@dataclass(frozen=True)
class Displaced:
    """A displaced mesh as written, and what was checked on it."""

    solid: SolidCheck
    softened_vertices: int
    """Vertices whose relief was lowered so that no thin or tightly curved triangle folds."""
    overlap_note: str | None
    """A self-overlap of less than half a pixel (the printer cures the union), else None."""
    written: list[Path]
    repair_note: str | None = None
    """With ``--repair``: parts found, closed and united (nothing is dropped)."""
    frame: FrameSummary | None = None
    """The tangent frames a stretched scn, fbm or turbulence followed, else None."""


def displace_mesh_file(
    model: Path,
    out: Path,
    *,
    amplitude_mm: float,
    texture: str = "fbm",
    feature_size_mm: float = 2.0,
    seed: int = 0,
    octaves: int = 4,
    field: str = "swirl",
    stretch: float = 1.0,
    length_mm: float = 2.0,
    scale: float = 1.0,
    printer: str = "prusa-sl1",
    repair: bool = False,
    refractive_index: float = 1.5,
) -> Displaced:
    """Displace a closed mesh along its angle-weighted normals by a texture, check it, write it.

    The options go through the design schema (the same checks and messages as a design's
    ``[texture]``, ``[relief]`` and ``[printer]``). The result must not fold a triangle,
    must be a valid solid, and must not pass through itself in any layer of ``printer``
    (winding numbers); otherwise nothing is written. With ``stretch`` > 1, scn, fbm and
    turbulence are stretched along ``field`` in each vertex's tangent frame.
    """
    from printapp.design import design_from_dict
    from printapp.exporters import check_mesh_output, write_mesh
    from printapp.mesh import folded_triangles, load_closed_mesh, winding_verdict
    from printapp.relief import build_relief
    from printapp.solid import check_solid
    from slicing import slice_mesh

    check_mesh_output(out)
    options = {
        "base": {"shape": "mesh", "path": str(model), "scale": scale},
        "texture": {
            "kind": texture,
            "feature_size_mm": feature_size_mm,
            "seed": seed,
            "octaves": octaves,
            "field": field,
            "stretch": stretch,
            "length_mm": length_mm,
        },
        "relief": {"amplitude_mm": amplitude_mm},
        "printer": {"name": printer},
    }
    try:
        design = design_from_dict(options, "options")
    except DesignError as exc:
        # Name the flag the user typed, not the design key it fills.
        message = str(exc).removeprefix("options: ")
        for key, flag in _FLAGS.items():
            if message.startswith(f"{key}:"):
                message = flag + message[len(key) :]
                break
        raise DesignError(message) from None
    base = load_closed_mesh(model, scale, repair=repair)
    repaired = base.metadata.get("repair")
    relief = build_relief(design, base=base)
    if folded_triangles(relief.undisplaced, relief.mesh):
        raise DesignError(f"{model}: the displaced mesh still folds over; use a smaller --amplitude-mm")
    solid = check_solid(relief.mesh)
    if not solid.ok:
        raise DesignError(f"{model}: the displaced mesh is not a valid solid ({solid.manifold_status})")
    note = None
    try:
        # What the printer would see: a surface passing through itself winds twice.
        winding = slice_mesh(relief.mesh.vertices, relief.mesh.faces, design.printer.profile).max_winding()
    except ValueError:
        winding = None  # larger than this printer: no layers to look at
    if winding is not None:
        overlap = winding_verdict(winding)
        if not overlap.ok:
            raise DesignError(
                f"--amplitude-mm: {amplitude_mm:g} mm makes the surface pass through itself "
                f"(winding number {winding:.2f}); use a smaller amplitude or larger features"
            )
        note = overlap.message if overlap.slight else None
    written = write_mesh(out, relief.mesh.vertices, relief.mesh.faces, refractive_index=refractive_index)
    return Displaced(
        solid,
        relief.softened_vertices,
        note,
        written,
        None if repaired is None else repaired.sentence(),
        relief.frame,
    )
