"""``printapp warmup``: compile every numba kernel and Dr.Jit program a run uses, once, ahead of time.

The kernels are cached (numba ``cache=True`` beside the package, or under
``NUMBA_CACHE_DIR``; Dr.Jit in ``~/.drjit``), so the first real run then costs what
every later one does. ``make`` runs this after installing. Each step calls the same
public functions a run calls, with the same array types, on inputs a few samples big.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from printapp.progress import StageTimer


def _noise() -> None:
    import noise

    pts = np.random.default_rng(0).uniform(0.0, 4.0, (64, 3))
    axis = np.linspace(0.0, 3.0, 8)
    for cell_seed in noise.CELL_SEED_MODES:
        noise.sparse_convolution(pts, cell_seed=cell_seed)
        noise.sparse_convolution_grid(axis, axis, cell_seed=cell_seed)
    noise.fbm(pts, octaves=3, min_pitch=0.1)
    noise.fbm_grid(axis, axis, octaves=3, min_pitch=0.1)
    noise.turbulence(pts, low=0, high=2, min_pitch=0.1)
    noise.turbulence_grid(axis, axis, low=0, high=2, min_pitch=0.1)
    noise.veins(pts, angle=0.3, period=2.0, strength=3.0, sharpness=2.0, low=0, high=2)
    noise.veins_grid(axis, axis, angle=0.3, period=2.0, strength=3.0, sharpness=2.0, low=0, high=2)
    # Points whose cells lie far apart are sorted by cell instead of counted into a grid.
    noise.sparse_convolution(pts * 1e5)
    from noise.cellular import cellular
    from noise.tables import NoiseTable

    cellular(pts[:, :2])
    table = NoiseTable(8.0, 0)  # the photo fits' stand-in noise
    table(pts[:, :2])
    table.octave_sum(pts[:, :2], 0, np.array([1.0, 2.0]), np.array([1.0, 0.5]), np.zeros((2, 2)))


def _lic() -> None:
    import trimesh

    from noise.lic import lic2d
    from noise.surface import field_rotation, lic_surface

    u = np.ones((16, 16))
    lic2d(u, np.zeros_like(u), np.random.default_rng(0).random((16, 16)), length=3.0)
    sphere = trimesh.creation.icosphere(1)
    vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    field = field_rotation(vertices, faces, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    lic_surface(vertices, faces, field, length=0.3, step=0.1, noise_scale=0.2)


def _design(design_dict: dict, brdf: bool) -> None:
    from printapp.design import design_from_dict
    from printapp.relief import appearance_field, build_relief
    from printapp.rendering import predict_for_design
    from printapp.solid import check_solid

    design = design_from_dict(design_dict, "warm-up")
    relief = build_relief(design)
    check_solid(relief.mesh)
    field, _ = appearance_field(design, relief)
    if brdf:  # the compact model's fit is SciPy, seconds that a warm-up need not pay twice
        predict_for_design(design, field)


def _tile() -> None:
    small = {"base": {"width_mm": 3.0, "depth_mm": 3.0}, "brdf": {"rays": 2000}}
    _design(small, brdf=True)
    _design({**small, "texture": {"kind": "lic", "field": "swirl", "feature_size_mm": 0.5}}, brdf=False)
    _design({**small, "texture": {"kind": "marble", "feature_size_mm": 1.0}}, brdf=False)
    for network in ("cellular", "ridged"):  # the photo fits' marble
        veined = {"kind": "veined", "feature_size_mm": 1.0, "vein_network": network, "vein_scale_mm": 2.0}
        _design({**small, "texture": veined}, brdf=False)
    from render.brdf_model import lobe_row_means

    # The analytic fit's lobe (whether the small tile's fit reached it or not).
    up = np.array([[0.0, 0.0, 1.0]])
    lobe_row_means("ggx", 0.3, 0.2, 0.0, 1.5, up, np.zeros(1, dtype=np.int64), up[None])


def _mesh() -> None:
    import trimesh

    from printapp.design import design_from_dict
    from printapp.exporters import stl_bytes, threemf_bytes
    from printapp.relief import build_relief
    from printapp.stl import load_closed_stl
    from slicing import find_printer, slice_mesh, write_sl1

    box = trimesh.creation.box((4.0, 4.0, 4.0))
    threemf_bytes(box.vertices, box.faces)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "box.stl"
        path.write_bytes(stl_bytes(box.vertices, box.faces))
        load_closed_stl(path)
        # Noise in tangent frames (stretched along a field) as well as isotropic and LIC.
        for kind, stretch in (("fbm", 1.0), ("fbm", 3.0), ("lic", 1.0)):
            texture = {"kind": kind, "feature_size_mm": 1.0, "field": "axis:0,0,1", "stretch": stretch}
            design = design_from_dict(
                {"base": {"path": str(path)}, "texture": texture, "relief": {"amplitude_mm": 0.1}}
            )
            relief = build_relief(design)
        # The design's other frame and field choices: `onb = "frisvad"`, `field = "curvature:max"`.
        from noise.frames import onb
        from noise.surface import field_principal_curvature

        onb(np.asarray(box.vertex_normals, dtype=np.float64), "frisvad")
        field_principal_curvature(np.asarray(box.vertices), np.asarray(box.faces), "max")
        import io

        slices = slice_mesh(relief.mesh.vertices, relief.mesh.faces, find_printer("prusa-sl1"))
        write_sl1(io.BytesIO(), slices, "warm")
        slices.max_winding()


def _emboss_and_brdf() -> None:
    from noise.heightfield import HeightField
    from printapp.adaptive_slab import adaptive_slab_arrays
    from printapp.brdf import heightfield_from_mesh
    from printapp.exporters import stl_bytes
    from printapp.slab import slab_arrays

    heights = np.random.default_rng(1).random((17, 17)) * 0.1
    vertices, faces = slab_arrays(HeightField(heights, 0.1, 0.1), 1.0)
    adaptive_slab_arrays(heights, 1.6, 1.6, 1.0, 0.01)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "slab.stl"
        path.write_bytes(stl_bytes(vertices, faces))
        heightfield_from_mesh(path)


def _materials() -> None:
    from printapp.material_report import material_report
    from printapp.materials import appearance
    from render.diffusion import diffuse_box
    from render.fresnel import fresnel_dielectric

    appearance("white-resin")
    _, optics = material_report("white-resin", {}, [450.0, 550.0])
    optics.phase_function(np.linspace(-1.0, 1.0, 5), 0)  # `printapp material --plot`
    fresnel_dielectric(np.linspace(0.0, 1.0, 5), 1.5)
    # The light diffused through a translucent tile (the BSSRDF preview).
    diffuse_box((3, 3, 3), 0.1, 1.0, 0.01, 0.0, 1.5, {"top": np.ones((3, 3))})


_BOX = {"body_albedo": (0.8, 0.5, 0.2), "refractive_index": 1.5, "width_px": 16, "height_px": 12}
"""The warm-up's scene: a small resin box under the studio light."""


