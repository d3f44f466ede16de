"""Slicing: PrusaSlicer's conventions, exact coverage, .sl1 round trips, the as-printed relief."""

import io
import shutil
import subprocess
import zipfile
from pathlib import Path

import manifold3d
import numpy as np
import pytest
import trimesh

from noise.heightfield import HeightField
from slicing import PRINTERS, read_sl1, slice_heights, slice_mesh, write_sl1
from slicing.printed import pixel_centres_mm, printed_heights

ROOT = Path(__file__).parent.parent
SL1 = PRINTERS["prusa-sl1"]
PEER_INI = ROOT / "printapp" / "bench" / "peers" / "sl1_flat.ini"


def manifold_mesh(m: manifold3d.Manifold) -> trimesh.Trimesh:
    mesh = m.to_mesh()
    return trimesh.Trimesh(
        mesh.vert_properties[:, :3].astype(float), mesh.tri_verts.astype(np.int64), process=False
    )


@pytest.fixture(scope="module")
def lshape() -> trimesh.Trimesh:
    """An asymmetric L: a 10 x 2 mm arm along x and a 2 x 6 mm arm along y, 3 mm tall."""
    a = manifold3d.Manifold.cube([10.0, 2.0, 3.0])
    b = manifold3d.Manifold.cube([2.0, 6.0, 3.0])
    return manifold_mesh(a + b)


def sl1_bytes(mesh, **kwargs) -> bytes:
    buffer = io.BytesIO()
    write_sl1(buffer, slice_mesh(mesh.vertices, mesh.faces, SL1, **kwargs), "part")
    return buffer.getvalue()


def test_print_time_is_prusaslicers():
    """PrusaSlicer 2.5.0's printTime on the SL1 profile (exposure 7.5 s, first 35 s), recorded
    from its config.ini for boxes of 20 all-slow, 34 and 800 all-fast layers of 0.05 mm."""
    from slicing.sl1 import print_time_s

    sl1 = PRINTERS["prusa-sl1"]
    assert print_time_s(sl1, [0.05] * 20, [True] * 20) == pytest.approx(555.0, abs=1e-6)
    assert print_time_s(sl1, [0.05] * 34, [False] * 34) == pytest.approx(653.5, abs=1e-6)
    assert print_time_s(sl1, [0.05] * 800, [False] * 800) == pytest.approx(10420.0, abs=1e-3)


def test_a_float32_top_adds_no_empty_layer():
    """A 1.7 mm box stored in float32 has its top at 1.70000005 mm: 34 layers, as PrusaSlicer 2.5 makes."""
    top = float(np.float32(1.7))
    assert top > 1.7
    assert len(slice_heights(top, 0.05, 0.05)) == 34 == len(slice_heights(1.7, 0.05, 0.05))
    assert len(slice_heights(1.7251, 0.05, 0.05)) == 35  # the plane at 1.725 cuts it
    box = trimesh.creation.box(extents=(5.0, 5.0, 1.7))
    box.apply_translation((0.0, 0.0, 0.85))
    vertices = np.asarray(box.vertices, dtype=np.float32).astype(np.float64)
    slices = slice_mesh(vertices, box.faces, SL1)
    assert slices.n_layers == 34
    assert all(area > 0 for area in slices.section_areas_mm2())


def test_a_part_below_the_first_slice_plane_is_refused():
    with pytest.raises(ValueError, match="below the first slice plane"):
        slice_heights(1e-6, 0.05, 0.05)


def test_slice_heights_follow_prusaslicer():
    z = slice_heights(3.0, 0.05, 0.05)
    assert len(z) == 1 + int(np.ceil((3.0 - 0.05) / 0.05))
    assert z[0] == pytest.approx(0.025)
    np.testing.assert_allclose(np.diff(z[1:]), 0.05)
    assert z[1] == pytest.approx(0.075)
    assert len(slice_heights(0.03, 0.05, 0.05)) == 1
    z = slice_heights(1.0, 0.1, 0.05)
    assert z[0] == pytest.approx(0.025) and z[1] == pytest.approx(0.1)


