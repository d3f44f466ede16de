"""Printable meshes: invariants (closed, oriented, manifold, genus, volume), not bytes."""

import numpy as np
import pytest
import trimesh

from noise.frames import angle_weighted_normals
from noise.heightfield import HeightField
from printapp.errors import DesignError
from printapp.mesh import (
    bisect_long_edges,
    crease_weights,
    displace_along_normals,
    folded_triangles,
    load_closed_mesh,
    refine_to_edge_length,
    slab_from_heightfield,
)
from printapp.solid import check_solid

DATA = __import__("pathlib").Path(__file__).parent.parent / "printapp" / "samples" / "meshes"


def triangulated_volume(h: np.ndarray, dx: float, dy: float, base: float) -> float:
    """Closed form for the slab: base prism plus, per cell, the two prisms under its triangles."""
    cells = 2 * h[:-1, :-1] + h[:-1, 1:] + h[1:, :-1] + 2 * h[1:, 1:]
    w, d = (h.shape[1] - 1) * dx, (h.shape[0] - 1) * dy
    return w * d * base + dx * dy * float(cells.sum()) / 6.0


@pytest.mark.parametrize(
    ("ny", "nx", "dx", "dy"), [(2, 2, 1.0, 1.0), (7, 13, 0.1, 0.25), (50, 40, 0.05, 0.05)]
)
def test_slab_is_a_closed_oriented_genus_zero_solid(ny, nx, dx, dy):
    rng = np.random.default_rng(ny * nx)
    h = rng.uniform(0, 0.3, size=(ny, nx))
    mesh = slab_from_heightfield(HeightField(h, dx, dy), 1.5)
    check = check_solid(mesh)
    assert check.watertight and check.winding_consistent and check.manifold
    assert check.genus == 0
    assert check.volume_mm3 == pytest.approx(triangulated_volume(h, dx, dy, 1.5), rel=1e-12)
    assert check.triangles == 2 * (nx - 1) * (ny - 1) + 3 * (2 * (nx - 1) + 2 * (ny - 1))
    np.testing.assert_allclose(check.bbox_min_mm, [0, 0, 0], atol=1e-12)
    # every face normal of the floor points down, every wall normal outward
    normals = mesh.face_normals
    floor = np.all(mesh.vertices[mesh.faces][:, :, 2] == 0, axis=1)
    assert np.allclose(normals[floor], [0, 0, -1])


def test_flat_slab_volume_is_the_box():
    mesh = slab_from_heightfield(HeightField(np.zeros((5, 9)), 0.5, 0.25), 2.0)
    assert mesh.volume == pytest.approx(4.0 * 1.0 * 2.0, rel=1e-12)


def test_slab_rejects_a_top_below_the_floor():
    with pytest.raises(ValueError, match="base_thickness_mm"):
        slab_from_heightfield(HeightField(np.full((3, 3), -3.0), 1.0, 1.0), 2.0)


def test_angle_weighted_normals_of_a_cube_point_along_the_diagonals():
    cube = trimesh.creation.box()
    normals = angle_weighted_normals(cube.vertices, cube.faces)
    expected = cube.vertices / np.linalg.norm(cube.vertices, axis=1, keepdims=True)
    np.testing.assert_allclose(normals, expected, atol=1e-12)


def test_angle_weighted_normals_are_the_plain_numpy_ones_on_a_cad_part_with_slivers():
    from printapp.bench.reference.vertex_normals import angle_weighted_normals_plain

    mesh = load_closed_mesh(DATA / "featuretype.STL", scale=5.0)
    refined = refine_to_edge_length(mesh, 2.0)
    for v, f in ((mesh.vertices, mesh.faces), (refined.vertices, refined.faces)):
        edges = np.linalg.norm(np.roll(v[f], -1, axis=1) - v[f], axis=2)
        # (the part's fillets carry triangles a hundred times longer than they are wide)
        assert np.max(edges.max(axis=1) / edges.min(axis=1)) > 100
        np.testing.assert_allclose(
            angle_weighted_normals(v, f), angle_weighted_normals_plain(v, f), atol=1e-10
        )
    lonely = np.vstack([mesh.vertices, [[1e3, 0.0, 0.0]]])  # a vertex of no face
    assert np.all(angle_weighted_normals(lonely, mesh.faces)[-1] == 0.0)


