"""Talking to Mitsuba 3: variant choice, scenes from numpy meshes, renders.

printapp's BSDF plugins (the fitted model and the traced table) are in
:mod:`render.mitsuba_bsdfs`.

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

from render.mitsuba_bsdfs import CompactSurface, TableSurface, surface_bsdf
from render.translucency import MediumRGB

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
    """A soft box (large rectangular area light), a small spot light for crisp highlights, and a dim
    uniform environment.

    Directions in radians; both lights are aimed at the object's centre. The soft box shows
    a surface's overall gloss; the small light's reflection shows the highlight's shape
    (how sharp, which way it is stretched), which a large light blurs.
    """

    azimuth_rad: float = math.radians(60.0)
    elevation_rad: float = math.radians(35.0)
    radiance: float = 12.0
    size_factor: float = 1.5
    environment: float = 0.15
    highlight_azimuth_rad: float = math.radians(-150.0)
    highlight_elevation_rad: float = math.radians(55.0)
    highlight_radiance: float = 60.0
    highlight_size_factor: float = 0.12

    @property
    def brightest(self) -> float:
        """The largest radiance in the scene: no passive surface can look brighter."""
        return max(self.radiance, self.highlight_radiance, self.environment)


MEDIUM_MAX_DEPTH = 1024
"""Bounces for translucent renders: enough for light to cross a few transport mean free paths
of the media the chooser sends here (``render.translucency``); denser media get the body albedo."""


PREVIEW_FOV_DEG = 30.0
"""Field of view of printapp's preview camera (degrees, across the image's shorter side)."""


@dataclass(frozen=True)
class Framing:
    """Where the camera stands: it frames the bounding sphere, then backs off ``distance_scale`` times."""

    centre: np.ndarray
    radius_mm: float
    distance_mm: float
    half_fov_rad: float
    width_px: int
    height_px: int

    @classmethod
    def of(
        cls,
        vertices_mm: np.ndarray,
        width_px: int,
        height_px: int,
        fov_deg: float,
        distance_scale: float = 1.0,
    ) -> Framing:
        lo, hi = vertices_mm.min(axis=0), vertices_mm.max(axis=0)
        radius = float(np.linalg.norm(hi - lo)) / 2.0
        half_fov = math.radians(fov_deg) / 2.0
        aspect = width_px / height_px
        # Fit the bounding sphere inside the narrower of the two fields of view.
        narrow = half_fov if aspect >= 1.0 else math.atan(math.tan(half_fov) * aspect)
        distance = 1.1 * radius / math.sin(narrow) * distance_scale
        return cls((lo + hi) / 2.0, radius, distance, half_fov, width_px, height_px)

    @property
    def aspect(self) -> float:
        return self.width_px / self.height_px

    @property
    def pixel_footprint_mm(self) -> float:
        """Width of one pixel at the object's centre (mm); the fov spans the image's shorter side."""
        return 2.0 * self.distance_mm * math.tan(self.half_fov_rad) / min(self.width_px, self.height_px)


def medium_dict(medium: MediumRGB) -> dict[str, Any]:
    """Mitsuba's ``homogeneous`` medium (lengths in mm, the scene's unit) for an RGB medium."""
    sigma_t = [s + a for s, a in zip(medium.sigma_s_per_mm, medium.sigma_a_per_mm, strict=True)]
    albedo = [s / t if t > 0 else 0.0 for s, t in zip(medium.sigma_s_per_mm, sigma_t, strict=True)]
    # Mitsuba's RGB values must lie in [0, 1]: give sigma_t relative to its largest channel and
    # that channel as the medium's scale.
    scale = max(max(sigma_t), 1e-12)
    return {
        "type": "homogeneous",
        "sigma_t": {"type": "rgb", "value": [float(t / scale) for t in sigma_t]},
        "scale": float(scale),
        "albedo": {"type": "rgb", "value": [float(min(a, 1.0)) for a in albedo]},
        "phase": {"type": "hg", "g": float(medium.g)},
    }


def mesh_object(vertices: np.ndarray, faces: np.ndarray, bsdf: Any, interior: Any = None) -> Any:
    """A Mitsuba triangle mesh from arrays, without writing a file.

    Mitsuba must be imported with a variant set (:func:`choose_variant`).

    Parameters
    ----------
    vertices : ndarray, shape (n, 3)
        Vertex positions (mm: the scene's unit); stored as float32.
    faces : ndarray of int, shape (m, 3)
        Vertex indices of each triangle; stored as uint32.
    bsdf : mitsuba.BSDF
        The surface's BSDF (a loaded plugin object).
    interior : mitsuba.Medium, optional
        A participating medium inside the closed mesh.

    Returns
    -------
    mitsuba.Mesh
        The shape, named ``"relief"``, ready for a scene dictionary.
    """
    import mitsuba as mi

    props = mi.Properties()
    props["bsdf"] = bsdf
    if interior is not None:
        props["interior"] = interior
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
    medium: MediumRGB | None = None,
    surface: CompactSurface | TableSurface | dict | None = None,
    distance_scale: float = 1.0,
    frame_vertices: np.ndarray | None = None,
    coverage: bool = False,
) -> np.ndarray:
    """Path-trace a mesh made of smooth pigmented resin under studio light.

    The resin is Mitsuba's ``plastic`` BSDF: a smooth dielectric interface of index
    ``refractive_index`` (Fresnel reflection) over a diffuse body of ``body_albedo``,
    with the internal scattering accounted for (Weidlich & Wilkie 2007). The camera
    looks at the centre of the bounding box from the given elevation and azimuth and
    frames the bounding sphere (from ``distance_scale`` times as far, see :class:`Framing`)
    of ``frame_vertices`` (default: the mesh's own), so that a base shape and its relief
    are seen from the same place.

    With ``surface``, the mesh (then usually the smooth base shape) wears that
    representation of the printed relief's appearance instead: the fitted compact model
    or the traced table (:func:`surface_bsdf`).

    With ``medium`` (a translucent resin, see :mod:`render.translucency`) the body is instead
    a homogeneous medium (``sigma_s``, ``sigma_a`` per mm, Henyey–Greenstein phase function)
    inside a smooth dielectric boundary of the same index, rendered with Mitsuba's volumetric
    path tracer (``volpath``, up to ``MEDIUM_MAX_DEPTH`` bounces); ``body_albedo`` is unused.

    Parameters
    ----------
    vertices_mm : (n, 3) float array
        Vertex positions (mm).
    faces : (m, 3) int array
        Triangles, counter-clockwise seen from outside.

    Returns
    -------
    (height_px, width_px, 3) float32 array of linear RGB radiance; with ``coverage``, a
    (height_px, width_px) boolean mask of the pixels that see the mesh instead.
    """
    import drjit as dr
    import mitsuba as mi

    light = light or StudioLight()
    framed = vertices_mm if frame_vertices is None else frame_vertices
    frame = Framing.of(framed, width_px, height_px, fov_deg, distance_scale)
    centre, radius, distance = frame.centre, frame.radius_mm, frame.distance_mm

    def on_sphere(az: float, el: float, r: float) -> list[float]:
        return [
            float(centre[0] + r * math.cos(el) * math.cos(az)),
            float(centre[1] + r * math.cos(el) * math.sin(az)),
            float(centre[2] + r * math.sin(el)),
        ]

    eye = on_sphere(azimuth_rad, elevation_rad, distance)
    # The lamp backs off with the camera and grows with its distance: it lights the object
    # from the same solid angle, and it stays out of the frame.
    lamp = on_sphere(
        light.azimuth_rad,
        light.elevation_rad,
        (2.0 * radius + distance / distance_scale / 2.0) * distance_scale,
    )
    T = mi.ScalarTransform4f
    box_size = light.size_factor * radius * distance_scale
    interior = None
    if surface is not None:
        bsdf = surface_bsdf(surface)
    elif medium is None:
        bsdf = mi.load_dict(
            {
                "type": "plastic",
                "int_ior": float(refractive_index),
                "ext_ior": 1.0,
                "diffuse_reflectance": {"type": "rgb", "value": [float(c) for c in body_albedo]},
                "nonlinear": True,
            }
        )
    else:
        bsdf = mi.load_dict({"type": "dielectric", "int_ior": float(refractive_index), "ext_ior": 1.0})
        interior = mi.load_dict(medium_dict(medium))
    scene_dict: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 8}
        if medium is None
        else {"type": "volpath", "max_depth": MEDIUM_MAX_DEPTH, "rr_depth": MEDIUM_MAX_DEPTH},
        "sensor": {
            "type": "perspective",
            "fov": float(fov_deg),
            "fov_axis": "x" if frame.aspect <= 1.0 else "y",
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
        "relief": mesh_object(np.asarray(vertices_mm), np.asarray(faces), bsdf, interior),
    }
    if light.radiance > 0.0:
        # (Without light, no box either: a dark box would shade the environment.)
        scene_dict["softbox"] = {
            "type": "rectangle",
            "to_world": T().look_at(origin=lamp, target=[float(c) for c in centre], up=[0.0, 0.0, 1.0])
            @ T().scale([box_size, box_size, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [light.radiance] * 3}},
        }
    if light.highlight_radiance > 0.0:
        spot = on_sphere(
            light.highlight_azimuth_rad,
            light.highlight_elevation_rad,
            (2.0 * radius + distance / distance_scale / 2.0) * distance_scale,
        )
        spot_size = light.highlight_size_factor * radius * distance_scale
        scene_dict["spot"] = {
            "type": "rectangle",
            "to_world": T().look_at(origin=spot, target=[float(c) for c in centre], up=[0.0, 0.0, 1.0])
            @ T().scale([spot_size, spot_size, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [light.highlight_radiance] * 3}},
        }
    if coverage:
        # Which pixels see the mesh: the distance to the first hit through each pixel's centre.
        scene_dict["integrator"] = {"type": "aov", "aovs": "depth:depth"}
        scene_dict["sensor"]["film"]["pixel_format"] = "luminance"
        depth = np.array(mi.render(mi.load_dict(scene_dict), spp=1), dtype=np.float64)
        dr.sync_thread()
        return depth.reshape(int(height_px), int(width_px), -1)[..., -1] > 0.0
    # One sample per film pixel per pass: a multi-sample pass adds into pixels with atomics,
    # whose order, and so whose rounding, changes from run to run. To keep that and still
    # take many samples per pass, the film is k times finer each way (same field of view)
    # and each k x k block is averaged in numpy: k^2 stratified samples per pixel, in a
    # fixed order, byte-identical for the same design whatever the thread count.
    k = _supersampling(int(spp), int(width_px) * int(height_px))
    scene_dict["sensor"]["film"]["width"] = int(width_px) * k
    scene_dict["sensor"]["film"]["height"] = int(height_px) * k
    scene = mi.load_dict(scene_dict)
    total = np.zeros((int(height_px), int(width_px), 3), dtype=np.float64)
    passes = int(spp) // (k * k)
    for p in range(passes):
        image = mi.render(scene, spp=1, seed=(int(seed) * 0x9E3779B1 + p) & 0xFFFFFFFF)
        dr.sync_thread()
        fine = np.array(image, dtype=np.float64).reshape(int(height_px), k, int(width_px), k, -1)[..., :3]
        total += fine.mean(axis=(1, 3))
    return (total / passes).astype(np.float32)


_SAMPLES_PER_PASS = 8_000_000  # film pixels in one pass (about 100 MB of float32 RGB)


def _supersampling(spp: int, pixels: int) -> int:
    """The largest k with k^2 dividing ``spp`` and k^2 * pixels within one pass's budget."""
    best = 1
    k = 1
    while k * k <= spp and k * k * pixels <= max(_SAMPLES_PER_PASS, pixels):
        if spp % (k * k) == 0:
            best = k
        k += 1
    return best


def to_srgb8(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear RGB to 8-bit sRGB (IEC 61966-2-1 transfer curve), clipped to [0, 1]."""
    x = np.clip(np.nan_to_num(image * exposure, nan=0.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)
