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

from render.mitsuba_bsdfs import CompactSurface, TableSurface, coated_resin_bsdf, surface_bsdf
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
    # Mitsuba's C++ logger writes warnings straight to stdout, where they would mix with a
    # command's output (and with JSON); printapp reports what matters itself.
    mi.set_log_level(mi.LogLevel.Error)
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
        columns = np.ascontiguousarray(vertices_mm.T)  # rows reduce ten times faster than (n, 3) columns
        lo, hi = columns.min(axis=1), columns.max(axis=1)
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


def mesh_object(
    vertices: np.ndarray,
    faces: np.ndarray,
    bsdf: Any,
    interior: Any = None,
    *,
    emission: np.ndarray | None = None,
    emission_weight: float = 1.0,
    normals: np.ndarray | None = None,
    texcoords: np.ndarray | None = None,
) -> Any:
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
    emission : ndarray, shape (n, 3), optional
        Per-vertex linear-RGB radiance: the mesh is then also an area emitter (Lambertian,
        interpolated over each triangle), picked by next-event estimation with relative
        weight ``emission_weight``.
    texcoords : ndarray, shape (n, 2), optional
        Per-vertex UV coordinates. They set the shading frame's tangent (``dp/du``), the
        azimuth 0 of an anisotropic BSDF; without them Mitsuba takes each triangle's first
        edge, which differs from triangle to triangle.

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
    if emission is not None:
        props["emitter"] = mi.load_dict(
            {
                "type": "area",
                "radiance": {"type": "mesh_attribute", "name": "vertex_emission"},
                "sampling_weight": float(emission_weight),
            }
        )
    mesh = mi.Mesh(
        "relief",
        vertex_count=int(vertices.shape[0]),
        face_count=int(faces.shape[0]),
        props=props,
        has_vertex_normals=normals is not None,
        has_vertex_texcoords=texcoords is not None,
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(vertices, dtype=np.float32).ravel()
    if normals is not None:
        params["vertex_normals"] = np.ascontiguousarray(normals, dtype=np.float32).ravel()
    params["faces"] = np.ascontiguousarray(faces, dtype=np.uint32).ravel()
    if texcoords is not None:
        params["vertex_texcoords"] = np.ascontiguousarray(texcoords, dtype=np.float32).ravel()
    params.update()
    if emission is not None:
        values = np.ascontiguousarray(np.clip(emission, 0.0, None), dtype=np.float32)
        if values.shape != (int(vertices.shape[0]), 3):
            raise ValueError(f"emission: expected shape ({vertices.shape[0]}, 3), got {values.shape}")
        mesh.add_attribute("vertex_emission", 3, values.ravel())
    return mesh


@dataclass(frozen=True)
class StudioPlaces:
    """Where the camera, the soft box and the spot stand (mm), and the spot's half side."""

    eye: list[float]
    lamp: list[float]
    spot: list[float]
    lamp_distance_mm: float
    spot_half_size_mm: float


def studio_places(
    frame: Framing, elevation_rad: float, azimuth_rad: float, light: StudioLight, distance_scale: float
) -> StudioPlaces:
    """The camera at ``frame``'s distance and the lights of ``light`` round ``frame.centre``.

    The lamps back off with the camera and grow with its distance: they light the object
    from the same solid angle, and they stay out of the frame.
    """
    centre, radius, distance = frame.centre, frame.radius_mm, frame.distance_mm

    def on_sphere(az: float, el: float, r: float) -> list[float]:
        return [
            float(centre[0] + r * math.cos(el) * math.cos(az)),
            float(centre[1] + r * math.cos(el) * math.sin(az)),
            float(centre[2] + r * math.sin(el)),
        ]

    lamp_distance = (2.0 * radius + distance / distance_scale / 2.0) * distance_scale
    return StudioPlaces(
        eye=on_sphere(azimuth_rad, elevation_rad, distance),
        lamp=on_sphere(light.azimuth_rad, light.elevation_rad, lamp_distance),
        spot=on_sphere(light.highlight_azimuth_rad, light.highlight_elevation_rad, lamp_distance),
        lamp_distance_mm=lamp_distance,
        spot_half_size_mm=light.highlight_size_factor * radius * distance_scale,
    )


def lamp_transforms(frame: Framing, places: StudioPlaces, light: StudioLight, distance_scale: float) -> dict:
    """The lamps' ``to_world`` (unit rectangles aimed at the centre): to place them, or to move them."""
    import mitsuba as mi

    T, centre, up = mi.ScalarTransform4f, [float(c) for c in frame.centre], [0.0, 0.0, 1.0]
    box, spot = light.size_factor * frame.radius_mm * distance_scale, places.spot_half_size_mm
    return {
        "softbox": T().look_at(origin=places.lamp, target=centre, up=up) @ T().scale([box, box, 1.0]),
        "spot": T().look_at(origin=places.spot, target=centre, up=up) @ T().scale([spot, spot, 1.0]),
    }


def resin_scene_dict(
    vertices_mm: np.ndarray,
    faces: np.ndarray,
    *,
    body_albedo: tuple[float, float, float],
    refractive_index: float,
    width_px: int,
    height_px: int,
    elevation_rad: float = math.radians(40.0),
    azimuth_rad: float = math.radians(-60.0),
    fov_deg: float = 30.0,
    light: StudioLight | None = None,
    medium: MediumRGB | None = None,
    surface: CompactSurface | TableSurface | dict | None = None,
    distance_scale: float = 1.0,
    frame_vertices: np.ndarray | None = None,
    emission: np.ndarray | None = None,
) -> tuple[dict[str, Any], Framing]:
    """The Mitsuba scene of :func:`render_resin_mesh` (variant already chosen), and its framing.

    ``emission`` (per-vertex linear-RGB radiance, ``(n, 3)``) makes the resin's body an emitter
    of that radiance under a black-bodied smooth coating (Fresnel reflection only): the light
    that a subsurface-scattering model (:mod:`render.bssrdf`) says comes back out.
    """
    import mitsuba as mi

    light = light or StudioLight()
    framed = vertices_mm if frame_vertices is None else frame_vertices
    frame = Framing.of(framed, width_px, height_px, fov_deg, distance_scale)
    centre, radius = frame.centre, frame.radius_mm
    places = studio_places(frame, elevation_rad, azimuth_rad, light, distance_scale)
    eye, lamp_distance, T = places.eye, places.lamp_distance_mm, mi.ScalarTransform4f
    weights = _irradiance_weights(light, radius, distance_scale, lamp_distance)
    interior = None
    if surface is not None:
        bsdf = surface_bsdf(surface)
    elif medium is None:
        albedo = (0.0, 0.0, 0.0) if emission is not None else body_albedo
        if mi.variant().startswith("scalar"):
            # (printapp's Python plugins run too slowly on the scalar variant.)
            bsdf = mi.load_dict(
                {
                    "type": "plastic",
                    "int_ior": float(refractive_index),
                    "ext_ior": 1.0,
                    "diffuse_reflectance": {"type": "rgb", "value": [float(c) for c in albedo]},
                    "nonlinear": True,
                }
            )
        else:
            bsdf = coated_resin_bsdf(tuple(float(c) for c in albedo), float(refractive_index))
    else:
        bsdf = mi.load_dict({"type": "dielectric", "int_ior": float(refractive_index), "ext_ior": 1.0})
        interior = mi.load_dict(medium_dict(medium))
    relief = mesh_object(
        np.asarray(vertices_mm),
        np.asarray(faces),
        bsdf,
        interior,
        emission=emission,
        emission_weight=weights.get("relief", 0.0),
        # A BRDF representation's azimuths are the relief's x and y (the gonioreflectometer's):
        # UV = (x, y) makes every triangle's tangent the world's x where it faces up.
        texcoords=None if surface is None else np.asarray(vertices_mm)[:, :2],
    )
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
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
        },
        "environment": {
            "type": "constant",
            "radiance": {"type": "rgb", "value": [light.environment] * 3},
            "sampling_weight": weights["environment"],
        },
        "relief": relief,
    }
    placed = lamp_transforms(frame, places, light, distance_scale)  # (both lamps; unlit ones are left out)
    # An unlit lamp is left out (a dark box would shade the environment). A lamp's face reflects
    # nothing (Mitsuba's default is grey): render.caustics' split of the image is then exact.
    for name, radiance in (("softbox", light.radiance), ("spot", light.highlight_radiance)):
        if radiance > 0.0:
            scene_dict[name] = {
                "type": "rectangle",
                "to_world": placed[name],
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
                "emitter": {
                    "type": "area",
                    "radiance": {"type": "rgb", "value": [float(radiance)] * 3},
                    "sampling_weight": weights[name],
                },
            }
    return scene_dict, frame


