"""Height maps: readers with physical scale, Gwyddion-style corrections, ISO 25178 parameters."""

import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from printapp.errors import DesignError
from printapp.heightmap_readers import read_heightmap
from printapp.topography import fill_masked, level, mask_outliers, roughness

DATA = Path(__file__).parent.parent / "printapp" / "samples" / "topography"


def test_al3d_against_the_reference_values():
    topo = read_heightmap(DATA / "al3d-1.al3d")
    assert topo.heights_mm.shape == (296, 200)
    assert topo.pitch_x_mm == pytest.approx(0.438027e-3)
    raw = roughness(topo.heights_mm, topo.pitch_x_mm, topo.pitch_y_mm)
    assert raw.sq_um == pytest.approx(7.688266, rel=1e-6)  # SurfaceTopography's regression value
    assert raw.sa_um == pytest.approx(6.394, abs=1e-3)
    assert raw.sz_um == pytest.approx(34.95, abs=1e-2)
    levelled = roughness(level(topo.heights_mm, 1), topo.pitch_x_mm, topo.pitch_y_mm)
    assert levelled.sq_um == pytest.approx(0.2898, abs=1e-4)
    assert levelled.sa_um == pytest.approx(0.2302, abs=1e-4)


def write_x3p(path: Path, heights_m: np.ndarray, dx_m: float, dy_m: float) -> None:
    ny, nx = heights_m.shape
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2"><Record1><Revision>ISO5436 - 2000</Revision>
<FeatureType>SUR</FeatureType><Axes><CX><AxisType>I</AxisType><DataType>L</DataType><Increment>{dx_m!r}</Increment>
<Offset>0</Offset></CX><CY><AxisType>I</AxisType><DataType>L</DataType><Increment>{dy_m!r}</Increment><Offset>0</Offset>
</CY><CZ><AxisType>A</AxisType><DataType>D</DataType></CZ></Axes></Record1><Record3><MatrixDimension><SizeX>{nx}</SizeX>
<SizeY>{ny}</SizeY><SizeZ>1</SizeZ></MatrixDimension><DataLink><PointDataLink>bindata/data.bin</PointDataLink>
</DataLink></Record3></p:ISO5436_2>"""
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("main.xml", xml)
        archive.writestr("bindata/data.bin", heights_m.astype("<f8").tobytes())


def test_x3p_keeps_non_square_pixels(tmp_path):
    heights = np.random.default_rng(0).normal(0, 1e-7, (30, 40))
    write_x3p(tmp_path / "s.x3p", heights, 1.25e-7, 3.5e-7)
    topo = read_heightmap(tmp_path / "s.x3p")
    assert topo.heights_mm.shape == (30, 40)
    assert (topo.pitch_x_mm, topo.pitch_y_mm) == pytest.approx((1.25e-4, 3.5e-4))
    np.testing.assert_allclose(topo.heights_mm, heights * 1000)


def test_sine_surface_parameters():
    a, wavelength, pitch = 0.01, 0.5, 0.005  # mm
    x = np.arange(0, 10 * wavelength, pitch)
    z = a * np.sin(2 * np.pi * x / wavelength)[None, :] * np.ones((50, 1))
    r = roughness(z, pitch, pitch)
    assert r.sa_um == pytest.approx(2 * a / math.pi * 1000, rel=1e-3)
    assert r.sq_um == pytest.approx(a / math.sqrt(2) * 1000, rel=1e-3)
    assert r.sz_um == pytest.approx(2 * a * 1000, rel=1e-3)
    assert r.ssk == pytest.approx(0.0, abs=1e-6)
    assert r.sku == pytest.approx(1.5, rel=1e-3)
    assert r.sdq == pytest.approx(a * 2 * math.pi / wavelength / math.sqrt(2), rel=2e-3)


def test_level_removes_planes_and_polynomials():
    y, x = np.mgrid[0:40, 0:60].astype(float)
    bump = 0.01 * np.sin(x / 3.0) * np.cos(y / 5.0)
    np.testing.assert_allclose(level(0.3 + 0.02 * x - 0.01 * y, 1), 0.0, atol=1e-12)
    quadratic = 0.001 * (x - 20) ** 2 + 0.002 * x * y
    assert np.abs(level(quadratic + bump, 2) - bump).max() < 0.3 * np.abs(bump).max()


@pytest.mark.slow
def test_outliers_are_masked_and_filled():
    z = np.fromfunction(lambda r, c: 0.01 * r + 0.02 * c, (30, 30))
    z[10, 12] = 50.0
    z[20, 5] = np.nan
    mask = mask_outliers(z)
    assert mask[10, 12] and mask[20, 5] and mask.sum() == 2
    filled = fill_masked(z, mask)
    assert filled[10, 12] == pytest.approx(0.01 * 10 + 0.02 * 12)
    assert filled[20, 5] == pytest.approx(0.01 * 20 + 0.02 * 5)


@pytest.mark.parametrize(("dtype", "top"), [(np.uint8, 255), (np.uint16, 65535)])
def test_images_scale_to_width_and_depth(tmp_path, dtype, top):
    pixels = np.zeros((11, 21), dtype=dtype)
    pixels[0, 0] = top  # the top-left pixel is white: the far (+y) edge seen from above
    Image.fromarray(pixels).save(tmp_path / "m.png")
    topo = read_heightmap(tmp_path / "m.png", width_mm=10.0, depth_mm=0.5)
    assert topo.pitch_x_mm == pytest.approx(0.5) and topo.pitch_y_mm == pytest.approx(0.5)
    assert topo.heights_mm[-1, 0] == pytest.approx(0.5) and topo.heights_mm.sum() == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("name", "content", "kwargs", "message"),
    [
        ("m.png", None, {}, "no physical scale"),
        ("m.npy", "npy", {}, "needs --pitch-mm"),
        ("m.bmp", b"xx", {}, "unsupported height map format"),
        ("m.al3d", b"nonsense" * 10, {}, "not an Alicona"),
        ("m.x3p", b"not a zip", {}, "not an .x3p file"),
        ("missing.png", "skip", {}, "no such height map"),
        ("m.npy", "nan", {"pitch_mm": 0.1}, "every sample is missing"),
    ],
)
def test_bad_height_maps(tmp_path, name, content, kwargs, message):
    path = tmp_path / name
    if content is None:
        Image.fromarray(np.zeros((4, 4), np.uint8)).save(path)
    elif content == "npy":
        np.save(path, np.zeros((4, 4)))
    elif content == "nan":
        np.save(path, np.full((4, 4), np.nan))
    elif content != "skip":
        path.write_bytes(content)
    with pytest.raises(DesignError, match=message):
        read_heightmap(path, **kwargs)


@pytest.mark.slow
def test_heightmap_and_emboss_commands(tmp_path):
    from tests.test_cli import printapp

    result = printapp("heightmap", DATA / "al3d-1.al3d", "--flatten", "plane", "--json", tmp_path / "p.json")
    assert result.returncode == 0, result.stderr
    params = __import__("json").loads((tmp_path / "p.json").read_text())["parameters"]
    assert params["Sq_um"] == pytest.approx(0.2898, abs=1e-4)
    image = tmp_path / "map.png"
    y, x = np.mgrid[0:200, 0:300]
    Image.fromarray((127 + 120 * np.sin(x / 9.0) * np.cos(y / 7.0)).astype(np.uint8)).save(image)
    stl = tmp_path / "slab.stl"
    result = printapp("emboss", image, "--width-mm", "15", "--depth-mm", "0.4", "-o", stl)
    assert result.returncode == 0, result.stderr
    import trimesh

    mesh = trimesh.load(stl)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.bounds[1][0] == pytest.approx(15.0)
    assert 2.0 < mesh.bounds[1][2] <= 2.4 + 1e-6
    bad = printapp("emboss", image, "-o", tmp_path / "x.stl")
    assert bad.returncode == 2 and "no physical scale" in bad.stderr
    assert not (tmp_path / "x.stl").exists()


def test_gwyddion_files_keep_scale_and_non_square_pixels(tmp_path):
    from gwyfile.objects import GwyContainer, GwyDataField, GwySIUnit

    heights = np.random.default_rng(1).normal(0, 1e-7, (20, 30))
    container = GwyContainer()
    container["/0/data"] = GwyDataField(
        heights, xreal=30e-6, yreal=40e-6, si_unit_xy=GwySIUnit(unitstr="m"), si_unit_z=GwySIUnit(unitstr="m")
    )
    container.tofile(str(tmp_path / "m.gwy"))
    topo = read_heightmap(tmp_path / "m.gwy")
    assert (topo.pitch_x_mm, topo.pitch_y_mm) == pytest.approx((1e-3, 2e-3))
    np.testing.assert_allclose(topo.heights_mm, heights * 1000)
    (tmp_path / "bad.gwy").write_bytes(b"GWYPnonsense")
    with pytest.raises(DesignError, match="cannot read the Gwyddion file"):
        read_heightmap(tmp_path / "bad.gwy")


@pytest.mark.slow
def test_heightmap_crop_and_bad_crop(tmp_path):
    from tests.test_cli import printapp

    result = printapp(
        "heightmap", DATA / "al3d-1.al3d", "--crop", "10:110,20:220", "--json", tmp_path / "c.json"
    )
    assert result.returncode == 0, result.stderr
    summary = __import__("json").loads((tmp_path / "c.json").read_text())
    assert summary["samples"] == [200, 100]
    bad = printapp("heightmap", DATA / "al3d-1.al3d", "--crop", "10:900,0:5")
    assert bad.returncode == 2 and "--crop" in bad.stderr
    bad = printapp("heightmap", DATA / "al3d-1.al3d", "--flatten", "cubic")
    assert bad.returncode == 2 and "--flatten: expected 'plane' or 'poly:K'" in bad.stderr
