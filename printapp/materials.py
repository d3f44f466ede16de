"""Materials as data: the catalogue in ``printapp/data/materials.toml`` (or a user's file), its
parameters, and the scattering properties and rendering appearance computed from them.

A material names a host index, particle types (index, size distribution, volume fraction) or a
model (FCJ07's milk), the wavelengths it is sampled at, and parameters a design or the command
line may set (``tio2_volume_fraction``, ``fat_wt_pct``...). Everything numeric happens in
:mod:`render.particles`, :mod:`render.mie` and :mod:`render.translucency`; this module reads
files and turns every problem into one sentence naming the material, key or file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from printapp.errors import PrintappError
from printapp.tomlfile import read_toml

CATALOGUE = files("printapp").joinpath("data/materials.toml")
_INDEX_KEYS = {
    "dispersion": {"A", "B", "C_um2", "D_um2", "E_um2", "kappa", "range_nm"},
    "table": {"wavelength_nm", "n", "kappa"},
    "constant": {"n", "kappa", "range_nm"},
    "mean": {"of", "weights"},
}
_DIST_KEYS = {
    "lognormal": {
        "median_radius_um",
        "sigma",
        "mean_radius_um",
        "std_radius_um",
        "weighting",
        "bound_um",
        "range_um",
    },
    "powerlaw": {"r_min_um", "r_max_um", "exponent"},
    "bimodal": {"first", "second", "second_fraction"},
}


class MaterialError(PrintappError, ValueError):
    """A material, its file or its parameters are wrong (exit code 2; a ValueError for pydantic)."""


@dataclass(frozen=True)
class Parameter:
    """A number a design or the command line may set, with its range."""

    name: str
    default: float
    minimum: float
    maximum: float
    help: str = ""


@dataclass(frozen=True)
class MaterialSpec:
    """One material of a library, as read (parameters not yet applied)."""

    name: str
    description: str
    model: str
    host: str
    wavelengths_nm: tuple[float, ...]
    parameters: dict[str, Parameter]
    particles: tuple[dict[str, Any], ...] = ()
    options: dict[str, Any] = field(default_factory=dict)
    sources: tuple[str, ...] = ()
    defaults: dict[str, float] = field(default_factory=dict)


@dataclass
class Library:
    """Indices, absorbers and materials read from one or more TOML files."""

    indices: dict[str, Any]
    index_sources: dict[str, str]
    absorbers: dict[str, dict[str, Any]]
    materials: dict[str, MaterialSpec]


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MaterialError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _numbers(where: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, list):
        raise MaterialError(f"{where}: expected an array of numbers, got {value!r}")
    return tuple(_number(f"{where}[{i}]", v) for i, v in enumerate(value))


def _pair(where: str, value: Any) -> tuple[float, float]:
    pair = _numbers(where, value)
    if len(pair) != 2 or pair[0] >= pair[1]:
        raise MaterialError(f"{where}: expected [min, max] with min < max, got {value!r}")
    return pair[0], pair[1]


def _table(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise MaterialError(f"{where}: expected a table, got {value!r}")
    return value


def _only(where: str, table: dict[str, Any], allowed: set[str]) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise MaterialError(f"{where}: unknown key '{extra[0]}'; valid keys are {', '.join(sorted(allowed))}")


def _build_index(name: str, raw: dict[str, Any], raw_all: dict[str, Any], where: str, seen: tuple[str, ...]):
    from render import indices

    kind = raw.get("kind")
    if kind not in _INDEX_KEYS:
        raise MaterialError(f"{where}.kind: expected one of {', '.join(_INDEX_KEYS)}, got {kind!r}")
    _only(where, raw, _INDEX_KEYS[kind] | {"kind", "source"})
    try:
        if kind == "dispersion":
            b = _numbers(f"{where}.B", raw.get("B", []))
            c = _numbers(f"{where}.C_um2", raw.get("C_um2", []))
            d = _numbers(f"{where}.D_um2", raw.get("D_um2", []))
            e = _numbers(f"{where}.E_um2", raw.get("E_um2", []))
            if len(b) != len(c) or len(d) != len(e):
                raise MaterialError(f"{where}: expected as many B as C_um2 and as many D_um2 as E_um2")
            return indices.Dispersion(
                name,
                _pair(f"{where}.range_nm", raw.get("range_nm")),
                _number(f"{where}.A", raw.get("A", 1.0)),
                b,
                c,
                d,
                e,
                _number(f"{where}.kappa", raw.get("kappa", 0.0)),
            )
        if kind == "table":
            return indices.Table(
                name,
                _numbers(f"{where}.wavelength_nm", raw.get("wavelength_nm")),
                _numbers(f"{where}.n", raw.get("n")),
                _numbers(f"{where}.kappa", raw.get("kappa")),
            )
        if kind == "constant":
            return indices.Constant(
                name,
                _number(f"{where}.n", raw.get("n")),
                _pair(f"{where}.range_nm", raw.get("range_nm")),
                _number(f"{where}.kappa", raw.get("kappa", 0.0)),
            )
        of = raw.get("of")
        if not isinstance(of, list) or not of or not all(isinstance(o, str) for o in of):
            raise MaterialError(f"{where}.of: expected an array of index names")
        weights = _numbers(f"{where}.weights", raw.get("weights", [1.0] * len(of)))
        if len(weights) != len(of) or any(w < 0 for w in weights) or sum(weights) <= 0:
            raise MaterialError(f"{where}.weights: expected one non-negative weight per index in 'of'")
        parts = []
        for part in of:
            if part in seen or part == name:
                raise MaterialError(f"{where}.of: index '{part}' refers back to itself")
            if part not in raw_all:
                raise MaterialError(f"{where}.of: unknown index '{part}'")
            parts.append(_build_index(part, raw_all[part], raw_all, f"indices.{part}", (*seen, name)))
        return indices.Mean(name, tuple(parts), weights)
    except ValueError as exc:
        if isinstance(exc, MaterialError):
            raise
        raise MaterialError(f"{where}: {exc}") from None


def _read_toml(path: Path | Any, label: str) -> dict[str, Any]:
    return read_toml(path, label, "material", MaterialError)


def _parse_material(
    name: str,
    raw: dict[str, Any],
    where: str,
    library_raw: dict[str, Any],
    known: dict[str, MaterialSpec] | None = None,
) -> MaterialSpec:
    allowed = {
        "description",
        "model",
        "host",
        "wavelengths_nm",
        "parameters",
        "particles",
        "sources",
        "fat_index",
        "casein_index",
        "absorber",
        "preset",
        "set",
    }
    _only(where, raw, allowed)
    if "preset" in raw:
        base_name = raw["preset"]
        materials = library_raw.get("materials", {})
        if isinstance(base_name, str) and base_name in materials and "preset" not in materials[base_name]:
            base = _parse_material(base_name, materials[base_name], f"materials.{base_name}", library_raw)
        elif isinstance(base_name, str) and known and base_name in known:
            base = known[base_name]
        else:
            raise MaterialError(
                f"{where}.preset: expected the name of a material that is not itself a preset"
            )
        overrides = _table(f"{where}.set", raw.get("set", {}))
        defaults = dict(base.defaults)
        for key, value in overrides.items():
            if key not in base.parameters:
                raise MaterialError(f"{where}.set: '{key}' is not a parameter of '{base_name}'")
            defaults[key] = _number(f"{where}.set.{key}", value)
        return MaterialSpec(
            name,
            str(raw.get("description", base.description)),
            base.model,
            base.host,
            base.wavelengths_nm,
            base.parameters,
            base.particles,
            base.options,
            base.sources,
            defaults,
        )
    model = raw.get("model", "particles")
    if model not in ("particles", "milk"):
        raise MaterialError(f"{where}.model: expected 'particles' or 'milk', got {model!r}")
    host = raw.get("host")
    if not isinstance(host, str):
        raise MaterialError(f"{where}.host: expected the name of an index")
    lam = _numbers(f"{where}.wavelengths_nm", raw.get("wavelengths_nm"))
    if not lam or any(b <= a for a, b in zip(lam, lam[1:], strict=False)) or lam[0] <= 0:
        raise MaterialError(f"{where}.wavelengths_nm: expected increasing positive wavelengths (nm)")
    params: dict[str, Parameter] = {}
    for key, spec in _table(f"{where}.parameters", raw.get("parameters", {})).items():
        spec = _table(f"{where}.parameters.{key}", spec)
        _only(f"{where}.parameters.{key}", spec, {"default", "min", "max", "help"})
        p = Parameter(
            key,
            _number(f"{where}.parameters.{key}.default", spec.get("default")),
            _number(f"{where}.parameters.{key}.min", spec.get("min", 0.0)),
            _number(f"{where}.parameters.{key}.max", spec.get("max", 1e300)),
            str(spec.get("help", "")),
        )
        if not p.minimum <= p.default <= p.maximum:
            raise MaterialError(f"{where}.parameters.{key}: expected min <= default <= max")
        params[key] = p
    particles = raw.get("particles", [])
    if not isinstance(particles, list) or not all(isinstance(p, dict) for p in particles):
        raise MaterialError(f"{where}.particles: expected an array of tables ([[...particles]])")
    if model == "particles" and not particles:
        raise MaterialError(f"{where}.particles: expected at least one particle type")
    options = {k: raw[k] for k in ("fat_index", "casein_index", "absorber") if k in raw}
    if model == "milk":
        for key in ("fat_wt_pct", "protein_wt_pct", "homogenization_mpa", "riboflavin_mg_per_100g"):
            if key not in params:
                raise MaterialError(f"{where}.parameters: the milk model needs '{key}'")
        for key in ("fat_index", "casein_index", "absorber"):
            if not isinstance(options.get(key), str):
                raise MaterialError(f"{where}.{key}: the milk model needs it (a name)")
    sources = raw.get("sources", [])
    if not isinstance(sources, list):
        raise MaterialError(f"{where}.sources: expected an array of strings")
    return MaterialSpec(
        name,
        str(raw.get("description", "")),
        model,
        host,
        lam,
        params,
        tuple(particles),
        options,
        tuple(str(s) for s in sources),
        {k: p.default for k, p in params.items()},
    )


def parse_library(raw: dict[str, Any], label: str, base: Library | None = None) -> Library:
    """Indices, absorbers and materials of a parsed TOML document (over ``base``, if given)."""
    _only(label, raw, {"indices", "absorbers", "materials", "material", "cure"})
    raw_indices = dict(base_raw_indices(base))
    raw_indices.update(_table(f"{label}: indices", raw.get("indices", {})))
    indices = {}
    sources = {}
    for name, spec in raw_indices.items():
        spec = _table(f"{label}: indices.{name}", spec)
        indices[name] = _build_index(name, spec, raw_indices, f"{label}: indices.{name}", ())
        sources[name] = str(spec.get("source", ""))
    absorbers = dict(base.absorbers) if base else {}
    for name, spec in _table(f"{label}: absorbers", raw.get("absorbers", {})).items():
        spec = _table(f"{label}: absorbers.{name}", spec)
        _only(
            f"{label}: absorbers.{name}",
            spec,
            {
                "wavelength_nm",
                "absorbance",
                "reference_absorbance",
                "reference_molar_absorption",
                "molar_mass_g_per_mol",
                "source",
            },
        )
        lam = _numbers(f"{label}: absorbers.{name}.wavelength_nm", spec.get("wavelength_nm"))
        absorbance = _numbers(f"{label}: absorbers.{name}.absorbance", spec.get("absorbance"))
        if len(lam) != len(absorbance) or len(lam) < 2:
            raise MaterialError(
                f"{label}: absorbers.{name}: expected equally long wavelength_nm and absorbance"
            )
        scale = _number(
            f"{label}: absorbers.{name}.reference_molar_absorption", spec.get("reference_molar_absorption")
        )
        scale /= _number(f"{label}: absorbers.{name}.reference_absorbance", spec.get("reference_absorbance"))
        absorbers[name] = {
            "wavelength_nm": lam,
            "molar_absorption_l_per_mol_cm": tuple(a * scale for a in absorbance),
            "molar_mass_g_per_mol": _number(
                f"{label}: absorbers.{name}.molar_mass_g_per_mol", spec.get("molar_mass_g_per_mol")
            ),
            "source": str(spec.get("source", "")),
        }
    materials = dict(base.materials) if base else {}
    raw_materials = _table(f"{label}: materials", raw.get("materials", {}))
    for name, spec in raw_materials.items():
        materials[name] = _parse_material(
            name, _table(f"{label}: materials.{name}", spec), f"{label}: materials.{name}", raw, materials
        )
    library = Library(indices, sources, absorbers, materials)
    library._raw_indices = raw_indices  # type: ignore[attr-defined]
    for spec in materials.values():
        _check_references(spec, library, label)
    return library


def base_raw_indices(base: Library | None) -> dict[str, Any]:
    return dict(getattr(base, "_raw_indices", {})) if base else {}


def _check_references(spec: MaterialSpec, library: Library, label: str) -> None:
    where = f"{label}: materials.{spec.name}"
    names = [spec.host] + [p.get("index") for p in spec.particles]
    names += [spec.options[k] for k in ("fat_index", "casein_index") if k in spec.options]
    for name in names:
        if not isinstance(name, str) or name not in library.indices:
            raise MaterialError(
                f"{where}: unknown index {name!r}; known: {', '.join(sorted(library.indices))}"
            )
    if "absorber" in spec.options and spec.options["absorber"] not in library.absorbers:
        raise MaterialError(f"{where}.absorber: unknown absorber {spec.options['absorber']!r}")


@lru_cache(maxsize=1)
def builtin_library() -> Library:
    """The catalogue shipped with printapp."""
    return parse_library(_read_toml(CATALOGUE, "materials.toml"), "materials.toml")


def material_names() -> list[str]:
    return sorted(builtin_library().materials)


def find_material(name_or_file: str | Path) -> tuple[MaterialSpec, Library]:
    """A catalogue material by name, or the one material of a TOML file.

    A material file holds one ``[material]`` table (the keys of a catalogue entry) and may add
    its own ``[indices.NAME]`` and ``[absorbers.NAME]`` next to the built-in ones.
    """
    text = str(name_or_file)
    library = builtin_library()
    if text in library.materials:
        return library.materials[text], library
    path = Path(text)
    if path.suffix.lower() == ".toml" or path.exists():
        raw = _read_toml(path, str(path))
        material = raw.pop("material", None)
        if not isinstance(material, dict):
            raise MaterialError(f"{path}: expected a [material] table")
        raw.setdefault("materials", {})
        if not isinstance(raw["materials"], dict) or raw["materials"]:
            raise MaterialError(f"{path}: expected one [material] table and no [materials] tables")
        raw["materials"] = {path.stem: material}
        lib = parse_library(raw, str(path), base=library)
        return lib.materials[path.stem], lib
    import difflib

    close = difflib.get_close_matches(text, library.materials, n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise MaterialError(
        f"unknown material '{text}'; expected one of {', '.join(material_names())} or a .toml file{hint}"
    )


def resolve_parameters(spec: MaterialSpec, given: dict[str, float] | None) -> dict[str, float]:
    """The material's defaults with ``given`` applied, each checked against its range."""
    values = dict(spec.defaults)
    for key, value in (given or {}).items():
        if key not in spec.parameters:
            valid = ", ".join(sorted(spec.parameters)) or "none"
            raise MaterialError(f"{spec.name}: unknown parameter '{key}'; its parameters are {valid}")
        p = spec.parameters[key]
        v = _number(f"{spec.name}: {key}", value)
        if not p.minimum <= v <= p.maximum:
            raise MaterialError(
                f"{spec.name}: {key} expected a value in [{p.minimum:g}, {p.maximum:g}], got {v:g}"
            )
        values[key] = v
    return values


