"""End to end through the real command line: the demo, bad input, verification failures."""

import hashlib
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

pytestmark = pytest.mark.slow  # end to end: `make test-fast` leaves these out

ROOT = Path(__file__).parent.parent
SAMPLES = ROOT / "printapp" / "samples"


def printapp(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "printapp", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def demo_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("demo")
    first = printapp("demo", "-o", base / "a", "--quiet")
    second = printapp("demo", "-o", base / "b", "--quiet")
    return base, first, second


def test_demo_writes_every_output(demo_runs):
    base, first, _ = demo_runs
    assert first.returncode == 0, first.stderr
    names = {p.name for p in (base / "a").iterdir()}
    assert names == {
        "model.stl",
        "model.3mf",
        "slices.sl1",
        "preview.png",
        "brdf.npz",
        "design.resolved.toml",
        "report.html",
        "manifest.json",
    }
    assert "Traceback" not in first.stderr


def test_demo_model_is_a_watertight_slab_of_the_right_volume(demo_runs):
    base, _, _ = demo_runs
    mesh = trimesh.load(base / "a" / "model.stl", file_type="stl")
    assert mesh.is_watertight and mesh.is_winding_consistent
    manifest = json.loads((base / "a" / "manifest.json").read_text())
    w, d, _ = manifest["bbox_mm"]["size"]
    assert (w, d) == pytest.approx((20.0, 20.0))
    # Analytic bounds: the slab lies between the base box and the box to the relief's peak,
    # and the relief of zero-mean noise mapped onto [0, A] fills it about half way.
    base_box = 20.0 * 20.0 * 2.0
    assert base_box < mesh.volume < 20.0 * 20.0 * 2.3
    assert mesh.volume == pytest.approx(20.0 * 20.0 * (2.0 + 0.3 / 2), rel=0.01)
    assert manifest["volume_mm3"] == pytest.approx(mesh.volume, rel=1e-5)
    assert manifest["triangles"] == len(mesh.faces)
    assert manifest["watertight"] is True and manifest["verification"]["passed"] is True
    assert manifest["seeds"] == {"texture": 7, "brdf": 7, "render": 7}
    assert set(manifest["stages_s"]) >= {"relief", "check", "render", "write"}
    assert manifest["printer"]["layers"] == 46  # 1 + ceil((2.3 - 0.05) / 0.05)


def test_demo_preview_is_an_image_of_something(demo_runs):
    base, _, _ = demo_runs
    image = np.asarray(Image.open(base / "a" / "preview.png").convert("RGB"), dtype=float)
    assert image.shape == (768, 1024, 3)
    assert image.std() > 10  # not blank
    centre = image[300:470, 380:640].mean(axis=(0, 1))
    assert centre[0] > centre[2] + 30  # the orange tile fills the middle of the frame


def test_demo_is_deterministic(demo_runs):
    base, _, second = demo_runs
    assert second.returncode == 0, second.stderr
    for name in ("model.stl", "model.3mf", "slices.sl1", "design.resolved.toml", "preview.png", "brdf.npz"):
        assert digest(base / "a" / name) == digest(base / "b" / name), name


def run_bad(tmp_path, design_text: str | None, *extra):
    design = tmp_path / "d.toml"
    if design_text is not None:
        design.write_text(design_text)
    out = tmp_path / "out"
    result = printapp("design", design, "-o", out, "--quiet", *extra)
    return result, out


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (None, "no such design file"),
        ("[texture\nkind = 'fbm'\n", "TOML syntax error"),
        ("[texture]\noctavs = 3\n", "unknown key 'texture.octavs'; did you mean 'octaves'?"),
        ("[relief]\namplitude_mm = 'deep'\n", "relief.amplitude_mm: expected a number"),
        ("[texture]\nH = 2.0\n", "texture.H: expected a value in (0, 1], got 2.0"),
        ('[base]\nshape = "mesh"\npath = "missing.stl"\n', "no such mesh file"),
    ],
)
def test_bad_input_exits_2_with_one_sentence_and_writes_nothing(tmp_path, text, message):
    result, out = run_bad(tmp_path, text)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    assert len([line for line in result.stderr.splitlines() if line.strip()]) == 1
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_output_folder_as_user(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    result = printapp("demo", "-o", locked / "x", "--quiet")
    assert result.returncode == 2 and "not writable" in result.stderr


def test_output_folder_under_a_file_is_not_writable(tmp_path):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    result = printapp("demo", "-o", blocker / "out", "--quiet")
    assert result.returncode == 2
    assert "output folder is not writable" in result.stderr
    assert "Traceback" not in result.stderr


def test_output_folder_that_is_a_file(tmp_path):
    target = tmp_path / "taken"
    target.write_text("x")
    result = printapp("design", ROOT / "examples" / "fine_glossy.toml", "-o", target, "--quiet")
    assert result.returncode == 2
    assert "output folder is a file" in result.stderr
    assert target.read_text() == "x"


def test_failed_verification_exits_3_without_a_model(tmp_path):
    text = """
[base]
width_mm = 6.0
depth_mm = 6.0
[relief]
amplitude_um = 20      # less than one 50 um layer
[appearance]
anisotropy = [5.0, 10.0]
[render]
width_px = 64
height_px = 48
spp = 4
noise = 1.0  # tiny test renders: any noise passes (tests/test_convergence.py checks it)
"""
    result, out = run_bad(tmp_path, text)
    assert result.returncode == 3
    assert "less than one layer" in result.stderr and "anisotropy" in result.stderr
    names = {p.name for p in out.iterdir()}
    assert names == {"preview.png", "brdf.npz", "design.resolved.toml", "report.html", "manifest.json"}
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["verification"]["passed"] is False
    assert len(manifest["verification"]["reasons"]) == 2
    forced, out = run_bad(tmp_path, text, "--force")
    assert forced.returncode == 3
    assert (out / "model.stl").exists()


def test_mesh_design_end_to_end(tmp_path):
    design = tmp_path / "part.toml"
    design.write_text(
        f"""
[base]
path = "{(SAMPLES / "meshes" / "featuretype.STL").as_posix()}"
scale = 5.0
[texture]
feature_size_mm = 2.0
[relief]
amplitude_um = 150
[render]
width_px = 96
height_px = 64
spp = 4
noise = 1.0  # tiny test renders: any noise passes (tests/test_convergence.py checks it)
"""
    )
    result = printapp("design", design, "-o", tmp_path / "out", "--quiet")
    assert result.returncode == 0, result.stderr
    mesh = trimesh.load(tmp_path / "out" / "model.stl", file_type="stl")
    assert mesh.is_watertight and mesh.is_winding_consistent
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["genus"] == 9  # the part's holes survive the relief
    assert manifest["design"]["base"] == "mesh"


def test_printers_lists_the_profiles():
    result = printapp("printers")
    assert result.returncode == 0
    assert "prusa-sl1" in result.stdout and "prusa-sl1s-speed" in result.stdout and "47.25" in result.stdout


def test_help_lists_the_commands():
    result = printapp("--help")
    assert result.returncode == 0
    for command in ("demo", "design", "printers", "bench"):
        assert command in result.stdout


def test_every_help_text_is_shown_whole():
    # Rich markup had swallowed every "[...]" of the help texts: "Layer height [the profile's]."
    # read "Layer height ." and the --max-memory default and variable were gone.
    import typer.main
    from typer.testing import CliRunner

    from printapp.cli import app

    root = typer.main.get_group(app)
    checked = 0
    for name, command in [("", root), *sorted(root.commands.items())]:
        shown = " ".join(CliRunner().invoke(app, [*([name] if name else []), "--help"]).output.split())
        for param in command.params:
            text = getattr(param, "help", None)
            if text and "[" in text:
                assert " ".join(text.split()) in shown, (name, text)
                checked += 1
    assert checked >= 10


def test_bench_writes_json_and_chart(tmp_path):
    result = printapp("bench", "pitch", "--repeats", "1", "-o", tmp_path)
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "bench.json").read_text())
    rows = report["pitch"]["rows"]
    assert [r["pitch_mm"] for r in rows] == [0.4, 0.2, 0.1, 0.05, 0.025]
    errors = [r["rms_height_error_um"] for r in rows]
    assert errors[0] > errors[-1]  # finer pitch, smaller error
    assert (tmp_path / "pitch.png").stat().st_size > 1000
    unknown = printapp("bench", "nope", "-o", tmp_path)
    assert unknown.returncode == 2 and "unknown bench stage 'nope'" in unknown.stderr