def test_lshape_layers_orientation_and_mirroring(lshape):
    config, layers = read_sl1(io.BytesIO(sl1_bytes(lshape)))
    assert len(layers) == 60 and config["numFast"] == "60" and config["jobDir"] == "part"
    image = layers[0]
    assert image.shape == (2560, 1440)  # portrait: 1440 wide, 2560 tall
    lit = np.argwhere(image > 127)
    rows, cols = lit[:, 0], lit[:, 1]
    # x runs down the rows (large x at the top), y along the columns (mirror_x): the long
    # arm fills all rows at small y (left), the short arm all columns at small x (bottom)
    assert rows.max() - rows.min() + 1 == pytest.approx(10 / SL1.pitch_x_mm, abs=2)
    assert cols.max() - cols.min() + 1 == pytest.approx(6 / SL1.pitch_y_mm, abs=2)
    bottom = image[rows.max() - 5]
    top = image[rows.min() + 5]
    assert (bottom > 127).sum() == pytest.approx(6 / SL1.pitch_y_mm, abs=2)
    assert (top > 127).sum() == pytest.approx(2 / SL1.pitch_y_mm, abs=2)
    assert np.argmax(top > 127) == cols.min()  # the long arm sits at small y, on the left
    # centred on the display
    assert (rows.min() + rows.max()) / 2 == pytest.approx(1280, abs=1.5)
    assert (cols.min() + cols.max()) / 2 == pytest.approx(720, abs=1.5)


def test_disc_coverage_equals_its_area():
    disc = manifold_mesh(manifold3d.Manifold.cylinder(1.0, 20.0, 20.0, 4096))
    slices = slice_mesh(disc.vertices, disc.faces, SL1)
    polygon_area = 0.5 * 4096 * 20.0**2 * np.sin(2 * np.pi / 4096)
    pixel_area = SL1.pitch_x_mm * SL1.pitch_y_mm
    for _, coverage in slices.coverages():
        grey = slices.grey(coverage)
        assert grey.sum() / 255 * pixel_area == pytest.approx(polygon_area, rel=1e-3)
        assert coverage.sum() * pixel_area == pytest.approx(polygon_area, rel=1e-9)
        partial = (grey > 0) & (grey < 255)
        assert partial.sum() > 1000  # anti-aliased edge


def test_holes_stay_empty():
    ring = manifold_mesh(
        manifold3d.Manifold.cylinder(1.0, 10.0, 10.0, 256) - manifold3d.Manifold.cylinder(1.0, 5.0, 5.0, 256)
    )
    slices = slice_mesh(ring.vertices, ring.faces, SL1)
    _, coverage = next(iter(slices.coverages()))
    centre = coverage[
        slices.rows // 2 - 20 : slices.rows // 2 + 20, slices.cols // 2 - 20 : slices.cols // 2 + 20
    ]
    assert centre.max() < 1e-12  # empty up to the accumulation's rounding
    expected = 0.5 * 256 * (100 - 25) * np.sin(2 * np.pi / 256)
    assert coverage.sum() * SL1.pitch_x_mm * SL1.pitch_y_mm == pytest.approx(
        expected, rel=1e-7
    )  # float32 vertices


def test_sl1_archive_layout_and_determinism(lshape):
    data = sl1_bytes(lshape)
    assert data == sl1_bytes(lshape)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        names = archive.namelist()
        assert names[:2] == ["config.ini", "prusaslicer.ini"]
        assert names[2:] == [f"part{k:05d}.png" for k in range(60)]
        # the ini files deflated; the layers stored, their PNG streams being deflated already
        kinds = [i.compress_type for i in archive.infolist()]
        assert kinds == [zipfile.ZIP_DEFLATED] * 2 + [zipfile.ZIP_STORED] * 60
        assert not any(n.endswith("/") for n in names)
        keys = [line.split(" = ")[0] for line in archive.read("config.ini").decode().splitlines()]
        assert keys == sorted(keys)
        assert set(keys) == {
            "action", "expTime", "expTimeFirst", "expUserProfile", "fileCreationTimestamp", "hollow",
            "jobDir", "layerHeight", "materialName", "numFade", "numFast", "numSlow", "printProfile",
            "printTime", "printerModel", "printerProfile", "printerVariant", "prusaSlicerVersion",
            "usedMaterial",
        }  # fmt: skip
        config = dict(line.split(" = ", 1) for line in archive.read("config.ini").decode().splitlines())
        assert float(config["usedMaterial"]) == pytest.approx(lshape.volume / 1000, rel=0.01)
        ini = dict(line.split(" = ", 1) for line in archive.read("prusaslicer.ini").decode().splitlines())
        assert ini["display_mirror_x"] == "1" and ini["display_orientation"] == "portrait"


def test_no_antialias_gives_pure_black_and_white(lshape):
    _, layers = read_sl1(io.BytesIO(sl1_bytes(lshape, antialias=False)))
    assert set(np.unique(layers[10]).tolist()) == {0, 255}