def _substitute(value: Any, params: dict[str, float], where: str) -> Any:
    if isinstance(value, str):
        if value not in params:
            raise MaterialError(f"{where}: expected a number or a parameter name, got '{value}'")
        return params[value]
    return value


def _distribution(raw: Any, params: dict[str, float], where: str):
    from render.particles import Bimodal, LogNormal, PowerLaw

    raw = _table(where, raw)
    kind = raw.get("kind")
    if kind not in _DIST_KEYS:
        raise MaterialError(f"{where}.kind: expected one of {', '.join(_DIST_KEYS)}, got {kind!r}")
    _only(where, raw, _DIST_KEYS[kind] | {"kind"})

    def num(key: str, default: Any = None) -> float:
        return _number(f"{where}.{key}", _substitute(raw.get(key, default), params, f"{where}.{key}"))

    try:
        if kind == "lognormal":
            weighting = raw.get("weighting", "number")
            bound = num("bound_um") if "bound_um" in raw else None
            rng = _pair(f"{where}.range_um", raw["range_um"]) if "range_um" in raw else None
            if "median_radius_um" in raw:
                return LogNormal(num("median_radius_um"), num("sigma"), weighting, bound, rng)
            return LogNormal.from_mean_std(
                num("mean_radius_um"), num("std_radius_um"), weighting=weighting, bound_um=bound, range_um=rng
            )
        if kind == "powerlaw":
            return PowerLaw(num("r_min_um"), num("r_max_um"), num("exponent"))
        return Bimodal(
            _distribution(raw.get("first"), params, f"{where}.first"),
            _distribution(raw.get("second"), params, f"{where}.second"),
            num("second_fraction"),
        )
    except ValueError as exc:
        if isinstance(exc, MaterialError):
            raise
        raise MaterialError(f"{where}: {exc}") from None