@pytest.mark.parametrize("edge_mm", [4.0, 1.0, 0.37])
def test_bisection_makes_trimeshs_triangles_in_trimeshs_order(edge_mm):
    mesh = load_closed_mesh(DATA / "featuretype.STL", scale=5.0)
    theirs = trimesh.remesh.subdivide_to_size(
        mesh.vertices, mesh.faces, max_edge=edge_mm, max_iter=40, return_index=True
    )
    ours = bisect_long_edges(mesh.vertices, mesh.faces, edge_mm)
    # The same corners, bit for bit, face by face (the midpoints are numbered differently).
    np.testing.assert_array_equal(ours[0][ours[1]], theirs[0][theirs[1]])
    np.testing.assert_array_equal(ours[2], theirs[2])
    assert len(ours[0]) == len(theirs[0])
    refined = trimesh.Trimesh(ours[0], ours[1], process=False)
    assert refined.is_watertight and refined.is_winding_consistent
    assert refined.edges_unique_length.max() <= edge_mm
    with pytest.raises(ValueError, match="after 1 rounds"):
        bisect_long_edges(mesh.vertices, mesh.faces, edge_mm / 8, max_rounds=1)


def test_crease_weights_and_folds_are_the_numpy_formulas():
    mesh = load_closed_mesh(DATA / "featuretype.STL", scale=5.0)
    refined = refine_to_edge_length(mesh, 2.0)
    v, f = np.asarray(refined.vertices), np.asarray(refined.faces)
    normals = angle_weighted_normals(v, f)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    unit = face_n / np.linalg.norm(face_n, axis=1, keepdims=True)
    worst = np.ones(len(v))
    for k in range(3):
        np.minimum.at(worst, f[:, k], np.einsum("ij,ij->i", normals[f[:, k]], unit))
    t = np.clip(
        (worst - np.cos(np.radians(30.0))) / (np.cos(np.radians(10.0)) - np.cos(np.radians(30.0))), 0, 1
    )
    np.testing.assert_allclose(crease_weights(v, f, normals), t * t * (3 - 2 * t), atol=1e-12)
    assert 0.0 < np.mean(t == 1.0) < 1.0  # both smooth and creased vertices
    moved = v.copy()
    moved[f[:5, 0]] = 2 * moved[f[:5, 1]] - moved[f[:5, 0]]  # mirror a corner through the next: folds
    after = trimesh.Trimesh(moved, f, process=False)
    turned = np.einsum(
        "ij,ij->i", face_n, np.cross(moved[f[:, 1]] - moved[f[:, 0]], moved[f[:, 2]] - moved[f[:, 0]])
    )
    assert folded_triangles(refined, after) == int(np.sum(turned <= 0)) > 0


def test_displacing_a_closed_mesh_keeps_it_closed():
    mesh = load_closed_mesh(DATA / "featuretype.STL", scale=5.0)
    refined = refine_to_edge_length(mesh, 1.0)
    assert np.max(refined.edges_unique_length) <= 1.0 + 1e-9
    assert refined.volume == pytest.approx(mesh.volume, rel=1e-9)
    offsets = np.full(len(refined.vertices), 0.1)
    moved, _ = displace_along_normals(refined, offsets)
    check = check_solid(moved)
    assert check.watertight and check.winding_consistent and check.manifold
    assert check.genus == check_solid(mesh).genus
    assert moved.volume > mesh.volume  # outward


