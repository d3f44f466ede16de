"""STL and 3MF writers, read back by trimesh (an independent reader); staging never leaves partial files."""

import io
import zipfile

import numpy as np
import pytest
import trimesh

from printapp.errors import DesignError
from printapp.exporters import stl_bytes, threemf_bytes
from printapp.outputs import FILE_MODE, OutputFolder, atomic_write_files, remove_stale_staging


@pytest.fixture
def sphere():
    return trimesh.creation.icosphere(subdivisions=2, radius=3.0)


def test_stl_round_trip(sphere):
    data = stl_bytes(sphere.vertices, sphere.faces)
    assert len(data) == 84 + 50 * len(sphere.faces)
    back = trimesh.load(io.BytesIO(data), file_type="stl")
    assert back.is_watertight
    assert back.volume == pytest.approx(sphere.volume, rel=1e-5)
    stored = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    np.testing.assert_allclose(stored["n"], sphere.face_normals, atol=1e-6)


def test_3mf_round_trip_and_determinism(sphere):
    data = threemf_bytes(sphere.vertices, sphere.faces, name='ball "<1>"')
    assert data == threemf_bytes(sphere.vertices, sphere.faces, name='ball "<1>"')
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert set(archive.namelist()) == {"[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model"}
    back = trimesh.load(io.BytesIO(data), file_type="3mf", force="mesh")
    assert len(back.faces) == len(sphere.faces)
    assert back.volume == pytest.approx(sphere.volume, rel=1e-6)


def test_triangle_elements_are_pythons_decimal_formatting():
    from printapp.decimal_text import triangle_elements

    rng = np.random.default_rng(4)
    faces = rng.integers(0, 10 ** rng.integers(1, 13, size=(500, 3)), size=(500, 3))
    faces[:3] = [[0, 9, 10], [99, 100, 101], [2**40, 7, 0]]  # every number of digits's edges
    plain = ('<triangle v1="%d" v2="%d" v3="%d"/>' * len(faces)) % tuple(faces.ravel().tolist())
    assert triangle_elements(faces) == plain.encode("ascii")
    assert triangle_elements(np.zeros((0, 3), dtype=np.int64)) == b""
    with pytest.raises(ValueError, match="faces"):
        triangle_elements(np.array([[0, -1, 2]]))


def test_output_folder_moves_only_on_commit_and_creates_nothing_before(tmp_path):
    dest = tmp_path / "deep" / "out"
    with pytest.raises(RuntimeError), OutputFolder(dest) as out:
        out.write_text("a.txt", "half")
        raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its parent nor a staging folder
    with OutputFolder(dest) as out:
        out.write_text("a.txt", "whole")
        out.commit()
    assert [p.name for p in dest.iterdir()] == ["a.txt"]
    assert [p.name for p in dest.parent.iterdir()] == ["out"]


def test_output_folder_swaps_in_whole_and_leaves_nothing_stale(tmp_path):
    dest = tmp_path / "out"
    with OutputFolder(dest) as out:
        out.write_text("model.stl", "old model")
        out.write_text("manifest.json", "old")
        out.commit()
    with OutputFolder(dest) as out:  # a failed verdict: no model this time
        out.write_text("manifest.json", "failed")
        out.commit()
    assert sorted(p.name for p in dest.iterdir()) == ["manifest.json"]
    assert (dest / "manifest.json").read_text() == "failed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_output_folder_keeps_files_it_does_not_own(tmp_path):
    dest = tmp_path / "out"
    dest.mkdir()
    (dest / "notes.txt").write_text("mine")
    (dest / "model.stl").write_text("stale")
    with OutputFolder(dest, owned=lambda name: name != "notes.txt") as out:
        out.write_text("manifest.json", "new")
        out.commit()
    assert sorted(p.name for p in dest.iterdir()) == ["manifest.json", "notes.txt"]


def test_outputs_get_the_umask_mode(tmp_path):
    single = atomic_write_files([(tmp_path / "a.bin", b"x")])[0]
    with OutputFolder(tmp_path / "out") as out:
        out.write_bytes("b.bin", b"y")
        (folder_file,) = out.commit()
    assert single.stat().st_mode & 0o777 == FILE_MODE
    assert folder_file.stat().st_mode & 0o777 == FILE_MODE


def test_a_killed_runs_staging_is_removed_by_the_next_run(tmp_path):
    import subprocess
    import sys

    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    pid = int(dead.stdout)
    stale = tmp_path / f".out.printapp-partial-{pid}-abc123"
    stale.mkdir()
    (stale / "model.stl").write_text("half")
    live = tmp_path / f".out.printapp-partial-{__import__('os').getpid()}-def456"
    live.mkdir()
    assert remove_stale_staging(tmp_path / "out") == [stale]
    assert not stale.exists() and live.exists()


def test_output_folder_that_is_a_file(tmp_path):
    target = tmp_path / "file"
    target.write_text("x")
    with pytest.raises(DesignError, match="output folder is a file"), OutputFolder(target):
        pass


def test_several_files_appear_together_or_not_at_all(tmp_path):
    (tmp_path / "sub").mkdir()
    first, second = tmp_path / "a.json", tmp_path / "sub" / "b.png"
    assert atomic_write_files([(first, b"{}"), (second, b"png")]) == [first, second]
    assert first.read_bytes() == b"{}" and second.read_bytes() == b"png"
    # a later destination that cannot be written stops all of them, before anything moves
    for blocked in (tmp_path / "missing" / "c.png", tmp_path / "sub"):
        with pytest.raises(DesignError, match="folder"):
            atomic_write_files([(first, b"new"), (blocked, b"x")])
        assert first.read_bytes() == b"{}"
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.json", "b.png", "sub"]  # no temporaries left


def test_zip_bytes_is_a_zip_that_zipfile_and_crc_checks_read():
    import zipfile

    from printapp.exporters import zip_bytes

    entries = [("a.txt", b"hello " * 1000), ("dir/b.bin", bytes(range(256)) * 50), ("empty", b"")]
    data = zip_bytes(entries)
    assert data == zip_bytes(entries)  # fixed dates: the same bytes
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert archive.testzip() is None  # every CRC checks
        assert archive.namelist() == [name for name, _ in entries]
        for name, payload in entries:
            info = archive.getinfo(name)
            assert info.compress_type == zipfile.ZIP_DEFLATED and info.date_time == (1980, 1, 1, 0, 0, 0)
            assert archive.read(name) == payload
    assert len(data) < 2_000  # deflated: 6 kB of text and 12.8 kB of a repeated pattern
