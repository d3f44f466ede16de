"""The Mitsuba adapter: variant choice (with the LLVM pitfall), renders, tone mapping."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from render.mitsuba_adapter import find_libllvm, to_srgb8


def test_find_libllvm_skips_versions_below_16(tmp_path, monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    (tmp_path / "libLLVM-15.so.1").write_bytes(b"")
    assert find_libllvm([str(tmp_path)]) is None
    (tmp_path / "libLLVM-17.so").write_bytes(b"")
    (tmp_path / "libLLVM.so.19.1").write_bytes(b"")
    assert find_libllvm([str(tmp_path)]) == str(tmp_path / "libLLVM.so.19.1")


def test_fallback_to_scalar_when_no_llvm_is_found(tmp_path):
    # In a fresh process, because a Mitsuba variant cannot be unset once chosen.
    code = (
        "import json, sys; from render.mitsuba_adapter import choose_variant;"
        f"c = choose_variant(search_dirs=[{str(tmp_path)!r}]);"
        "print(json.dumps([c.variant, c.warning]))"
    )
    env = {k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    variant, warning = json.loads(result.stdout.strip().splitlines()[-1])
    assert variant == "scalar_rgb"
    assert "libLLVM >= 16" in warning and "scalar_rgb" in warning


def test_srgb_transfer_curve():
    linear = np.array([[[0.0, 0.0031308, 0.5]], [[1.0, 2.0, np.nan]]])
    out = to_srgb8(linear)
    assert out.dtype == np.uint8
    assert out.tolist() == [[[0, 10, 188]], [[255, 255, 0]]]


def render_box(variant: str) -> float:
    code = (
        "import json, numpy as np, trimesh;"
        "from render.mitsuba_adapter import choose_variant, render_resin_mesh;"
        f"choose_variant({variant!r});"
        "m = trimesh.creation.box(extents=(10, 10, 2));"
        "img = render_resin_mesh(np.asarray(m.vertices), np.asarray(m.faces), body_albedo=(0.8, 0.8, 0.8),"
        " refractive_index=1.5, width_px=64, height_px=48, spp=64);"
        "print(json.dumps([float(img.mean()), float(img.min()), bool(np.isfinite(img).all())]))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_scalar_and_llvm_variants_agree_within_noise():
    from render.mitsuba_adapter import find_libllvm as finder

    scalar_mean, scalar_min, finite = render_box("scalar_rgb")
    assert finite and scalar_min >= 0 and scalar_mean > 0.05
    if finder() is None:
        pytest.skip("no libLLVM >= 16 here; only scalar_rgb can run")
    llvm_mean, _, _ = render_box("llvm_ad_rgb")
    assert llvm_mean == pytest.approx(scalar_mean, rel=0.03)


def test_render_sees_the_object():
    from render.mitsuba_adapter import choose_variant, render_resin_mesh

    choose_variant()
    m = trimesh.creation.box(extents=(10, 10, 2))
    img = render_resin_mesh(
        np.asarray(m.vertices),
        np.asarray(m.faces),
        body_albedo=(0.9, 0.1, 0.1),
        refractive_index=1.5,
        width_px=64,
        height_px=48,
        spp=16,
    )
    assert img.shape == (48, 64, 3)
    centre = img[18:30, 26:38].reshape(-1, 3).mean(axis=0)
    corner = img[:4, :4].reshape(-1, 3).mean(axis=0)
    assert centre[0] > 2 * centre[2]  # the red resin is in the middle of the frame
    assert corner[0] == pytest.approx(corner[2], rel=0.05)  # grey background in the corner


def _traced_kernels(renderer) -> set[str]:
    """The hashes of the kernels one small render launches."""
    import drjit as dr

    dr.kernel_history()  # (clears what came before)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        renderer.render(4, 0)
        dr.sync_thread()
        return {k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT}
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def test_one_traced_kernel_serves_every_lamp_position():
    # A lamp's transform baked into the kernel as literals made every frame of a light sweep
    # compile its own kernel (0.55 s each on 2 cores); held opaque, the frames share one.
    import math
    from dataclasses import replace

    from render.mitsuba_adapter import StudioLight, choose_variant, lamp_transforms, studio_places
    from render.progressive import SampleRenderer
    from tests.scenes import box_scene

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("the scalar variant traces no kernels")
    light = StudioLight()
    scene_dict, frame = box_scene(32, 24, light)
    renderer = SampleRenderer(scene_dict, 32, 24)
    seen = []
    for step in (1, 2, 3):
        moved = replace(
            light, azimuth_rad=light.azimuth_rad + step, elevation_rad=math.radians(30.0 + 10 * step)
        )
        places = studio_places(frame, math.radians(40.0), math.radians(-60.0), moved, 1.0)
        lamps = lamp_transforms(frame, places, moved, 1.0)
        renderer.move_shapes({name: lamps[name] for name in ("softbox", "spot") if renderer.has(name)})
        seen.append(_traced_kernels(renderer))
    assert seen[0], "the render launched no kernel"
    assert seen[1] == seen[0] and seen[2] == seen[0], seen


_PROGRAMS = """
import json, sys
import drjit as dr
from printapp.warmup import STEPS, preview_and_sweep
from render.mitsuba_adapter import choose_variant

choose_variant()
dr.set_flag(dr.JitFlag.KernelHistory, True)
if sys.argv[1] == "warm-up":
    next(step for name, _, step in STEPS if name == "render")()
else:
    preview_and_sweep(json.loads(sys.argv[1]))
dr.sync_thread()
jit = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT and k["operation_count"] > 20]
print(json.dumps(sorted({k["hash"] for k in jit})))
"""


@pytest.mark.slow
def test_the_warm_up_compiles_what_a_new_designs_preview_needs():
    """``printapp warmup`` renders a small tile's preview and light sweep at the default size; a
    design with another resin, size and relief then renders its preview and sweep with the same
    programs (a design's numbers are held in memory, not compiled in), all but reductions of a
    dozen operations. Before, each new design compiled five to seven programs (about 2 s here).
    Each side runs in a fresh process, as the two commands do: Mitsuba's own integrators call the
    BSDFs of every scene alive, so a process that rendered other scenes traces other programs."""
    from render.mitsuba_adapter import choose_variant

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("the scalar variant traces no kernels")
    design = {
        "base": {"width_mm": 5.0, "depth_mm": 4.0},
        "texture": {"kind": "fbm", "feature_size_mm": 1.5, "seed": 3},
        "relief": {"amplitude_um": 120},
        "material": {"body_albedo": [0.3, 0.6, 0.2], "refractive_index": 1.55},
        "brdf": {"rays": 2000},
        "render": {"spp": 8, "noise": 0.2},
    }

    def programs(which: str) -> set[str]:
        out = subprocess.run(
            [sys.executable, "-c", _PROGRAMS, which], capture_output=True, text=True, timeout=600, check=True
        )
        return set(json.loads(out.stdout.strip().splitlines()[-1]))

    warm, needed = programs("warm-up"), programs(json.dumps(design))
    assert len(needed) >= 4  # guides, the camera's paths, the light paths, the sweep's
    assert needed <= warm, f"{len(needed - warm)} of {len(needed)} programs not compiled by the warm-up"