def test_open_meshes_are_refused_with_a_count_of_open_edges():
    with pytest.raises(
        DesignError, match=r"teapot.stl: expected a closed \(watertight\) mesh, found \d+ open edges"
    ):
        load_closed_mesh(DATA / "teapot.stl")
    with pytest.raises(DesignError, match="no such mesh file"):
        load_closed_mesh(DATA / "missing.stl")


def test_unreadable_mesh_file(tmp_path):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"solid nonsense\nfacet normal 1 2\n")
    with pytest.raises(DesignError, match="bad.stl"):
        load_closed_mesh(bad)


def test_relief_fades_at_creases_and_never_folds():
    from printapp.mesh import folded_triangles

    cube = trimesh.creation.box(extents=(4.0, 4.0, 4.0)).subdivide().subdivide()
    moved, _ = displace_along_normals(cube, np.full(len(cube.vertices), 0.3))
    on_edge = np.sum(np.isclose(np.abs(cube.vertices), 2.0), axis=1) >= 2
    face_interior = np.sum(np.isclose(np.abs(cube.vertices), 2.0), axis=1) == 1
    shift = np.linalg.norm(moved.vertices - cube.vertices, axis=1)
    assert np.allclose(shift[on_edge], 0.0)  # edges and corners stay put
    assert np.allclose(shift[face_interior], 0.3)  # flat faces get the whole relief
    # A CAD mesh with sliver triangles: large random offsets would fold many of them.
    part = refine_to_edge_length(load_closed_mesh(DATA / "featuretype.STL", scale=5.0), 0.5)
    offsets = np.random.default_rng(0).uniform(0.0, 0.3, len(part.vertices))
    moved, softened = displace_along_normals(part, offsets)
    assert folded_triangles(part, moved) == 0
    assert 0 < softened < 0.2 * len(part.vertices)
    assert check_solid(moved).watertight


def test_combine_solids_with_boxes_and_meshes():
    from printapp.design import Combine
    from printapp.mesh import combine_solids

    slab = slab_from_heightfield(HeightField(np.zeros((11, 21)), 1.0, 1.0), 2.0)  # 20 x 10 x 2 mm
    slot = Combine(op="difference", shape="box", size_mm=(4.0, 2.0, 10.0), translate_mm=(10.0, 5.0, 0.0))
    cut = check_solid(combine_solids(slab, [slot]))
    assert cut.watertight and cut.manifold and cut.genus == 1
    assert cut.volume_mm3 == pytest.approx(20 * 10 * 2 - 4 * 2 * 2, rel=1e-6)
    post = Combine(
        op="union", shape="mesh", path=str(DATA / "featuretype.STL"), scale=1.0, translate_mm=(3, 3, 1.5)
    )
    joined = check_solid(combine_solids(slab, [post]))
    assert joined.watertight and joined.volume_mm3 > 400
    away = Combine(op="intersection", shape="box", size_mm=(1.0, 1.0, 1.0), translate_mm=(100.0, 0.0, 0.0))
    with pytest.raises(DesignError, match=r"combine\[0\]: the intersection leaves nothing"):
        combine_solids(slab, [away])


@pytest.mark.skipif(__import__("shutil").which("admesh") is None, reason="ADMesh is not installed")
def test_admesh_finds_nothing_to_fix(tmp_path):
    import re
    import subprocess

    from printapp.exporters import stl_bytes

    rng = np.random.default_rng(4)
    mesh = slab_from_heightfield(HeightField(rng.uniform(0, 0.3, (40, 50)), 0.1, 0.1), 1.0)
    path = tmp_path / "slab.stl"
    path.write_bytes(stl_bytes(mesh.vertices, mesh.faces))
    # (ADMesh prints the 80-byte header as a C string, running on into the facet data's bytes.)
    report = subprocess.run(["admesh", "--exact", str(path)], capture_output=True, check=True).stdout
    report = report.decode("utf-8", errors="replace")
    assert re.search(r"Total disconnected facets\s*:\s*0\s", report)
    assert re.search(r"Facets reversed\s*:\s*0\s", report)
    assert re.search(r"Backwards edges\s*:\s*0\s", report)
    volume = float(re.search(r"Volume\s*:\s*([\d.]+)", report).group(1))
    assert volume == pytest.approx(mesh.volume, rel=1e-5)


