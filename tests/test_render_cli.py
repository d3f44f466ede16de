"""``printapp render``, ``printapp preview`` and the appearance gate of ``printapp design``."""

import json

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from printapp.cli import app

pytestmark = pytest.mark.slow  # end to end: `make test-fast` leaves these out

runner = CliRunner()

SMALL = """
name = "small tile"
[base]
width_mm = 8.0
depth_mm = 8.0
thickness_mm = 1.5
[texture]
feature_size_mm = 0.6
[relief]
amplitude_mm = 0.1
[brdf]
rays = 5000
[render]
width_px = 64
height_px = 48
spp = 4
noise = 1.0  # tiny test renders: any noise passes (tests/test_convergence.py checks it)
"""


@pytest.fixture()
def small_design(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


def test_render_picks_geometry_near_and_a_brdf_far(tmp_path, small_design):
    near = runner.invoke(app, ["render", str(small_design), "-o", str(tmp_path / "near.png")])
    assert near.exit_code == 0, near.output
    assert "rendered as geometry" in near.output
    far = runner.invoke(
        app, ["render", str(small_design), "--distance-scale", "60", "-o", str(tmp_path / "far.png")]
    )
    assert far.exit_code == 0, far.output
    assert "rendered as model" in far.output or "rendered as table" in far.output
    assert Image.open(tmp_path / "far.png").size == (64, 48)


@pytest.mark.parametrize("mode", ["model", "table", "geometry"])
def test_every_representation_renders_the_tile(tmp_path, small_design, mode):
    out, strip = tmp_path / f"{mode}.png", tmp_path / f"{mode}-sweep.png"
    args = ["render", str(small_design), "--mode", mode, "-o", str(out)]
    if mode == "model":
        args += ["--sweep", str(strip)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert f"rendered as {mode}" in result.output
    image = np.asarray(Image.open(out).convert("L"), dtype=float)
    centre = image[16:32, 24:40].mean()
    corner = image[:6, :6].mean()
    assert abs(centre - corner) > 5  # the tile stands out from the background
    if mode == "model":
        sweep = Image.open(strip)
        assert sweep.size == (6 * 160, 120)


def test_render_says_where_the_mode_and_size_came_from(tmp_path, small_design):
    flag = runner.invoke(
        app,
        ["render", str(small_design), "--mode", "model", "--size", "48x32", "-o", str(tmp_path / "f.png")],
    )
    assert flag.exit_code == 0, flag.output
    assert "rendered as model (asked for with --mode)" in flag.output
    assert Image.open(tmp_path / "f.png").size == (48, 32)
    assert "preview converged: raw noise" in flag.output
    forced = tmp_path / "forced.toml"
    forced.write_text(small_design.read_text().replace("[render]\n", '[render]\nmode = "table"\n'))
    design = runner.invoke(app, ["render", str(forced), "-o", str(tmp_path / "d.png")])
    assert design.exit_code == 0, design.output
    assert "rendered as table (asked for in the design)" in design.output
    bad = runner.invoke(app, ["render", str(small_design), "--size", "big", "-o", str(tmp_path / "b.png")])
    assert bad.exit_code == 2 and "--size: expected WIDTHxHEIGHT" in bad.output


def test_preview_draws_any_mesh(tmp_path):
    from pathlib import Path

    mesh = Path(__file__).parent.parent / "printapp" / "samples" / "meshes" / "featuretype.STL"
    out = tmp_path / "view.png"
    result = runner.invoke(
        app, ["preview", str(mesh), "-o", str(out), "--width-px", "200", "--height-px", "150"]
    )
    assert result.exit_code == 0, result.output
    image = np.asarray(Image.open(out).convert("L"), dtype=float)
    assert image.shape == (150, 200) and image.std() > 5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["render", "{design}", "-o", "{tmp}/r.jpg"], ".png"),
        (["render", "{tmp}/missing.toml"], "missing.toml"),
        (["preview", "{tmp}/missing.stl"], "missing.stl"),
        (["preview", "{design}", "-o", "{tmp}/v.png"], "mesh"),
    ],
)
def test_bad_input_exits_2_with_a_sentence(tmp_path, small_design, args, message):
    filled = [a.format(design=small_design, tmp=tmp_path) for a in args]
    result = runner.invoke(app, filled)
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output


def test_gate_passes_met_targets_and_fails_missed_ones_with_the_miss(tmp_path, small_design):
    met = small_design.read_text() + "[appearance]\ngloss_60 = [0.0, 200.0]\nhaze = [0.0, 200.0]\n"
    path = tmp_path / "met.toml"
    path.write_text(met)
    result = runner.invoke(app, ["design", str(path), "-o", str(tmp_path / "met"), "--quiet"])
    assert result.exit_code == 0, result.output
    manifest = json.loads((tmp_path / "met" / "manifest.json").read_text())
    assert any("gloss_60" in c for c in manifest["verification"]["checks"])
    assert manifest["render"]["representation"] in ("model", "table", "geometry")
    fit = manifest["brdf"]["fit"]
    assert fit["relative_error"] is None or fit["relative_error"] >= 0
    assert fit["table_noise"] is None or fit["table_noise"] > 0

    missed = small_design.read_text() + "[appearance]\ngloss_60 = [150.0, 200.0]\n"
    path = tmp_path / "missed.toml"
    path.write_text(missed)
    result = runner.invoke(app, ["design", str(path), "-o", str(tmp_path / "missed"), "--quiet"])
    assert result.exit_code == 3
    assert "gloss_60" in result.output and "misses the target [150, 200] by" in result.output
    assert not (tmp_path / "missed" / "model.stl").exists()
    # The model files were staged ahead of the verdict (the preview met its goal) and unstaged:
    # none is left, listed or hidden, and the folder holds exactly what the manifest says.
    listed = json.loads((tmp_path / "missed" / "manifest.json").read_text())["outputs"]
    assert not {"model.stl", "model.3mf", "slices.sl1"} & set(listed)
    assert sorted(p.name for p in (tmp_path / "missed").iterdir()) == sorted(listed)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
