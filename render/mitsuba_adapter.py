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


# --- The printed surface's appearance as BSDFs: the fitted model and the traced table ----------

_registered: dict[str, Any] = {}


@dataclass(frozen=True)
class CompactSurface:
    """Representation (a): the fitted compact model (:class:`render.brdf_model.MicrofacetBRDF`).

    ``body_rgb`` is the resin's linear-RGB body albedo (the fit's grey albedo is its
    luminance). The anisotropy's azimuth is measured in the shading frame, which on a
    surface facing +z is the world's x and y.
    """

    distribution: str
    alpha_u: float
    alpha_v: float
    azimuth_rad: float
    ior: float
    body_rgb: tuple[float, float, float]
    spike_weight: float = 0.0
    spike_alpha: float = 0.002


@dataclass(frozen=True)
class TableSurface:
    """Representation (b): a traced BRDF table over a regular grid of incident directions.

    ``specular`` and ``body`` are ``(n_theta_i, n_phi_i, n_theta_o, n_phi_o)`` arrays
    (1/sr) of the surface-only and the through-the-body parts; incident polar angles run
    evenly from 0 to ``theta_i_max_rad``, azimuths evenly over [0, 2 pi); ``body_tint``
    scales the body part per channel (for a coloured resin traced in grey).
    """

    specular: np.ndarray
    body: np.ndarray
    theta_i_max_rad: float
    body_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)


def surface_bsdf(surface: CompactSurface | TableSurface | dict) -> Any:
    """A Mitsuba BSDF object for a representation of the printed surface (variant already set).

    A ``dict`` is a Mitsuba plugin description, loaded as it is (for comparisons with
    Mitsuba's own BSDFs).
    """
    import mitsuba as mi

    from render.fresnel import diffuse_fresnel_reflectance

    _register_plugins()
    if isinstance(surface, dict):
        return mi.load_dict(surface)
    if isinstance(surface, CompactSurface):
        return mi.load_dict(
            {
                "type": "printapp_compact",
                "distribution": surface.distribution,
                "alpha_u": float(surface.alpha_u),
                "alpha_v": float(surface.alpha_v),
                "azimuth": float(surface.azimuth_rad),
                "spike_weight": float(surface.spike_weight),
                "spike_alpha": float(surface.spike_alpha),
                "ior": float(surface.ior),
                "f_dr_int": float(diffuse_fresnel_reflectance(1.0 / surface.ior)),
                "body": {"type": "rgb", "value": [float(c) for c in surface.body_rgb]},
            }
        )
    bsdf = mi.load_dict({"type": "printapp_table"})
    bsdf.set_table(surface.specular, surface.body, surface.theta_i_max_rad, surface.body_tint)
    return bsdf