def _index(library: Library, name: str, lam: np.ndarray, material: str) -> np.ndarray:
    try:
        return library.indices[name](lam)
    except ValueError as exc:
        raise MaterialError(f"{material}: {exc}") from None


def spectral_optics(
    spec: MaterialSpec,
    library: Library,
    parameters: dict[str, float] | None = None,
    wavelengths_nm: np.ndarray | None = None,
    n_radii: int = 160,
):
    """sigma_s, sigma_a, g per wavelength (:class:`render.particles.SpectralOptics`).

    ``wavelengths_nm`` defaults to the material's own samples; any wavelength outside the
    range of one of its indices is an error naming the index and its range.
    """
    from render.indices import WithAbsorber
    from render.particles import Component, bulk_optics, milk_recipe

    params = resolve_parameters(spec, parameters)
    lam = np.asarray(spec.wavelengths_nm if wavelengths_nm is None else wavelengths_nm, dtype=np.float64)
    if lam.ndim != 1 or lam.size == 0 or not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise MaterialError(f"{spec.name}: expected positive wavelengths in nanometres")
    components = []
    if spec.model == "milk":
        absorber = library.absorbers[spec.options["absorber"]]
        milk_density = 1.030
        concentration = (params["riboflavin_mg_per_100g"] * 1e-3 / absorber["molar_mass_g_per_mol"]) / (
            100.0 / milk_density / 1000.0
        )
        host_model = WithAbsorber(
            f"{spec.host} + {spec.options['absorber']}",
            library.indices[spec.host],
            absorber["wavelength_nm"],
            absorber["molar_absorption_l_per_mol_cm"],
            concentration,
        )
        try:
            host = host_model(lam)
            recipe = milk_recipe(params["fat_wt_pct"], params["protein_wt_pct"], params["homogenization_mpa"])
        except ValueError as exc:
            raise MaterialError(f"{spec.name}: {exc}") from None
        if recipe.fat is not None:
            fat_index = _index(library, spec.options["fat_index"], lam, spec.name)
            components.append(Component("fat globules", fat_index, recipe.fat, recipe.fat_volume_fraction))
        casein_index = _index(library, spec.options["casein_index"], lam, spec.name)
        components.append(
            Component("casein micelles", casein_index, recipe.casein, recipe.casein_volume_fraction)
        )
    else:
        host = _index(library, spec.host, lam, spec.name)
        for i, raw in enumerate(spec.particles):
            where = f"{spec.name}: particles[{i}]"
            _only(where, raw, {"name", "index", "volume_fraction", "distribution"})
            fraction = _number(
                f"{where}.volume_fraction",
                _substitute(raw.get("volume_fraction"), params, f"{where}.volume_fraction"),
            )
            dist = _distribution(raw.get("distribution"), params, f"{where}.distribution")
            index = _index(library, raw["index"], lam, spec.name)
            components.append(Component(str(raw.get("name", f"particles {i}")), index, dist, fraction))
    try:
        return bulk_optics(lam, host, components, n_radii=n_radii)
    except ValueError as exc:
        raise MaterialError(f"{spec.name}: {exc}") from None


@lru_cache(maxsize=32)
def _cached_appearance(name: str, items: tuple[tuple[str, float], ...]):
    from render.translucency import appearance_from_spectra

    spec, library = find_material(name)
    optics = spectral_optics(spec, library, dict(items))
    return appearance_from_spectra(
        optics.wavelength_nm, optics.host_index, optics.sigma_s_per_mm, optics.sigma_a_per_mm, optics.g
    )


def appearance(name: str, parameters: dict[str, float] | None = None):
    """The rendering appearance (:class:`render.translucency.Appearance`) of a catalogue material."""
    spec, _ = find_material(name)
    values = resolve_parameters(spec, parameters)
    return _cached_appearance(name, tuple(sorted(values.items())))


def check_design_material(name: str, parameters: dict[str, float]) -> None:
    """Raise MaterialError unless ``name`` is a catalogue material and ``parameters`` fit it."""
    library = builtin_library()
    if name not in library.materials:
        import difflib

        close = difflib.get_close_matches(name, library.materials, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise MaterialError(f"unknown material '{name}', expected one of {', '.join(material_names())}{hint}")
    resolve_parameters(library.materials[name], parameters)
