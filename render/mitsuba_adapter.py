"""The one module that talks to Mitsuba 3: variant choice, scenes from numpy meshes, renders.

Variant choice (DESIGN.md, "Environment facts"): ``cuda_ad_rgb`` when a CUDA driver
works, else ``llvm_ad_rgb`` when a shared libLLVM >= 16 is found (Dr.Jit's code
generation aborts the process with libLLVM 15, so the version is checked *before*
the variant is touched), else ``scalar_rgb``, with a reason the caller can show.
Mitsuba is imported lazily so that ``import render`` stays cheap.
"""

from __future__ import annotations

import ctypes.util
import glob
import math
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

MIN_LLVM_MAJOR = 16
_LLVM_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
)
_chosen: VariantChoice | None = None


@dataclass(frozen=True)
class VariantChoice:
    """The Mitsuba variant in use and, when it is not the fastest, why."""

    variant: str
    libllvm: str | None
    warning: str | None


def _llvm_major(path: str) -> int | None:
    match = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
    if match is None:
        match = re.search(r"llvm-(\d+)", path)
    return int(match.group(1)) if match else None


def find_libllvm(
    search_dirs: tuple[str, ...] | list[str] = _LLVM_DIRS, min_major: int = MIN_LLVM_MAJOR
) -> str | None:
    """Newest shared libLLVM with major version >= ``min_major`` in ``search_dirs``, or None.

    ``DRJIT_LIBLLVM_PATH``, when set to an existing file, wins over the search.
    """
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env and os.path.isfile(env):
        major = _llvm_major(env)
        if major is None or major >= min_major:
            return env
    candidates: list[tuple[int, str]] = []
    for folder in search_dirs:
        patterns = [
            os.path.join(folder, "libLLVM*.so*"),
            os.path.join(folder, "llvm-*", "lib", "libLLVM*.so*"),
        ]
        for pattern in patterns:
            for path in glob.glob(pattern):
                major = _llvm_major(path)
                if major is not None and major >= min_major and os.path.isfile(path):
                    candidates.append((major, path))
    if not candidates:
        return None
    return sorted(candidates)[-1][1]


def choose_variant(
    prefer: str | None = None, search_dirs: tuple[str, ...] | list[str] = _LLVM_DIRS
) -> VariantChoice:
    """Pick and set the fastest Mitsuba variant that works here.

    Parameters
    ----------
    prefer : str, optional
        Force a variant (``"scalar_rgb"``, ``"llvm_ad_rgb"``, ``"cuda_ad_rgb"``).
        Also read from the ``PRINTAPP_MITSUBA_VARIANT`` environment variable.
    search_dirs : sequence of str
        Where to look for libLLVM.
    """
    global _chosen
    prefer = prefer or os.environ.get("PRINTAPP_MITSUBA_VARIANT") or None
    if _chosen is not None and prefer in (None, _chosen.variant) and tuple(search_dirs) == _LLVM_DIRS:
        return _chosen
    libllvm = find_libllvm(search_dirs)
    if libllvm is not None:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", libllvm)
    import mitsuba as mi

    choice: VariantChoice | None = None
    if prefer is not None:
        if prefer == "llvm_ad_rgb" and libllvm is None:
            raise RuntimeError(f"llvm_ad_rgb needs a shared libLLVM >= {MIN_LLVM_MAJOR}; none was found")
        mi.set_variant(prefer)
        choice = VariantChoice(prefer, libllvm, None)
    if choice is None and ctypes.util.find_library("cuda") is not None:
        try:
            mi.set_variant("cuda_ad_rgb")
            import drjit as dr

            dr.eval(mi.Float(1.0) + 1.0)
            choice = VariantChoice("cuda_ad_rgb", libllvm, None)
        except Exception:
            choice = None
    if choice is None and libllvm is not None:
        try:
            mi.set_variant("llvm_ad_rgb")
            choice = VariantChoice("llvm_ad_rgb", libllvm, None)
        except Exception as exc:
            choice = VariantChoice(
                "scalar_rgb",
                libllvm,
                f"Mitsuba's llvm_ad_rgb failed ({exc}); rendering on scalar_rgb (slower)",
            )
    if choice is None:
        choice = VariantChoice(
            "scalar_rgb",
            None,
            f"no shared libLLVM >= {MIN_LLVM_MAJOR} found; rendering on Mitsuba's scalar_rgb variant "
            "(several times slower). Install Debian's libllvm19 for llvm_ad_rgb.",
        )
    mi.set_variant(choice.variant)
    if tuple(search_dirs) == _LLVM_DIRS:
        _chosen = choice
    return choice


@dataclass(frozen=True)
class StudioLight:
    """A soft box (rectangular area light) over a dim uniform environment.

    Directions in radians; the soft box is aimed at the object's centre.
    """

    azimuth_rad: float = math.radians(60.0)
    elevation_rad: float = math.radians(35.0)
    radiance: float = 12.0
    size_factor: float = 1.5
    environment: float = 0.15


