"""The binary STL fast path of ``printapp slice`` against trimesh's reading of the same files."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from printapp.errors import DesignError
from printapp.stl import closed_and_oriented, load_closed_stl, read_binary_stl, signed_volume

SAMPLES = Path(__file__).parent.parent / "printapp" / "samples" / "meshes"


def stl_of(mesh: trimesh.Trimesh) -> bytes:
    return trimesh.exchange.stl.export_stl(mesh)


@pytest.mark.parametrize("mesh", [trimesh.creation.icosphere(3), trimesh.creation.box((3.0, 2.0, 1.0))])
def test_same_vertices_and_faces_as_trimesh(tmp_path, mesh):
    path = tmp_path / "m.stl"
    path.write_bytes(stl_of(mesh))
    ours_v, ours_f = read_binary_stl(path.read_bytes(), "m")
    theirs = trimesh.load(path, process=True)
    np.testing.assert_array_equal(ours_v, theirs.vertices)
    np.testing.assert_array_equal(ours_f, theirs.faces)
    assert closed_and_oriented(ours_f) == (0, 0)
    assert signed_volume(ours_v, ours_f) == pytest.approx(theirs.volume, rel=1e-12)


def test_open_flipped_and_inside_out_meshes(tmp_path):
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    path = tmp_path / "b.stl"
    path.write_bytes(stl_of(trimesh.Trimesh(box.vertices, box.faces[1:], process=False)))
    with pytest.raises(DesignError, match="open edges"):
        load_closed_stl(path)
    flipped = box.faces.copy()
    flipped[0] = flipped[0, ::-1]
    path.write_bytes(stl_of(trimesh.Trimesh(box.vertices, flipped, process=False)))
    with pytest.raises(DesignError, match="flipped"):
        load_closed_stl(path)
    path.write_bytes(stl_of(trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)))
    vertices, faces = load_closed_stl(path)
    assert signed_volume(vertices, faces) == pytest.approx(1.0)


def test_signed_zero_is_one_vertex_and_nan_is_refused():
    corners = np.zeros((1, 3, 3), np.float32)
    corners[0, 1] = (-0.0, 1.0, 0.0)
    corners[0, 2] = (1.0, 0.0, -0.0)
    record = np.zeros(1, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    record["v"] = corners
    data = b"\0" * 80 + (1).to_bytes(4, "little") + record.tobytes()
    vertices, faces = read_binary_stl(data, "z")
    assert len(vertices) == 3 and faces.tolist() == [[0, 1, 2]]
    record["v"][0, 0, 0] = np.nan
    with pytest.raises(DesignError, match="NaN"):
        read_binary_stl(b"\0" * 80 + (1).to_bytes(4, "little") + record.tobytes(), "z")
    with pytest.raises(DesignError, match="not a binary STL"):
        read_binary_stl(data[:-1], "z")


def test_edge_counts_match_a_dictionary_of_directed_edges():
    # The sort-and-search count against the plain definition: per directed edge, how many
    # faces use it, and whether its reverse is used at all.
    from collections import Counter

    import trimesh

    def by_dictionary(faces):
        edges = Counter((int(f[i]), int(f[(i + 1) % 3])) for f in faces for i in range(3))
        open_edges = sum(n for (a, b), n in edges.items() if (b, a) not in edges)
        return open_edges, sum(1 for n in edges.values() if n > 1)

    sphere = np.asarray(trimesh.creation.icosphere(subdivisions=3).faces)
    rng = np.random.default_rng(7)
    cases = [
        sphere,
        sphere[:-3],  # a hole
        np.vstack([sphere[:10, ::-1], sphere[10:]]),  # flipped faces
        np.vstack([sphere, sphere[:3], sphere[:3]]),  # edges used three times
        rng.integers(0, 40, (200, 3)),  # soup
    ]
    for faces in cases:
        assert closed_and_oriented(faces) == by_dictionary(faces)