@pytest.mark.parametrize("kind", ["scn", "fbm", "turbulence", "marble"])
def test_texture_images(tmp_path, kind):
    out = tmp_path / f"{kind}.png"
    result = printapp("texture", kind, "--size", "64", "-o", out)
    assert result.returncode == 0, result.stderr
    image = np.asarray(Image.open(out))
    assert image.shape == (64, 64) and image.dtype == np.uint8
    assert image.std() > 10


def test_texture_raw_values_match_the_library(tmp_path):
    import noise

    out = tmp_path / "v.npy"
    result = printapp(
        "texture", "fbm", "--size", "32", "--cells", "4", "--octaves", "3", "--seed", "2", "-o", out
    )
    assert result.returncode == 0, result.stderr
    axis = (np.arange(32) + 0.5) * (4 / 32)
    np.testing.assert_array_equal(np.load(out), noise.fbm_grid(axis, axis, octaves=3, seed=2))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["fbm", "--lacunarity", "1", "-o", "x.npy"], "--lacunarity: expected a number > 1"),
        (["fbm", "--H", "0", "-o", "x.npy"], "--H: expected a number in (0, 1]"),
        (["scn", "--cell-seed", "x", "-o", "x.npy"], "--cell-seed: expected one of"),
        (["scn", "-o", "x.jpg"], "expected an output file ending in .png or .npy"),
        (["scn", "-o", "missing/x.png"], "does not exist"),
    ],
)
def test_texture_bad_arguments(tmp_path, args, message):
    result = printapp("texture", *args, cwd=tmp_path)
    assert result.returncode == 2
    assert message in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_bench_noise_checks_the_fast_paths_against_the_plain_kernel(tmp_path, monkeypatch):
    # In process, at a twenty-fifth of the stage's sizes (the whole stage, 10^6 points a case,
    # takes 25 s; the command line itself is tested on `bench pitch` above).
    import printapp.bench.noise as stage
    from printapp.bench import run_bench

    monkeypatch.setattr(stage, "SCATTERED_POINTS", 40_000)
    monkeypatch.setattr(stage, "SLICE_SIDE", 256)
    monkeypatch.setattr(stage, "SWEEP_POINTS", 20_000)
    run_bench(["noise"], tmp_path, repeats=1)
    report = json.loads((tmp_path / "bench.json").read_text())["noise"]
    assert len(report["rows"]) == 4
    assert all(row["max_abs_diff_vs_plain"] < 1e-12 for row in report["rows"])
    distances = [r["histogram_tv_distance"] for r in report["impulse_sweep"]]
    assert distances[0] > distances[-1]  # more impulses, closer to the large-N limit
    assert (tmp_path / "noise.png").stat().st_size > 1000