def _render() -> None:
    import trimesh

    from render.convergence import allocate_samples
    from render.mitsuba_adapter import choose_variant, render_resin_mesh

    choose_variant()
    # Progressive rendering's allocation (a preview's later rounds).
    allocate_samples(np.ones(4), np.full(4, 2), np.ones(4, dtype=bool), 0.1, 0.5, step=2, cap=8, lanes=9)
    box = trimesh.creation.box((2.0, 2.0, 1.0))
    render_resin_mesh(np.asarray(box.vertices), np.asarray(box.faces), spp=1, **_BOX)
    _caustic_split(np.asarray(box.vertices), np.asarray(box.faces))
    _preview()


def _preview() -> None:
    """Mitsuba's programs for a design's preview and light sweep, as ``printapp design`` runs them.

    A design's numbers (its resin, its size, the lamps' places) are held in memory, not compiled
    into the programs (render.mitsuba_bsdfs, render.progressive), so what a small tile compiles
    here at the default preview size serves every coated design of that size. Its goal is out of
    reach and its time cap short, so the rounds over listed pixels run and then it stops.
    """
    render = {"spp": 8, "noise": 0.001, "max_spp": 32, "time_cap_s": 1.0}
    # A relief whose lamp caustics are light-traced apart, and a nearly flat one whose are not.
    for amplitude_um in (300.0, 5.0):
        preview_and_sweep(
            {
                "base": {"width_mm": 3.0, "depth_mm": 3.0},
                "relief": {"amplitude_um": amplitude_um},
                "brdf": {"rays": 2000},
                "render": render,
            }
        )


