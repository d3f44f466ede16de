"""Design files: reading them (with ``texture.from`` fragments and paths relative to the file) and
writing ``design.resolved.toml`` back, in mm and degrees with every default filled in.
"""

from __future__ import annotations

import math
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

import tomli_w

from printapp.design import Design, MeshBase, design_from_dict
from printapp.errors import DesignError
from printapp.schema_errors import short_repr
from printapp.tomlfile import read_toml


def _include_texture(data: Any, path: Path) -> Any:
    """Replace ``texture.from = "FILE"`` by FILE's [texture] table, overridden by the keys beside ``from``.

    FILE (relative to the design's folder) is a design or a fragment such as
    ``printapp fit`` writes; only its [texture] table is taken.
    """
    if not (isinstance(data, dict) and isinstance(data.get("texture"), dict) and "from" in data["texture"]):
        return data
    local = dict(data["texture"])
    name = local.pop("from")
    if not isinstance(name, str) or not name:
        raise DesignError(f"{path}: texture.from: expected the name of a TOML file, got {short_repr(name)}")
    source = Path(name) if Path(name).is_absolute() else path.parent / name
    fragment = read_toml(source, f"{path}: texture.from {source}", "texture fragment", DesignError)
    included = fragment.get("texture")
    if not isinstance(included, dict):
        raise DesignError(f"{path}: texture.from: expected a [texture] table in {source}")
    if "from" in included:
        raise DesignError(f"{path}: texture.from: {source} has its own texture.from; expected one level only")
    return {**data, "texture": {**included, **local}}


def load_design(path: str | Path) -> Design:
    """Read and validate a design file.

    Relative mesh paths in the file are resolved against the file's folder.

    Raises
    ------
    DesignError
        If the file is missing or unreadable, is not valid TOML (with the line), or
        does not validate (with the key and what was expected).
    """
    path = Path(path)
    data = read_toml(path, str(path), "design", DesignError)
    data = _include_texture(data, path)
    design = design_from_dict(data, str(path))
    kind, _, image = (design.texture.field or "").partition(":")
    if kind == "image" and not Path(image).is_absolute():
        field = f"image:{path.parent / image}"
        design = design.model_copy(update={"texture": design.texture.model_copy(update={"field": field})})
    if design.combine:
        resolved = [
            c.model_copy(update={"path": str(path.parent / c.path)})
            if c.path is not None and not Path(c.path).is_absolute()
            else c
            for c in design.combine
        ]
        design = design.model_copy(update={"combine": resolved})
    if isinstance(design.base, MeshBase):
        mesh_path = Path(design.base.path)
        if not mesh_path.is_absolute():
            mesh_path = path.parent / mesh_path
        design = design.model_copy(update={"base": design.base.model_copy(update={"path": str(mesh_path)})})
    return design


def to_file_units(data: Any) -> Any:
    """A dumped design (or part of one) in file units: ``_rad`` keys back to ``_deg``, no ``None`` keys."""
    if isinstance(data, dict):
        out = {}
        for key, value in data.items():
            if value is None:
                continue  # TOML has no null: an absent key means "use the default"
            if key.endswith("_rad") and isinstance(value, float):
                # 12 significant digits undo the radian round trip's last-bit noise.
                out[key[:-4] + "_deg"] = float(f"{math.degrees(value):.12g}")
            else:
                out[key] = to_file_units(value)
        return out
    if isinstance(data, (list, tuple)):
        return [to_file_units(v) for v in data]
    return data


def resolved_toml(design: Design) -> str:
    """The design with every default filled in, as TOML in mm and degrees.

    Loading the result gives back an equal :class:`Design`.
    """
    dumped = design.model_dump(mode="python")
    dumped["relief"]["pitch_mm"] = design.pitch_mm
    dumped["printer"]["layer_height_mm"] = design.layer_height_mm
    if design.material.name is not None:
        # Derived from the named material, not settings: writing them would not load back.
        del dumped["material"]["refractive_index"], dumped["material"]["body_albedo"]
    data = to_file_units(dumped)
    header = "# printapp design, resolved: every default filled in. Lengths in mm, angles in degrees.\n"
    return header + tomli_w.dumps(data)


DEFAULT_DESIGN = files("printapp").joinpath("data/default_design.toml")
"""The design ``printapp demo`` runs."""


def load_default_design() -> Design:
    """The built-in design that ``printapp demo`` runs."""
    with as_file(DEFAULT_DESIGN) as path:
        return load_design(path)