def _mesh_object(vertices: np.ndarray, faces: np.ndarray, bsdf: Any) -> Any:
    import mitsuba as mi

    props = mi.Properties()
    props["bsdf"] = bsdf
    mesh = mi.Mesh(
        "relief",
        vertex_count=int(vertices.shape[0]),
        face_count=int(faces.shape[0]),
        props=props,
        has_vertex_normals=False,
        has_vertex_texcoords=False,
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(vertices, dtype=np.float32).ravel()
    params["faces"] = np.ascontiguousarray(faces, dtype=np.uint32).ravel()
    params.update()
    return mesh


def render_resin_mesh(
    vertices_mm: np.ndarray,
    faces: np.ndarray,
    *,
    body_albedo: tuple[float, float, float],
    refractive_index: float,
    width_px: int,
    height_px: int,
    spp: int,
    seed: int = 0,
    elevation_rad: float = math.radians(40.0),
    azimuth_rad: float = math.radians(-60.0),
    fov_deg: float = 30.0,
    light: StudioLight | None = None,
) -> np.ndarray:
    """Path-trace a mesh made of smooth pigmented resin under studio light.

    The resin is Mitsuba's ``plastic`` BSDF: a smooth dielectric interface of index
    ``refractive_index`` (Fresnel reflection) over a diffuse body of ``body_albedo``,
    with the internal scattering accounted for (Weidlich & Wilkie 2007). The camera
    looks at the centre of the bounding box from the given elevation and azimuth and
    frames the bounding sphere.

    Parameters
    ----------
    vertices_mm : (n, 3) float array
        Vertex positions (mm).
    faces : (m, 3) int array
        Triangles, counter-clockwise seen from outside.

    Returns
    -------
    (height_px, width_px, 3) float32 array of linear RGB radiance.
    """
    import drjit as dr
    import mitsuba as mi

    light = light or StudioLight()
    lo, hi = vertices_mm.min(axis=0), vertices_mm.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = float(np.linalg.norm(hi - lo)) / 2.0
    half_fov = math.radians(fov_deg) / 2.0
    aspect = width_px / height_px
    # Fit the bounding sphere inside the narrower of the two fields of view.
    narrow = half_fov if aspect >= 1.0 else math.atan(math.tan(half_fov) * aspect)
    distance = 1.1 * radius / math.sin(narrow)

    def on_sphere(az: float, el: float, r: float) -> list[float]:
        return [
            float(centre[0] + r * math.cos(el) * math.cos(az)),
            float(centre[1] + r * math.cos(el) * math.sin(az)),
            float(centre[2] + r * math.sin(el)),
        ]

    eye = on_sphere(azimuth_rad, elevation_rad, distance)
    lamp = on_sphere(light.azimuth_rad, light.elevation_rad, 2.0 * radius + distance / 2.0)
    T = mi.ScalarTransform4f
    box_size = light.size_factor * radius
    bsdf = mi.load_dict(
        {
            "type": "plastic",
            "int_ior": float(refractive_index),
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": [float(c) for c in body_albedo]},
            "nonlinear": True,
        }
    )
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 8},
            "sensor": {
                "type": "perspective",
                "fov": float(fov_deg),
                "fov_axis": "x" if aspect <= 1.0 else "y",
                "to_world": T().look_at(origin=eye, target=[float(c) for c in centre], up=[0.0, 0.0, 1.0]),
                "film": {
                    "type": "hdrfilm",
                    "width": int(width_px),
                    "height": int(height_px),
                    # A box filter puts each sample in exactly one pixel; with one sample per
                    # pixel per pass no two threads ever add to the same pixel, so the
                    # image does not depend on thread timing (see the loop below).
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": 1, "seed": int(seed)},
            },
            "environment": {
                "type": "constant",
                "radiance": {"type": "rgb", "value": [light.environment] * 3},
            },
            "softbox": {
                "type": "rectangle",
                "to_world": T().look_at(origin=lamp, target=[float(c) for c in centre], up=[0.0, 0.0, 1.0])
                @ T().scale([box_size, box_size, 1.0]),
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [light.radiance] * 3}},
            },
            "relief": _mesh_object(np.asarray(vertices_mm), np.asarray(faces), bsdf),
        }
    )
    # Accumulate one-sample passes in a fixed order: byte-identical images for the same
    # design, whatever the thread count (a multi-sample pass adds into pixels with
    # atomics, whose order, and so whose rounding, changes from run to run).
    total = np.zeros((int(height_px), int(width_px), 3), dtype=np.float64)
    for k in range(int(spp)):
        image = mi.render(scene, spp=1, seed=(int(seed) * 0x9E3779B1 + k) & 0xFFFFFFFF)
        dr.sync_thread()
        total += np.array(image, dtype=np.float64)
    return (total / int(spp)).astype(np.float32)


def to_srgb8(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear RGB to 8-bit sRGB (IEC 61966-2-1 transfer curve), clipped to [0, 1]."""
    x = np.clip(np.nan_to_num(image * exposure, nan=0.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)
