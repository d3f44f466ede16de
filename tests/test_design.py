"""The design schema: every kind of bad input gives one clear sentence; units convert once."""

import math

import pytest

from printapp.design import Design, DesignError, MeshBase, design_from_dict
from printapp.design_io import load_design, resolved_toml


def error_of(data) -> str:
    with pytest.raises(DesignError) as info:
        design_from_dict(data, "d.toml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("d.toml")
    return message


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"texture": {"octavs": 3}}, "unknown key 'texture.octavs'; did you mean 'octaves'?"),
        ({"bse": {}}, "unknown key 'bse'; did you mean 'base'?"),
        ({"relief": {"amplitude_nm": 3}}, "did you mean 'amplitude_um'?"),
        ({"texture": {"octaves": 0}}, "texture.octaves: expected a value in [1, 16], got 0"),
        ({"texture": {"octaves": 2.5}}, "texture.octaves: expected an integer, got 2.5"),
        ({"texture": {"lacunarity": 1.0}}, "texture.lacunarity: expected a value in (1, 8], got 1.0"),
        ({"texture": {"H": 1.5}}, "texture.H: expected a value in (0, 1], got 1.5"),
        (
            {"texture": {"kind": "perlin"}},
            "texture.kind: expected one of 'scn', 'fbm', 'turbulence', 'lic', 'marble' or 'veined'",
        ),
        ({"texture": {"low": 4, "high": 2}}, "'high' (2) must be at least 'low' (4)"),
        ({"texture": "fbm"}, "texture: expected a table, got 'fbm'"),
        ({"relief": {"amplitude_um": -3}}, "relief.amplitude_um: expected a value in (0, 50000], got -3"),
        ({"relief": {"amplitude_um": 3, "amplitude_mm": 1}}, "give either 'amplitude_um' or 'amplitude_mm'"),
        (
            {"relief": {"pitch_mm": 0.0001}},
            "gives 200000 samples along a 20 mm side; expected at most 100000",
        ),
        ({"base": {"width_mm": "20"}}, "base.width_mm: expected a number, got '20'"),
        ({"base": {"shape": "sphere"}}, 'base: expected shape = "tile" or "mesh"'),
        ({"printer": {"name": "prusa-sl2"}}, "unknown printer 'prusa-sl2'"),
        ({"printer": {"layer_height_mm": 0.5}}, "outside what Original Prusa SL1 can print"),
        ({"material": {"refractive_index": math.nan}}, "material.refractive_index: expected a finite number"),
        (
            {"material": {"body_albedo": [0.5, 2.0, 0.5]}},
            "material.body_albedo[1]: expected a value <= 1, got 2",
        ),
        ({"appearance": {"roughness": [0.5, 0.1]}}, "'roughness' must be [min, max] with min <= max"),
        ({"render": {"spp": True}}, "render.spp: expected an integer, got True"),
    ],
)
def test_each_bad_value_is_named_with_what_was_expected(data, expected):
    assert expected in error_of(data)


def test_units_convert_once_at_the_boundary():
    d = design_from_dict(
        {"relief": {"amplitude_um": 250}, "texture": {"angle_deg": 30}, "base": {"width_cm": 3}}
    )
    assert d.relief.amplitude_mm == pytest.approx(0.25)
    assert d.texture.angle_rad == pytest.approx(math.pi / 6)
    assert d.base.width_mm == pytest.approx(30.0)


def test_defaults_come_from_the_printer():
    d = Design()
    assert d.pitch_mm == pytest.approx(120.96 / 2560)
    assert d.layer_height_mm == 0.05
    assert d.material.refractive_index == 1.5


def test_resolved_toml_reloads_to_the_same_design(tmp_path):
    d = design_from_dict({"texture": {"angle_deg": 30, "stretch": 4.0}, "appearance": {"anisotropy": [2, 5]}})
    first = resolved_toml(d)
    path = tmp_path / "r.toml"
    path.write_text(first)
    again = load_design(path)
    assert resolved_toml(again) == first
    assert "pitch_mm = " in first and "layer_height_mm = 0.05" in first and "seed = 0" in first
    assert again.texture.angle_rad == pytest.approx(d.texture.angle_rad, abs=1e-12)


def test_toml_syntax_error_names_the_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\n[texture]\noctaves = = 3\n')
    with pytest.raises(DesignError, match=r"bad.toml: TOML syntax error: .*line 3"):
        load_design(path)


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(DesignError, match="no such design file"):
        load_design(tmp_path / "nope.toml")
    with pytest.raises(DesignError, match="found a folder"):
        load_design(tmp_path)


def test_mesh_paths_resolve_against_the_design_folder(tmp_path):
    path = tmp_path / "sub" / "d.toml"
    path.parent.mkdir()
    path.write_text('[base]\npath = "part.stl"\nscale = 25.4\n')
    d = load_design(path)
    assert isinstance(d.base, MeshBase)
    assert d.base.path == str(tmp_path / "sub" / "part.stl")


def test_examples_all_validate():
    from pathlib import Path

    examples = sorted(Path(__file__).parent.parent.joinpath("examples").glob("*.toml"))
    assert len(examples) >= 3
    for path in examples:
        load_design(path)


def test_lic_field_specs(tmp_path):
    assert "expected 'constant:ANGLE' with ANGLE in degrees" in error_of(
        {"texture": {"field": "constant:thirty"}}
    )
    assert "expected 'constant:ANGLE', 'swirl' or 'image:FILE'" in error_of({"texture": {"field": "spiral"}})
    assert "expected a finite, non-zero X,Y,Z" in error_of({"texture": {"field": "axis:0,0,0"}})
    assert "three comma-separated numbers" in error_of({"texture": {"field": "direction:1,x,0"}})
    path = tmp_path / "d.toml"
    path.write_text('[texture]\nkind = "lic"\nfield = "image:angles.png"\n')
    assert load_design(path).texture.field == f"image:{tmp_path / 'angles.png'}"


def test_a_bssrdf_on_a_mesh_or_with_booleans_is_refused_at_loading():
    material = {"name": "white-resin", "translucency": "bssrdf"}
    mesh = {"base": {"path": "examples/cylinder.stl"}, "material": material}
    with pytest.raises(
        DesignError, match=r'^part.toml: material.translucency = "bssrdf": .*tiles without booleans'
    ):
        design_from_dict(mesh, "part.toml")
    tile = design_from_dict({"material": material}, "tile.toml")  # a tile is left to the renderer to judge
    assert tile.material.translucency == "bssrdf"