@pytest.mark.parametrize("example", sorted(p.name for p in (ROOT / "examples").glob("*.toml")))
def test_every_example_builds_and_passes_verification(tmp_path, example):
    from printapp.design_io import load_design
    from printapp.pipeline import run_design

    design = load_design(ROOT / "examples" / example)
    if design.solve is not None:
        # A design for `printapp solve`: its start misses its targets by design; the design that
        # `printapp solve` found for it (examples/solved/) is the one that prints.
        design = load_design(ROOT / "examples" / "solved" / f"{Path(example).stem}.solved.toml")
    outcome = run_design(design, tmp_path, quiet=True, render=False)
    assert outcome.passed, outcome.reasons
    assert outcome.manifest["watertight"] and outcome.manifest["manifold"]
    assert (tmp_path / "model.stl").exists()
    # A stretched scn, fbm or turbulence on a mesh reports the tangent frames it followed.
    frame = outcome.manifest["relief"]["frame"]
    framed = design.base.shape == "mesh" and design.texture.kind != "lic" and design.texture.stretch != 1
    assert (frame is not None) == framed
    if framed:
        assert frame["field"] == (design.texture.field or frame["field"])
        assert 0 <= frame["singular_vertices"] <= frame["blended_vertices"] <= frame["vertices"]