def _register_plugins() -> None:
    """Define and register printapp's BSDF plugins for the current variant (once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _registered:
        return

    def fresnel(cos_i, eta):
        cos_i = dr.clip(dr.abs(cos_i), 0.0, 1.0)
        sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
        cos_t = dr.safe_sqrt(1.0 - sin2_t)
        r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        return dr.select(sin2_t >= 1.0, 1.0, 0.5 * (r_perp * r_perp + r_par * r_par))

    class CompactResin(mi.BSDF):
        """The fitted compact model: anisotropic microfacet lobe, optional sharp spike, Lambertian body."""

        def __init__(self, props):
            super().__init__(props)
            self.ggx = props.get("distribution", "ggx") == "ggx"  # else Beckmann
            self.alpha_u = float(props.get("alpha_u", 0.1))
            self.alpha_v = float(props.get("alpha_v", 0.1))
            self.azimuth = float(props.get("azimuth", 0.0))
            self.spike_weight = float(props.get("spike_weight", 0.0))
            self.spike_alpha = float(props.get("spike_alpha", 0.002))
            self.eta = float(props.get("ior", 1.5))
            body = props.get("body", mi.ScalarColor3f(0.5, 0.5, 0.5))
            f_int = float(props.get("f_dr_int", 0.6))
            rho = [float(body[i]) for i in range(3)]
            # rho / (pi n^2 (1 - rho F_dr,int)) per channel
            self.body_factor = mi.Color3f(*[r / (math.pi * self.eta**2 * (1.0 - r * f_int)) for r in rho])
            self.body_mean = sum(rho) / 3.0
            self.m_components = [
                mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide,
                mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide,
            ]
            self.m_flags = self.m_components[0] | self.m_components[1]

        # --- one lobe -----------------------------------------------------------------
        def _rot(self, v):
            c, s = math.cos(self.azimuth), math.sin(self.azimuth)
            return mi.Vector3f(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)

        def _unrot(self, v):
            c, s = math.cos(self.azimuth), math.sin(self.azimuth)
            return mi.Vector3f(c * v.x - s * v.y, s * v.x + c * v.y, v.z)

        def _d(self, m, au, av):
            x2 = (m.x * m.x) / (au * au) + (m.y * m.y) / (av * av)
            z2 = m.z * m.z
            if self.ggx:
                q = x2 + z2
                return dr.rcp(dr.pi * au * av * q * q)
            return dr.exp(-x2 / z2) / (dr.pi * au * av * z2 * z2)

        def _lambda(self, w, au, av):
            proj = dr.sqrt(au * au * w.x * w.x + av * av * w.y * w.y)
            wz = dr.maximum(w.z, 1e-7)
            if self.ggx:
                return 0.5 * (dr.sqrt(1.0 + (proj / wz) ** 2) - 1.0)
            a = wz / dr.maximum(proj, 1e-12)
            lam = 0.5 * (dr.erf(a) - 1.0) + dr.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))
            return dr.select(a > 26.0, 0.0, lam)

        def _distribution(self, au, av):
            kind = mi.MicrofacetType.GGX if self.ggx else mi.MicrofacetType.Beckmann
            return mi.MicrofacetDistribution(kind, au, av, True)

        def _lobe_eval_pdf(self, wi, wo, au, av):
            """f cos(theta_o), and the pdf of sampling wo by this lobe's visible normals (rotated frame)."""
            h = dr.normalize(wi + wo)
            d = self._d(h, au, av)
            g2 = dr.rcp(1.0 + self._lambda(wi, au, av) + self._lambda(wo, au, av))
            f = fresnel(dr.dot(wi, h), self.eta) * d * g2 / (4.0 * wi.z)
            # Visible normals (Heitz 2018): pdf(m) = G1(wi) max(0, wi.m) D(m) / cos(theta_i).
            g1 = dr.rcp(1.0 + self._lambda(wi, au, av))
            pdf = (
                g1
                * dr.maximum(dr.dot(wi, h), 0.0)
                * d
                / wi.z
                / (4.0 * dr.maximum(dr.abs(dr.dot(wo, h)), 1e-12))
            )
            return f, pdf

        def _choice(self, cos_i):
            f = fresnel(cos_i, self.eta)
            spec = f
            body = (1.0 - f) * self.body_mean
            p_spec = spec / dr.maximum(spec + body, 1e-12)
            return p_spec

        def _all(self, wi_l, wo_l):
            wi, wo = self._rot(wi_l), self._rot(wo_l)
            w = self.spike_weight
            f1, p1 = self._lobe_eval_pdf(wi, wo, self.alpha_u, self.alpha_v)
            value = (1.0 - w) * f1
            pdf_spec = (1.0 - w) * p1
            if w > 0.0:
                f2, p2 = self._lobe_eval_pdf(wi, wo, self.spike_alpha, self.spike_alpha)
                value += w * f2
                pdf_spec += w * p2
            body = (1.0 - fresnel(wi.z, self.eta)) * (1.0 - fresnel(wo.z, self.eta)) * wo.z
            p_spec = self._choice(wi.z)
            pdf = p_spec * pdf_spec + (1.0 - p_spec) * mi.warp.square_to_cosine_hemisphere_pdf(wo_l)
            return value, body, pdf

        def eval(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            value, body, _ = self._all(si.wi, wo)
            out = mi.Spectrum(value) + self.body_factor * body
            return dr.select(ok, out, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            _, _, pdf = self._all(si.wi, wo)
            return dr.select(ok, pdf, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            value, body, pdf = self._all(si.wi, wo)
            out = mi.Spectrum(value) + self.body_factor * body
            return dr.select(ok, out, 0.0), dr.select(ok, pdf, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi_l = si.wi
            cos_i = mi.Frame3f.cos_theta(wi_l)
            active = active & (cos_i > 0)
            p_spec = self._choice(cos_i)
            pick_spec = sample1 < p_spec
            # Which lobe: the spike with probability spike_weight (reusing sample1's remainder).
            u_lobe = sample1 / dr.maximum(p_spec, 1e-12)
            wi = self._rot(wi_l)
            m, _ = self._distribution(self.alpha_u, self.alpha_v).sample(wi, sample2)
            if self.spike_weight > 0.0:
                m_spike, _ = self._distribution(self.spike_alpha, self.spike_alpha).sample(wi, sample2)
                m = dr.select(u_lobe < self.spike_weight, m_spike, m)
            wo_spec = self._unrot(2.0 * dr.dot(wi, m) * m - wi)
            wo_diff = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = dr.select(pick_spec, wo_spec, wo_diff)
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.eta = 1.0
            bs.sampled_component = dr.select(pick_spec, mi.UInt32(0), mi.UInt32(1))
            bs.sampled_type = dr.select(
                pick_spec,
                mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
            )
            value, body, pdf = self._all(wi_l, wo)
            bs.pdf = pdf
            ok = active & (mi.Frame3f.cos_theta(wo) > 0) & (pdf > 0)
            weight = (mi.Spectrum(value) + self.body_factor * body) / dr.maximum(pdf, 1e-12)
            return bs, dr.select(ok, weight, 0.0)

        def to_string(self):
            return f"CompactResin[alpha = ({self.alpha_u}, {self.alpha_v}), spike = {self.spike_weight}]"

    class TabulatedBRDF(mi.BSDF):
        """A traced BRDF table over a grid of incident directions, looked up bin by bin.

        The value is bilinear in the incident direction (theta_i, phi_i) between the grid's
        directions and constant over each outgoing bin (the table holds bin averages). The
        surface-only part and the body part are kept apart so that the body can be tinted
        per channel. Sampling is cosine-weighted.
        """

        def __init__(self, props):
            super().__init__(props)
            self.m_components = [mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide]
            self.m_flags = self.m_components[0]
            self.n_ti = self.n_pi = self.n_to = self.n_po = 1
            self.theta_i_max = 1.0

        def set_table(self, specular, body, theta_i_max, body_tint):
            """``specular``, ``body``: (n_theta_i, n_phi_i, n_theta_o, n_phi_o) in 1/sr."""
            self.n_ti, self.n_pi, self.n_to, self.n_po = specular.shape
            self.theta_i_max = float(theta_i_max)
            self.spec = mi.Float(np.ascontiguousarray(specular, dtype=np.float32).ravel())
            self.body = mi.Float(np.ascontiguousarray(body, dtype=np.float32).ravel())
            self.tint = mi.Color3f(*[float(t) for t in body_tint])

        def _bin(self, w):
            theta = dr.acos(dr.clip(w.z, -1.0, 1.0))
            phi = dr.atan2(w.y, w.x)
            phi = dr.select(phi < 0.0, phi + 2.0 * dr.pi, phi)
            to = dr.minimum(mi.UInt32(theta * (2.0 / dr.pi) * self.n_to), self.n_to - 1)
            po = dr.minimum(mi.UInt32(phi * (0.5 / dr.pi) * self.n_po), self.n_po - 1)
            return to * self.n_po + po

        def _lookup(self, wi, wo):
            """Bilinear over the incident grid (theta_i clamped, phi_i periodic).

            The body part is read at ``wo`` itself. The surface part is read, at each of
            the four grid directions ``wi_k``, where ``wi_k`` has the same half vector as
            ``(wi, wo)``: ``wo_k = 2 (wi_k . h) h - wi_k``, and carried over as
            ``f cos(theta_i) cos(theta_o)``, which for microfacet reflection is
            ``F D G / 4``, a function of h but for F and G. A glossy lobe moves with its
            mirror direction, so blending lobes read this way moves the lobe instead of
            smearing two copies of it.
            """
            theta_i = dr.acos(dr.clip(wi.z, -1.0, 1.0))
            phi_i = dr.atan2(wi.y, wi.x)
            phi_i = dr.select(phi_i < 0.0, phi_i + 2.0 * dr.pi, phi_i)
            h = dr.normalize(wi + wo)
            direct = self._bin(wo)
            ti = dr.clip(theta_i / self.theta_i_max * (self.n_ti - 1), 0.0, self.n_ti - 1.0)
            pi_ = phi_i * (0.5 / dr.pi) * self.n_pi
            t0 = dr.minimum(mi.UInt32(dr.floor(ti)), self.n_ti - 1)
            t1 = dr.minimum(t0 + 1, self.n_ti - 1)
            ft = ti - mi.Float(t0)
            p0 = mi.UInt32(dr.floor(pi_)) % self.n_pi
            p1 = (p0 + 1) % self.n_pi
            fp = pi_ - dr.floor(pi_)
            spec = mi.Float(0.0)
            body = mi.Float(0.0)
            per_in = self.n_to * self.n_po
            for t, wt in ((t0, 1.0 - ft), (t1, ft)):
                theta_k = mi.Float(t) * (self.theta_i_max / max(self.n_ti - 1, 1))
                for p, wp in ((p0, 1.0 - fp), (p1, fp)):
                    phi_k = mi.Float(p) * (2.0 * dr.pi / self.n_pi)
                    sin_k = dr.sin(theta_k)
                    wi_k = mi.Vector3f(sin_k * dr.cos(phi_k), sin_k * dr.sin(phi_k), dr.cos(theta_k))
                    wo_k = 2.0 * dr.dot(wi_k, h) * h - wi_k
                    moved = wo_k.z > 0.0
                    out_k = dr.select(moved, self._bin(wo_k), direct)
                    # f cos_i cos_o = F D G / 4 depends on h (and slowly on F, G): carry that.
                    scale = dr.select(moved, wi_k.z * wo_k.z / dr.maximum(wi.z * wo.z, 1e-4), 1.0)
                    base = (t * self.n_pi + p) * per_in
                    spec += wt * wp * scale * dr.gather(mi.Float, self.spec, base + out_k)
                    body += wt * wp * dr.gather(mi.Float, self.body, base + direct)
            return spec, body

        def eval(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            spec, body = self._lookup(si.wi, wo)
            value = (mi.Spectrum(spec) + self.tint * body) * mi.Frame3f.cos_theta(wo)
            return dr.select(ok, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            return dr.select(ok, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.eta = 1.0
            bs.pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            bs.sampled_component = mi.UInt32(0)
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (bs.pdf > 0)
            spec, body = self._lookup(si.wi, wo)
            weight = (mi.Spectrum(spec) + self.tint * body) * dr.pi  # f cos / (cos / pi)
            return bs, dr.select(ok, weight, 0.0)

        def to_string(self):
            return f"TabulatedBRDF[{self.n_ti} x {self.n_pi} incident, {self.n_to} x {self.n_po} outgoing]"

    mi.register_bsdf("printapp_compact", lambda props: CompactResin(props))
    mi.register_bsdf("printapp_table", lambda props: TabulatedBRDF(props))
    _registered[variant] = TabulatedBRDF
