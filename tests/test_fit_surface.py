"""``printapp fit`` on measured surfaces: ISO 25178 Sal, Str, Std against closed forms, and a printed
look-alike whose Sq, Sdq and Sal are the measured file's."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter
from typer.testing import CliRunner

from printapp.cli import app
from printapp.design_io import load_design
from printapp.texture import relief_heightfield
from printapp.topography import lateral, load_corrected, roughness

AL3D = Path(__file__).parent.parent / "printapp" / "samples" / "topography" / "al3d-1.al3d"
runner = CliRunner()


def test_lateral_parameters_of_known_surfaces():
    y, x = np.mgrid[0:200, 0:300] * 0.01
    angle = math.radians(30.0)
    across = -math.sin(angle) * x + math.cos(angle) * y
    stripes = np.sin(2 * math.pi * across / 0.2)  # cos(2 pi u / 0.2) = 0.2 at u = 0.2 acos(0.2) / 2 pi
    lat = lateral(stripes, 0.01, 0.01)
    assert lat.sal_um == pytest.approx(1000 * 0.2 * math.acos(0.2) / (2 * math.pi), rel=0.03)
    assert lat.std_deg == pytest.approx(30.0, abs=1.0) and lat.str_ratio < 0.1
    # Gaussian-filtered white noise: ACF exp(-r^2 / 4 s^2), 0.2 at r = 2 s sqrt(ln 5); isotropic.
    noise = gaussian_filter(np.random.default_rng(1).standard_normal((256, 256)), 5.0, mode="wrap")
    lat = lateral(noise, 1e-3, 1e-3)
    assert lat.sal_um == pytest.approx(2 * 5.0 * math.sqrt(math.log(5.0)), rel=0.1)
    assert lat.str_ratio > 0.8


def relief_statistics(design, magnification):
    heights = relief_heightfield(design).heights_mm / magnification
    pitch = design.pitch_mm / magnification
    r = roughness(heights, pitch, pitch)
    return r.sq_um, r.sdq, lateral(heights, pitch, pitch).sal_um


@pytest.mark.slow  # a whole fit and design run
def test_the_al3d_surface_prints_as_a_look_alike_with_its_sq_sdq_and_sal(tmp_path):
    out, metrics = tmp_path / "surface.toml", tmp_path / "surface.json"
    result = runner.invoke(
        app, ["fit", str(AL3D), "-o", str(out), "--json", str(metrics), "--preview", str(tmp_path / "s.png")]
    )
    assert result.exit_code == 0, result.output
    data = json.loads(metrics.read_text())
    measured = load_corrected(AL3D, flatten="plane")
    r = roughness(measured.heights_mm, measured.pitch_x_mm, measured.pitch_y_mm)
    sal = lateral(measured.heights_mm, measured.pitch_x_mm, measured.pitch_y_mm).sal_um
    design = load_design(out)  # a design of its own: base, relief and texture
    sq, sdq, fitted_sal = relief_statistics(design, data["params"]["magnification"])
    assert sq == pytest.approx(r.sq_um, rel=0.1)
    assert sdq == pytest.approx(r.sdq, rel=0.1)
    assert fitted_sal == pytest.approx(sal, rel=0.1)
    assert data["measured"]["Sq_um"] == pytest.approx(r.sq_um, rel=1e-3)
    # Magnified up to the printer's pixel: the slopes (Sdq), and so the gloss, are the file's.
    assert design.pitch_mm == pytest.approx(design.printer.profile.pitch_mm, rel=0.01)


def test_npy_maps_need_their_pitch_and_anisotropy_is_kept(tmp_path):
    rng = np.random.default_rng(3)
    field = gaussian_filter(rng.standard_normal((160, 160)), (2.0, 8.0), mode="wrap")  # long along x
    path = tmp_path / "map.npy"
    np.save(path, field * 1e-3)
    result = runner.invoke(app, ["fit", str(path), "-o", str(tmp_path / "f.toml")])
    assert result.exit_code == 2 and "--pitch-mm" in result.output and str(path) in result.output
    result = runner.invoke(
        app,
        [
            "fit",
            str(path),
            "--pitch-mm",
            "0.05",
            "--magnify",
            "1",
            "-o",
            str(tmp_path / "f.toml"),
            "--json",
            str(tmp_path / "f.json"),
        ],
    )
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "f.json").read_text())
    assert data["measured"]["Str"] < 0.5 and data["params"]["stretch"] > 1.5
    assert abs((data["params"]["angle_deg"] + 90.0) % 180.0 - 90.0) < 10.0  # the lay runs along x
    for key in ("Sq", "Sdq", "Sal"):
        assert abs(data["relative_errors"][key]) < 0.1, data["relative_errors"]
    result = runner.invoke(
        app, ["fit", str(path), "--pitch-mm", "0.05", "--model", "veined", "-o", str(tmp_path / "g.toml")]
    )
    assert result.exit_code == 2 and "--model" in result.output