@pytest.mark.parametrize(
    ("mesh", "kwargs", "message"),
    [
        (trimesh.creation.box(extents=(130.0, 10.0, 10.0)), {}, "too large in x by 9.04 mm"),
        (trimesh.creation.box(extents=(10.0, 10.0, 151.0)), {}, "too large in z by 1.00 mm"),
        (trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=int)), {}, "found none"),
        (trimesh.creation.box(), {"layer_height_mm": 0.2}, "outside what Original Prusa SL1 can print"),
    ],
)
def test_bad_input(mesh, kwargs, message):
    with pytest.raises(ValueError, match=message):
        slice_mesh(mesh.vertices, mesh.faces, SL1, **kwargs)


def test_as_printed_tile_recovers_the_design():
    from printapp.design import design_from_dict
    from printapp.mesh import slab_from_heightfield
    from printapp.relief import as_printed
    from printapp.texture import relief_heightfield

    design = design_from_dict({"base": {"width_mm": 6.0, "depth_mm": 5.0}, "relief": {"amplitude_um": 200}})
    field = relief_heightfield(design)
    mesh = slab_from_heightfield(field, 2.0)
    slices = slice_mesh(mesh.vertices, mesh.faces, SL1)
    printed = as_printed(field, slices, 2.0)
    sx, sy = field.slopes()
    steepest = float(np.max(np.hypot(sx, sy)))
    # within half a layer, plus what half a pixel of lateral offset can add on a slope
    assert printed.max_error_mm <= 0.025 + 0.5 * SL1.pitch_mm * steepest
    assert printed.rms_error_mm < 0.025
    heights = printed_heights(slices)
    x, _ = pixel_centres_mm(slices)
    assert heights.max() == pytest.approx(2.2, abs=0.05)
    assert len(x) == slices.cols


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("prusa-slicer") is None, reason="PrusaSlicer is not installed")
def test_layers_match_prusaslicer(tmp_path, lshape):
    stl = tmp_path / "lshape.stl"
    lshape.export(stl)
    subprocess.run(
        ["prusa-slicer", "--datadir", str(tmp_path / "dd"), "--loglevel", "1", "--load",
         str(PEER_INI), "--export-sla", "-o", str(tmp_path / "ps.sl1"), str(stl)],
        check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    with open(tmp_path / "ps.sl1", "rb") as stream:
        config_ps, theirs = read_sl1(stream)
    config_ours, ours = read_sl1(io.BytesIO(sl1_bytes(lshape)))
    assert len(ours) == len(theirs)
    assert set(config_ours) == set(config_ps)
    for key in ("numFast", "numSlow", "numFade", "expTime", "expTimeFirst", "layerHeight"):
        assert config_ours[key] == config_ps[key], key
    assert float(config_ours["printTime"]) == pytest.approx(float(config_ps["printTime"]), abs=1e-3)
    assert float(config_ours["usedMaterial"]) == pytest.approx(float(config_ps["usedMaterial"]), rel=1e-3)
    for a, b in zip(ours, theirs, strict=True):
        a, b = a.astype(int), b.astype(int)
        union = ((a > 127) | (b > 127)).sum()
        assert ((a > 127) & (b > 127)).sum() / union > 0.998
        edge = ((a > 0) & (a < 255)) | ((b > 0) & (b < 255))
        assert np.abs(a - b)[edge].mean() < 2.0


@pytest.mark.slow
def test_round_trip_gives_back_the_rendered_layers(lshape):
    slices = slice_mesh(lshape.vertices, lshape.faces, SL1)
    expected = [slices.display_image(slices.grey(coverage)).copy() for _, coverage in slices.coverages()]
    buffer = io.BytesIO()
    write_sl1(buffer, slices, "part")
    buffer.seek(0)
    _, layers = read_sl1(buffer)
    assert len(layers) == len(expected)
    for got, want in zip(layers, expected, strict=True):
        np.testing.assert_array_equal(got, want)


def test_bad_archives():
    with pytest.raises(ValueError, match="expected an .sl1 archive"):
        read_sl1(io.BytesIO(b"not a zip"))
    empty = io.BytesIO()
    with zipfile.ZipFile(empty, "w") as archive:
        archive.writestr("hello.txt", "x")
    empty.seek(0)
    with pytest.raises(ValueError, match="expected config.ini"):
        read_sl1(empty)


def test_heightfield_path_gives_the_same_archive_as_the_slab_mesh():
    from printapp.design import design_from_dict
    from printapp.mesh import slab_from_heightfield
    from printapp.texture import relief_heightfield
    from slicing import slice_heightfield

    design = design_from_dict({"base": {"width_mm": 7.0, "depth_mm": 5.0}, "relief": {"pitch_mm": 0.1}})
    field = relief_heightfield(design)
    mesh = slab_from_heightfield(field, 2.0)
    via_mesh, via_field = io.BytesIO(), io.BytesIO()
    write_sl1(via_mesh, slice_mesh(mesh.vertices, mesh.faces, SL1), "tile")
    write_sl1(via_field, slice_heightfield(field, 2.0, SL1), "tile")
    assert via_mesh.getvalue() == via_field.getvalue()
    with pytest.raises(ValueError, match="top must stay above"):
        slice_heightfield(HeightField(np.full((3, 3), -5.0), 0.1, 0.1), 2.0, SL1)


def test_winding_number_finds_self_overlap():
    box = trimesh.creation.box(extents=(10.0, 10.0, 3.0))
    inner = trimesh.creation.box(extents=(4.0, 4.0, 3.0))
    inner.apply_translation((3.0, 3.0, 0.5))
    overlapping = trimesh.util.concatenate([box, inner])  # closed shells, never merged
    assert slice_mesh(box.vertices, box.faces, SL1).max_winding() == pytest.approx(1.0)
    assert slice_mesh(overlapping.vertices, overlapping.faces, SL1).max_winding() == pytest.approx(2.0)


def test_layer_kernels_compile_once_wherever_a_layer_falls():
    """A layer's window cut in Python was typed C-contiguous when it spanned the whole width and
    not otherwise, so a part that filled its window on some layer compiled the kernels again
    (a second or two on the user's first run, past `printapp warmup`)."""
    from slicing.deflate import _deflate_layer
    from slicing.raster import _max_winding, _rasterise_layer_grey

    # A cone: its bottom layers fill the window, its top ones a small part of it.
    cone = trimesh.creation.cone(radius=5.0, height=4.0, sections=32)
    cone.apply_translation((0.0, 0.0, 0.2))
    slices = slice_mesh(cone.vertices, cone.faces, SL1)
    assert slices.max_winding() == pytest.approx(1.0)
    widths = {slices.layer_grey(k)[0].shape[1] for k in range(slices.n_layers)}
    assert max(widths) == slices.cols and min(widths) < slices.cols // 2
    write_sl1(io.BytesIO(), slices, "cone")
    assert len(_max_winding.signatures) == 1
    assert len(_rasterise_layer_grey.signatures) == 1
    assert len(_deflate_layer.signatures) == 1


def test_the_plane_search_is_numpys_searchsorted():
    """The slicer's hand-written binary search against ``np.searchsorted(side="left")``: repeated
    heights, values on, between and beyond them, infinities and NaN (which sorts last)."""
    from slicing.raster import _first_at_least

    rng = np.random.default_rng(3)
    for size in (0, 1, 2, 7, 64, 801):
        heights = np.sort(np.round(rng.uniform(0.0, 10.0, size), 1))  # rounding repeats some
        probes = np.concatenate(
            [heights, heights + 0.05, rng.uniform(-1.0, 11.0, 50), [-np.inf, np.inf, np.nan, 0.0, 10.0]]
        )
        expected = np.searchsorted(heights, probes, side="left")
        assert [_first_at_least(heights, float(p)) for p in probes] == expected.tolist()


@pytest.mark.slow
def test_fresh_processes_write_the_same_archive(tmp_path):
    """Six processes slice a 40 mm sphere (800 layers) and must write the same bytes.

    With ISA-L's level-1 deflate for the part's rows, 1 or 2 of every ten such runs wrote a
    layer whose bytes (not pixels) differed from the others': this test failed once in three
    tries on that code. The byte-for-byte check within one process never caught it.
    """
    import hashlib
    import sys

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=20.0)
    sphere.apply_translation([0.0, 0.0, 20.0])
    stl = tmp_path / "sphere.stl"
    sphere.export(stl)
    runs = []
    for k in range(6):
        out = tmp_path / f"run{k}" / "sphere.sl1"
        out.parent.mkdir()
        runs.append(
            subprocess.Popen([sys.executable, "-m", "printapp", "slice", str(stl), "-o", str(out), "--quiet"])
        )
    assert [run.wait(timeout=300) for run in runs] == [0] * 6
    archives = [(tmp_path / f"run{k}" / "sphere.sl1").read_bytes() for k in range(6)]
    digests = {hashlib.sha256(archive).hexdigest() for archive in archives}
    assert len(digests) == 1
