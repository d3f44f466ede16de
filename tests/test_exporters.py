"""STL and 3MF writers, read back by trimesh (an independent reader); staging never leaves partial files."""

import io
import zipfile

import numpy as np
import pytest
import trimesh

from printapp.errors import DesignError
from printapp.exporters import OutputFolder, atomic_write_files, stl_bytes, threemf_bytes


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


def test_output_folder_moves_only_on_commit(tmp_path):
    dest = tmp_path / "out"
    with pytest.raises(RuntimeError), OutputFolder(dest) as out:
        out.write_text("a.txt", "half")
        raise RuntimeError("interrupted")
    assert list(dest.iterdir()) == []
    with OutputFolder(dest) as out:
        out.write_text("a.txt", "whole")
        out.commit()
    assert [p.name for p in dest.iterdir()] == ["a.txt"]


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