def test_texture_lic_and_field_errors(tmp_path):
    out = tmp_path / "lic.png"
    result = printapp("texture", "lic", "--field", "constant:30", "--size", "64", "--length", "8", "-o", out)
    assert result.returncode == 0, result.stderr
    assert np.asarray(Image.open(out)).std() > 10
    bad = printapp("texture", "lic", "--field", "spiral", "-o", tmp_path / "x.png")
    assert bad.returncode == 2 and "--field: expected 'constant:ANGLE', 'swirl' or 'image:FILE'" in bad.stderr
    mesh_only = printapp("texture", "lic", "--field", "curvature:max", "-o", tmp_path / "x.png")
    assert mesh_only.returncode == 2 and "needs a mesh base" in mesh_only.stderr
    missing = printapp("texture", "lic", "--field", "image:none.png", "-o", tmp_path / "x.png")
    assert missing.returncode == 2 and "no such field image" in missing.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lic.png"]


def test_lic_fields_that_do_not_fit_the_base_are_refused_clearly(tmp_path):
    mesh = (SAMPLES / "meshes" / "featuretype.STL").as_posix()
    result, _ = run_bad(
        tmp_path, f'[base]\npath = "{mesh}"\n[texture]\nkind = "lic"\nfield = "image:a.png"\n'
    )
    assert result.returncode == 2
    assert "a.png: no such field image" in result.stderr
    result, _ = run_bad(tmp_path, '[texture]\nkind = "lic"\nfield = "curvature:max"\n')
    assert result.returncode == 2
    assert "needs a mesh base" in result.stderr


def test_lic_streaks_follow_the_field_on_a_tile():
    from printapp.design import design_from_dict
    from printapp.texture import relief_heightfield
    from render.microfacet import slope_roughness

    design = design_from_dict(
        {
            "base": {"width_mm": 8.0, "depth_mm": 8.0},
            "texture": {"kind": "lic", "field": "constant:30", "feature_size_mm": 0.2, "length_mm": 1.0},
            "relief": {"amplitude_um": 100},
        }
    )
    rough = slope_roughness(*relief_heightfield(design).slopes())
    # slopes are steepest across the streaks: the major roughness axis is at 30 + 90 degrees
    assert np.degrees(rough.major_azimuth_rad) == pytest.approx(120.0, abs=6.0)
    assert rough.anisotropy > 2.0


def test_bench_frames(tmp_path, monkeypatch):
    # In process, on a small tube and two stretches: the stage's full size (a 10^6-vertex tube,
    # six stretches, three seeds) takes minutes, and is what `printapp bench frames` runs.
    import printapp.bench.frames as stage
    from printapp.bench import run_bench

    monkeypatch.setattr(stage, "TUBE_VERTICES", 60_000)
    monkeypatch.setattr(stage, "STRETCHES", (1.0, 6.0))
    monkeypatch.setattr(stage, "SEEDS", (1,))
    run_bench(["frames"], tmp_path, repeats=1)
    report = json.loads((tmp_path / "bench.json").read_text())["frames"]
    rows = {(r["method"], r["dtype"]): r for r in report["rows"]}
    assert rows[("duff", "float32")]["max_error"] < 1e-6
    assert rows[("frisvad", "float32")]["max_error"] > 1e-3
    costs = report["framed_vs_flat"]
    assert [c["field"].split(" (")[0] for c in costs] == ["along the axis", "around it", "oblique"]
    assert all(c["framed_ns_per_sample"] > 0 and c["flat_ns_per_sample"] > 0 for c in costs)
    isotropic, stretched = report["anisotropy"]
    assert isotropic["noise_ratio"] == pytest.approx(1.0, rel=0.15)
    assert stretched["noise_ratio"] == pytest.approx(6.0, rel=0.15)
    assert stretched["worst_angle_error_deg"] < 5.0
    assert (tmp_path / "frames.png").stat().st_size > 1000