@pytest.mark.parametrize("bound_mm", [0.0, 0.0005, 0.003, 0.02])
def test_adaptive_top_is_closed_and_within_its_bound(bound_mm):
    import noise
    from printapp.adaptive_slab import adaptive_slab_arrays

    axis = np.linspace(0.0, 3.0, 129)
    h = noise.fbm_grid(axis, axis, octaves=4, seed=5)
    h = (h - h.min()) / (h.max() - h.min()) * 0.3
    vertices, faces, worst = adaptive_slab_arrays(h, 8.0, 6.0, 1.5, bound_mm)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    check = check_solid(mesh)
    assert check.watertight and check.winding_consistent and check.manifold and check.genus == 0
    assert worst <= bound_mm + 1e-12
    # An independent check of the bound: matplotlib's linear interpolation on the top's own
    # triangles, at every sample.
    import matplotlib.tri as mtri

    is_top = vertices[:, 2] > 1.0
    top_index = np.cumsum(is_top) - 1
    top_faces = faces[np.all(is_top[faces], axis=1)]
    top = vertices[is_top]
    interpolate = mtri.LinearTriInterpolator(
        mtri.Triangulation(top[:, 0], top[:, 1], top_index[top_faces]), top[:, 2]
    )
    xs, ys = np.meshgrid(np.linspace(0, 8.0, 129), np.linspace(0, 6.0, 129))
    z = np.asarray(interpolate(xs.ravel(), ys.ravel())) - 1.5
    assert np.nanmax(np.abs(z - h.ravel())) <= bound_mm + 1e-9
    full_triangles = 2 * 128 * 128
    top_triangles = len(top_faces)
    assert top_triangles <= full_triangles
    if bound_mm >= 0.003:  # tighter bounds may need the full grid, which is then what comes back
        assert top_triangles < full_triangles
    if bound_mm >= 0.02:
        assert top_triangles < full_triangles / 3


def test_adaptive_top_of_a_plane_is_two_triangles():
    from printapp.adaptive_slab import adaptive_slab_arrays

    x = np.linspace(0, 1, 33)
    vertices, faces, worst = adaptive_slab_arrays(0.1 * x[None, :] + 0.05 * x[:, None], 4.0, 4.0, 1.0, 1e-9)
    assert worst < 1e-12
    assert check_solid(trimesh.Trimesh(vertices, faces, process=False)).ok
    assert len(faces) == 2 + 3 * 4  # two triangles on top, four corner walls and floor fans
    with pytest.raises(ValueError, match="max_error_mm"):
        adaptive_slab_arrays(np.zeros((30, 30)), 1.0, 1.0, 1.0, -1.0)


def test_repair_closes_every_part_and_drops_none():
    """The teapot is four open parts (body, spout, handle, lid); MeshFix alone keeps only the body."""
    from printapp.mesh import repair_mesh

    teapot = trimesh.load(DATA / "teapot.stl", process=True)
    parts = teapot.split(only_watertight=False)
    assert len(parts) == 4 and not any(p.is_watertight for p in parts)
    solid, report = repair_mesh(teapot, "teapot")
    assert (report.parts_in, report.closed, report.solids_out) == (4, 4, 1)
    assert solid.is_watertight and solid.is_winding_consistent
    # Every part's volume is there: more than the body alone, less than the sum (they overlap).
    closed = [repair_mesh(p, "part")[0] for p in parts]
    volumes = sorted(c.volume for c in closed)
    assert volumes[-1] < solid.volume < sum(volumes)
    assert solid.volume > volumes[-1] + 0.5 * sum(volumes[:-1])