def preview_and_sweep(design_dict: dict) -> None:
    """Render a design's preview and light sweep as ``printapp design`` does (its relief and BRDF
    first; nothing is written)."""
    import gc

    from printapp.design import design_from_dict
    from printapp.relief import appearance_field, build_relief
    from printapp.rendering import light_sweep, predict_for_design, render_preview
    from printapp.report import sweep_settings

    # Scenes that earlier renders left behind freed first: Mitsuba's own integrators call the
    # BSDFs and emitters of every scene alive, and their programs differ with how many there are.
    gc.collect()
    design = design_from_dict(design_dict, "warm-up")
    relief = build_relief(design)
    field, _ = appearance_field(design, relief)
    predicted = predict_for_design(design, field, analytic=False)
    render_preview(design, relief, relief.mesh, predicted, field)
    light_sweep(design, relief, relief.mesh, predicted, field, **sweep_settings(design))


def _caustic_split(vertices: np.ndarray, faces: np.ndarray) -> None:
    """The kernels of a coated relief's preview split into camera and light paths (render.caustics)."""
    from render.caustics import caustic_image, coat_of, lamps_of
    from render.coated_path import CoatedPath
    from render.mitsuba_adapter import resin_scene_dict
    from render.progressive import SampleRenderer

    scene_dict, frame = resin_scene_dict(vertices, faces, **_BOX)
    renderer = SampleRenderer(scene_dict, 16, 12)
    if renderer.scalar:
        return
    coat = coat_of(scene_dict)
    integrator = CoatedPath(coat)
    renderer.render(1, 0, integrator=integrator)  # the first round: every pixel
    renderer.render(1, 0, np.arange(8), integrator=integrator)  # later rounds: listed pixels
    renderer.render(1, 0, integrator=CoatedPath(coat, caustics="camera"))  # where the split is declined
    lamps = lamps_of(renderer.scene, scene_dict)
    frame_args = {"centre_mm": frame.centre, "radius_mm": frame.radius_mm, "width_px": 16, "height_px": 12}
    _, guide = caustic_image(renderer.scene, coat, lamps, 1000, 0, learn=True, **frame_args)
    caustic_image(renderer.scene, coat, lamps, 1000, 1, guide=guide, **frame_args)


STEPS: tuple[tuple[str, str, Callable[[], None]], ...] = (
    ("noise", "noise kernels", _noise),
    ("lic", "line integral convolution", _lic),
    ("tile", "tile relief, slicing, BRDF", _tile),
    ("mesh", "mesh relief and slicing", _mesh),
    ("emboss", "slabs and mesh tops", _emboss_and_brdf),
    ("materials", "Lorenz-Mie", _materials),
    ("render", "Mitsuba programs", _render),
)


def warm_up(quiet: bool = False) -> dict[str, float]:
    """Run every step once; return the seconds each took (large the first time, small after)."""
    with StageTimer(quiet=quiet) as timer:
        for name, label, step in STEPS:
            with timer.stage(name, label):
                step()
    return dict(timer.seconds)