def test_slice_command_writes_an_archive_and_a_png_stack(tmp_path):
    out = tmp_path / "part.sl1"
    stack = tmp_path / "stack"
    result = printapp("slice", SAMPLES / "meshes" / "featuretype.STL", "-o", out, "--png-dir", stack)
    assert result.returncode == 0, result.stderr
    with zipfile.ZipFile(out) as archive:
        assert archive.namelist()[0] == "config.ini"
        count = len([n for n in archive.namelist() if n.endswith(".png")])
    assert count == len(list(stack.glob("*.png"))) > 10
    assert (stack / "config.ini").exists()
    image = Image.open(stack / "00000.png")
    assert image.mode == "L" and image.size == (1440, 2560)


def test_slice_command_writes_no_png_stack_when_the_archive_cannot_be_written(tmp_path):
    stack = tmp_path / "stack"
    out = tmp_path / "missing" / "part.sl1"
    result = printapp("slice", SAMPLES / "meshes" / "featuretype.STL", "-o", out, "--png-dir", stack)
    assert result.returncode == 2 and "does not exist" in result.stderr
    assert not list(stack.rglob("*.png"))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["printapp/samples/meshes/teapot.stl", "-o", "x.sl1"], "found 64 open edges"),
        (
            ["printapp/samples/meshes/featuretype.STL", "-o", "x.sl1", "--printer", "elegoo"],
            "--printer: unknown printer",
        ),
        (
            ["printapp/samples/meshes/featuretype.STL", "-o", "x.zip"],
            "expected an output file ending in .sl1",
        ),
        (
            ["printapp/samples/meshes/featuretype.STL", "-o", "x.sl1", "--layer-height-mm", "0.3"],
            "outside what",
        ),
    ],
)
def test_slice_bad_input(tmp_path, args, message):
    args = [str(ROOT / a) if a.startswith("printapp/samples/") else a for a in args]
    result = printapp("slice", *args, cwd=tmp_path)
    assert result.returncode == 2
    assert message in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_displace_repairs_and_writes_obj_with_material(tmp_path):
    out = tmp_path / "teapot.obj"
    result = printapp(
        "displace", SAMPLES / "meshes" / "teapot.stl", "--repair", "--amplitude-mm", "0.05",
        "--feature-size-mm", "3", "--refractive-index", "1.52", "-o", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    mtl = (tmp_path / "teapot.mtl").read_text()
    assert "Ni 1.52" in mtl and "illum 4" in mtl
    text = out.read_text()
    assert "mtllib teapot.mtl" in text and "\nvn " in text
    mesh = trimesh.load(out, force="mesh")
    assert mesh.is_watertight


def test_displace_stretches_the_noise_along_the_field(tmp_path):
    out = tmp_path / "cylinder.stl"
    result = printapp(
        "displace", ROOT / "examples" / "cylinder.stl", "--amplitude-mm", "0.08", "--feature-size-mm", "1.5",
        "--stretch", "5", "--field", "direction:1,0,0", "-o", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "stretched 5x along direction:1,0,0 in each vertex's tangent frame" in result.stdout
    singular = int(result.stdout.split(" singular vertices")[0].rsplit(";", 1)[1].replace(",", ""))
    assert singular > 1000  # the ends, where the axis (x) has no direction in the surface
    assert trimesh.load(out).is_watertight


def test_displace_writes_ply_and_refuses_open_meshes(tmp_path):
    out = tmp_path / "part.ply"
    result = printapp(
        "displace",
        SAMPLES / "meshes" / "featuretype.STL",
        "--scale",
        "5",
        "--amplitude-mm",
        "0.1",
        "-o",
        out,
    )
    assert result.returncode == 0, result.stderr
    mesh = trimesh.load(out)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.euler_number == 2 - 2 * 9
    bad = printapp(
        "displace",
        SAMPLES / "meshes" / "teapot.stl",
        "--amplitude-mm",
        "0.1",
        "-o",
        tmp_path / "t.stl",
    )
    assert bad.returncode == 2 and "printapp displace --repair" in bad.stderr
    assert not (tmp_path / "t.stl").exists()
    bad = printapp(
        "displace",
        SAMPLES / "meshes" / "featuretype.STL",
        "--amplitude-mm",
        "-1",
        "-o",
        out,
    )
    assert bad.returncode == 2 and "--amplitude-mm:" in bad.stderr  # the flag the user typed