def _irradiance_weights(
    light: StudioLight, radius_mm: float, distance_scale: float, lamp_distance_mm: float
) -> dict[str, float]:
    """How often next-event estimation picks each light: in proportion to the irradiance it gives the object.

    Mitsuba picks an emitter uniformly by default; with a dim environment, a large soft box and
    a small bright spot, two picks in three then go to lights that give little, and each
    sample's value jumps between zero and three times the soft box's share (a relative standard
    deviation of about 1.4 per sample on the demo tile). Weighted by irradiance at the object's
    centre (radiance times the lamp's solid angle; pi times radiance for the environment's upper
    half) the soft box is picked most and its samples vary only with the cosine and shadows. A
    glowing body (:mod:`render.bssrdf`) lights the object itself only a little: 2 %.
    """
    out: dict[str, float] = {"environment": max(light.environment, 0.0) * math.pi}
    for name, radiance, size in (
        ("softbox", light.radiance, light.size_factor),
        ("spot", light.highlight_radiance, light.highlight_size_factor),
    ):
        if radiance > 0.0:
            side = 2.0 * size * radius_mm * distance_scale
            out[name] = radiance * min(side * side / (lamp_distance_mm * lamp_distance_mm), 2.0 * math.pi)
    total = sum(out.values()) or 1.0
    weights = {k: max(v / total, 1e-3) for k, v in out.items()}
    weights["relief"] = 0.02
    return weights


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
    emission: np.ndarray | None = None,
) -> np.ndarray:
    """Path-trace a mesh made of smooth pigmented resin under studio light.

    The resin is Mitsuba's ``plastic`` BSDF: a smooth dielectric interface of index
    ``refractive_index`` (Fresnel reflection) over a diffuse body of ``body_albedo``,
    with the internal scattering accounted for (Weidlich & Wilkie 2007); on the vectorised
    variants it is printapp's copy of it (:func:`coated_resin_bsdf`), which draws the mirror
    reflection 70 % of the time instead of about 8 %: the same image with a third of the
    variance where a relief's facets glint or less (the preview's noise on the part_relief
    example, at the same samples, 5.5 % → 3.1 % when it drew it half the time). The camera
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
    With ``emission`` the body glows with that per-vertex radiance instead (see
    :func:`resin_scene_dict`).

    The coated resin's geometry is traced as the preview traces it (:mod:`render.coated_path`).

    Samples are stratified per pixel and averaged in numpy (:mod:`render.progressive`): the
    image is the same, byte for byte, for the same arguments and ``seed``. ``spp`` that is not
    a power of four is rendered in passes of powers of four (:func:`render.progressive.passes_of`),
    weighted by their samples.

    Parameters
    ----------
    vertices_mm : (n, 3) float array
        Vertex positions (mm).
    faces : (m, 3) int array
        Triangles, counter-clockwise seen from outside.

    Returns
    -------
    (height_px, width_px, 3) float32 array of linear RGB radiance; with ``coverage``, a
    (height_px, width_px) boolean mask of the pixels whose centre sees the mesh instead.
    """
    from render.coated_path import camera_estimator
    from render.progressive import SampleRenderer, passes_of

    scene_dict, _ = resin_scene_dict(
        vertices_mm,
        faces,
        body_albedo=body_albedo,
        refractive_index=refractive_index,
        width_px=width_px,
        height_px=height_px,
        elevation_rad=elevation_rad,
        azimuth_rad=azimuth_rad,
        fov_deg=fov_deg,
        light=light,
        medium=medium,
        surface=surface,
        distance_scale=distance_scale,
        frame_vertices=frame_vertices,
        emission=emission,
    )
    renderer = SampleRenderer(scene_dict, int(width_px), int(height_px))
    if coverage:
        return renderer.aovs(4, seed)["coverage"] >= 0.5
    integrator = camera_estimator(renderer)  # (None: the scene's own integrator)
    total = np.zeros((int(height_px), int(width_px), 3), dtype=np.float64)
    for p, count in enumerate(passes_of(int(spp))):
        total += count * renderer.render(
            count, (int(seed) * 0x9E3779B1 + p) & 0xFFFFFFFF, integrator=integrator
        )
    return (total / int(spp)).astype(np.float32)


def to_srgb8(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear RGB to 8-bit sRGB (IEC 61966-2-1 transfer curve), clipped to [0, 1]."""
    x = np.clip(np.nan_to_num(image * exposure, nan=0.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)
