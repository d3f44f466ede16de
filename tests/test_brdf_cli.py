"""``printapp brdf`` end to end: designs, height maps, mesh tiles, determinism and bad input."""

import json
import math

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from printapp.cli import app
from render.fresnel import fresnel_dielectric

pytestmark = pytest.mark.slow  # end to end: `make test-fast` leaves these out

runner = CliRunner()


def brdf(*args):
    return runner.invoke(app, ["brdf", *map(str, args)])


def load(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def ripple_npy(tmp_path_factory):
    # Ripples along x (slopes along x), periodic: 16 samples per period of 0.4 mm.
    folder = tmp_path_factory.mktemp("maps")
    x = np.arange(128) * 0.025
    heights = 0.005 * np.sin(2 * math.pi * x / 0.4)[None, :] * np.ones((96, 1))
    path = folder / "ripples.npy"
    np.save(path, heights)
    return path


def test_height_map_gives_the_table_the_plot_and_the_metrics(tmp_path, ripple_npy):
    out, plot, metrics = tmp_path / "b.npz", tmp_path / "b.png", tmp_path / "m.json"
    result = brdf(
        ripple_npy,
        "--pitch-mm",
        0.025,
        "--periodic",
        "--rays",
        20000,
        "-o",
        out,
        "--plot",
        plot,
        "--json",
        metrics,
    )
    assert result.exit_code == 0, result.output
    table = load(out)
    n_in = table["wi"].shape[0]
    assert table["f"].shape == (n_in, 45, 90) == table["stderr"].shape
    assert table["theta_o_edges"][-1] == pytest.approx(math.pi / 2)
    assert np.allclose(np.linalg.norm(table["wi"], axis=1), 1.0)
    omega = 0.5 * np.outer(np.diff(np.sin(table["theta_o_edges"]) ** 2), np.diff(table["phi_o_edges"]))
    assert np.allclose((table["f"] * omega).sum(axis=(1, 2)), table["albedo"])
    assert float(table["ior"]) == 1.5 and np.all(table["rays"] == 20000)
    m = json.loads(metrics.read_text())
    # Ripples along x stretch the highlight along x.
    assert m["highlight"]["anisotropy"] > 3
    assert min(m["highlight"]["azimuth_deg"], 180 - m["highlight"]["azimuth_deg"]) < 10
    assert set(m["gloss_gu"]) == {"20", "60", "85"}
    assert Image.open(plot).size[0] > 300
    assert "gloss" in result.output and "compact model" in result.output and "analytic fit" in result.output
    assert m["fit"]["distribution"] == "tabulated" and m["representation"]["use"] in ("model", "table")
    assert m["haze"] is None or m["haze_reason"].startswith("G60 - G20")
    assert set(table) >= {
        "model_ndf",
        "model_lambda_area",
        "model_relative_error",
        "model_used",
        "fit_params",
    }


def test_the_chooser_follows_its_rule_and_says_so(tmp_path, ripple_npy):
    # max(10 %, 3 x table noise): the model stands in for the table exactly when its error is
    # within that, and the metrics, the file and the command say which was used and why.
    out, metrics = tmp_path / "w.npz", tmp_path / "w.json"
    result = brdf(ripple_npy, "--pitch-mm", 0.025, "--rays", 200, "-o", out, "--json", metrics)
    assert result.exit_code == 0, result.output
    m = json.loads(metrics.read_text())
    tolerance = max(0.10, 3 * m["fit"]["table_noise"])
    assert m["representation"]["tolerance"] == pytest.approx(tolerance, rel=1e-4)
    within = m["fit"]["relative_error"] is not None and m["fit"]["relative_error"] <= tolerance
    assert (m["representation"]["use"] == "model") == within
    assert int(load(out)["model_used"]) == int(within)
    assert bool(m["warnings"]) != within and ("warning:" in result.output) != within


def test_a_model_that_misses_or_cannot_be_checked_is_a_warning():
    # The table stands in when the error is above the rule, or cannot be measured at all.
    from render.appearance import model_or_table
    from render.brdf_fit import FitResult

    for error, noise, words in ((0.35, 0.05, "35.0%"), (float("nan"), float("nan"), "cannot be measured")):
        choice, warnings = model_or_table(FitResult(None, error, 10, noise))
        assert choice["use"] == "table" and words in choice["reason"]
        assert warnings and "traced table stands in" in warnings[0] and words in warnings[0]
    choice, warnings = model_or_table(FitResult(None, 0.12, 10, 0.05))  # within 3 x 5 %
    assert choice["use"] == "model" and not warnings


def test_same_input_same_bytes(tmp_path, ripple_npy):
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    for path in (a, b):
        result = brdf(
            ripple_npy, "--pitch-mm", 0.025, "--rays", 5000, "--incident-deg", "0,45:30", "-o", path
        )
        assert result.exit_code == 0, result.output
    assert a.read_bytes() == b.read_bytes()


def test_flat_image_is_polished_resin(tmp_path):
    image = tmp_path / "flat.png"
    Image.fromarray(np.full((40, 40), 128, dtype=np.uint8)).save(image)
    out, metrics = tmp_path / "flat.npz", tmp_path / "flat.json"
    result = brdf(
        image,
        "--width-mm",
        2,
        "--depth-mm",
        0.1,
        "--rays",
        4000,
        "--body-albedo",
        0,
        "-o",
        out,
        "--json",
        metrics,
    )
    assert result.exit_code == 0, result.output
    m = json.loads(metrics.read_text())
    expected = (
        100
        * fresnel_dielectric(math.cos(math.radians(60)), 1.5)
        / fresnel_dielectric(math.cos(math.radians(60)), 1.567)
    )
    assert m["gloss_gu"]["60"] == pytest.approx(float(expected), abs=1e-3)
    assert load(out)["albedo"][0] == pytest.approx(0.04)
    # Polished resin is high gloss: its haze index is defined (ASTM D4039), the index mismatch's.
    assert m["haze"] == pytest.approx(m["gloss_gu"]["60"] - m["gloss_gu"]["20"]) and m["haze"] > 0


def test_mesh_tile_and_its_height_map_agree(tmp_path, ripple_npy):
    # The same ripples as an image, embossed to a closed slab, then measured from its mesh.
    heights = np.load(ripple_npy)
    grey = np.round((heights - heights.min()) / np.ptp(heights) * 65535).astype(np.uint16)
    image = tmp_path / "ripples.png"
    Image.fromarray(grey).save(image)
    stl = tmp_path / "tile.stl"
    emboss = runner.invoke(
        app,
        [
            "emboss",
            str(image),
            "--width-mm",
            "3.175",
            "--depth-mm",
            "0.01",
            "--pitch-mm",
            "0.025",
            "-o",
            str(stl),
        ],
    )
    assert emboss.exit_code == 0, emboss.output
    from_mesh, from_map = tmp_path / "mesh.json", tmp_path / "map.json"
    assert brdf(stl, "--rays", 20000, "-o", tmp_path / "m.npz", "--json", from_mesh).exit_code == 0
    result = brdf(
        image,
        "--width-mm",
        3.175,
        "--depth-mm",
        0.01,
        "--rays",
        20000,
        "-o",
        tmp_path / "i.npz",
        "--json",
        from_map,
    )
    assert result.exit_code == 0, result.output
    a, b = json.loads(from_mesh.read_text()), json.loads(from_map.read_text())
    assert a["from"] == "mesh tile's top surface"
    assert a["highlight"]["anisotropy"] == pytest.approx(b["highlight"]["anisotropy"], rel=0.15)
    assert a["gloss_gu"]["60"] == pytest.approx(b["gloss_gu"]["60"], rel=0.15, abs=1.0)


def test_design_file_uses_the_as_printed_relief_and_the_design_material(tmp_path):
    design = tmp_path / "d.toml"
    design.write_text(
        "[base]\nwidth_mm = 4.0\ndepth_mm = 4.0\n[texture]\nfeature_size_mm = 1.0\n"
        "[relief]\namplitude_mm = 0.1\n[material]\nrefractive_index = 1.55\n"
    )
    metrics = tmp_path / "m.json"
    result = brdf(design, "--rays", 5000, "-o", tmp_path / "d.npz", "--json", metrics)
    assert result.exit_code == 0, result.output
    m = json.loads(metrics.read_text())
    assert m["from"] == "as-printed relief"
    assert m["fit"]["ior"] == 1.55
    assert float(load(tmp_path / "d.npz")["ior"]) == 1.55


def test_lobe_error_target_from_the_design_or_the_command(tmp_path):
    design = tmp_path / "d.toml"
    design.write_text(
        "[base]\nwidth_mm = 4.0\ndepth_mm = 4.0\n[texture]\nfeature_size_mm = 1.0\n"
        "[relief]\namplitude_mm = 0.1\n[brdf]\nlobe_error = 0.002\n"
    )
    metrics = tmp_path / "m.json"
    assert brdf(design, "--rays", 5000, "-o", tmp_path / "d.npz", "--json", metrics).exit_code == 0
    m = json.loads(metrics.read_text())
    assert max(m["lobe_error"]) <= 0.002
    assert max(m["rays_per_direction"]) > 5000  # 5000 rays were not enough somewhere
    # the command's target overrides the design's
    loose = brdf(design, "--rays", 5000, "--lobe-error", "0.5", "-o", tmp_path / "e.npz", "--json", metrics)
    assert loose.exit_code == 0
    assert json.loads(metrics.read_text())["rays_per_direction"] == [5000] * len(m["rays_per_direction"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.npy", "--pitch-mm", "0.1"], "missing.npy"),
        (["{map}", "--incident-deg", "95:0"], "--incident-deg"),
        (["{map}", "--incident-deg", "north"], "--incident-deg"),
        (["{map}", "--pitch-mm", "0.1", "-o", "{tmp}/table.csv"], ".npz"),
        (["{map}", "--pitch-mm", "0.1", "--ior", "0.5"], "--ior"),
        (["{map}", "--pitch-mm", "0.1", "--body-albedo", "1.5"], "--body-albedo"),
        (["{map}", "--pitch-mm", "0.1", "--lobe-error", "0"], "--lobe-error"),
        (["{map}"], "pitch"),
    ],
)
def test_bad_input_is_one_clear_sentence_and_writes_nothing(tmp_path, ripple_npy, args, message):
    filled = [a.format(map=ripple_npy, tmp=tmp_path) for a in args]
    out = tmp_path / "never.npz"
    if "-o" not in filled:
        filled += ["-o", str(out)]
    result = runner.invoke(app, ["brdf", *filled])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert "Traceback" not in result.output
    assert not out.exists() and not (tmp_path / "table.csv").exists()