def test_enclosed_volume_is_the_closed_forms_and_trimesh_s():
    from printapp.solid import enclosed_volume_mm3

    box = trimesh.creation.box(extents=[2.0, 3.0, 5.0])
    assert enclosed_volume_mm3(box.vertices, box.faces) == pytest.approx(30.0, rel=1e-12)
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=4.0)
    volume = enclosed_volume_mm3(sphere.vertices + [10.0, -3.0, 7.0], sphere.faces)  # any origin
    assert volume == pytest.approx(sphere.volume, rel=1e-9)
    assert volume == pytest.approx(4.0 / 3.0 * np.pi * 4.0**3, rel=2e-3)  # the inscribed polyhedron
    assert enclosed_volume_mm3(sphere.vertices, sphere.faces[:, ::-1]) == pytest.approx(-volume)


def _meshes_to_count():
    box = trimesh.creation.box(extents=[2.0, 3.0, 5.0])
    sphere = trimesh.creation.icosphere(subdivisions=3)
    torus = trimesh.creation.torus(major_radius=3.0, minor_radius=1.0, major_sections=24, minor_sections=12)
    flipped = sphere.faces.copy()
    flipped[7] = flipped[7, ::-1]
    second = box.copy()
    second.apply_translation([2.0, 3.0, 0.0])  # shares one edge with the first box: four faces on it
    touching = trimesh.util.concatenate([box, second])
    touching.merge_vertices()
    spare = np.vstack([box.vertices, [[9.0, 9.0, 9.0]]])  # a vertex no face uses
    degenerate = np.vstack([box.faces, [[0, 0, 1], [1, 0, 0]]])
    both = trimesh.util.concatenate([box, sphere])
    return {
        "box": (box.vertices, box.faces),
        "sphere": (sphere.vertices, sphere.faces),
        "torus": (torus.vertices, torus.faces),
        "open": (sphere.vertices, sphere.faces[1:]),
        "one face flipped": (sphere.vertices, flipped),
        "every face flipped": (sphere.vertices, sphere.faces[:, ::-1]),
        "two parts": (both.vertices, both.faces),
        "edge on four faces": (touching.vertices, touching.faces),
        "unused vertex": (spare, box.faces),
        "degenerate faces": (box.vertices, degenerate),
        "one triangle": (box.vertices[:3], np.array([[0, 1, 2]])),
    }


@pytest.mark.parametrize("name", list(_meshes_to_count()))
def test_edge_topology_counts_as_trimesh_does(name):
    from printapp.solid import edge_topology

    vertices, faces = _meshes_to_count()[name]
    ours = edge_topology(faces, len(vertices))
    theirs = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    assert ours.watertight == theirs.is_watertight
    assert ours.winding_consistent == theirs.is_winding_consistent
    assert ours.euler_number == theirs.euler_number
    np.testing.assert_array_equal(ours.referenced, theirs.referenced_vertices)


def test_edge_topology_of_the_usual_cases():
    from printapp.solid import edge_topology

    meshes = _meshes_to_count()
    torus = edge_topology(meshes["torus"][1], len(meshes["torus"][0]))
    assert torus.watertight and torus.winding_consistent and torus.euler_number == 0  # genus 1
    sphere = edge_topology(meshes["sphere"][1], len(meshes["sphere"][0]))
    assert sphere.watertight and sphere.winding_consistent and sphere.euler_number == 2
    assert not edge_topology(meshes["open"][1], len(meshes["open"][0])).watertight
    flipped = edge_topology(meshes["one face flipped"][1], len(meshes["one face flipped"][0]))
    assert flipped.watertight and not flipped.winding_consistent
    with pytest.raises(ValueError, match="faces"):
        edge_topology(np.array([[0, 1, 5]]), 3)
