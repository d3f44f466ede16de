"""A virtual gonioreflectometer: the BRDF of a printed relief, by tracing rays through it.

The talk's recipe ("Simulation to go from micro to macro", "Ray tracing specular
surfaces", "Bidirectional Reflectance Distribution Function"): light is a collimated
beam of irradiance ``E`` on a patch of macro area ``A``; rays start uniformly over the
patch (so each carries the same share of the incident flux), are followed through
every bounce on the microgeometry, and escaping rays are binned by direction. The
measurement equation then gives the bin-averaged BRDF

    f_bin = (Phi_bin / Phi_in) / integral_bin cos(theta_o) d omega_o      [1/sr].

The surface is a height field on a regular grid, each cell cut into four triangles
that meet at its centre, raised to the mean of its four corners (the bilinear patch's
centre), and treated as periodic: the tile repeats in x and y, so no ray is lost at
its sides. The four-triangle cell has the square's symmetries: mirroring or turning a
relief by a multiple of 90 degrees mirrors or turns its facets, so the traced highlight
does not depend on how the grid is triangulated. (Two triangles per cell with one fixed
diagonal, as the printable slab has, favour that diagonal: on a Gaussian relief with
grooves at 30 degrees four pixels across, the highlight's anisotropy was 6.2 with the
relief as it is and 5.3 mirrored; with four triangles it is the same both ways.)

At each hit the ray's energy is split, not sampled: the Fresnel fraction ``R``
(unpolarised, dielectric, index ``n``) continues as the mirror reflection, and the
rest enters the resin. The resin is an opaque, pigmented body: light that enters it
is scattered by pigment within a few tens of micrometres (the transport mean free path
of pigmented resins, far below the relief's facets), forgets its direction, and comes
back out close to where it went in. So it is modelled, as Mitsuba's ``plastic`` and
Weidlich & Wilkie (2007) do, by a Lambertian body of albedo ``rho`` under the smooth
interface, with the internal reflections summed in closed form: the light leaving
the facet has radiance proportional to ``1 - R(theta_o)`` and total

    (1 - R(theta_i)) * rho * (1 - F_dr,int) / (1 - rho * F_dr,int),

where ``F_dr,int`` is the interface's diffuse reflectance seen from inside. That
light then continues as a ray that may hit the relief again. Translucency beyond the
facet scale is the Lorenz-Mie stage's business, not this one's.

The tracer walks the grid cell by cell (a 2-D DDA) with a max-mipmap: blocks of
2^L x 2^L cells whose highest sample lies below the ray are skipped whole (Tevs,
Ihrke & Seidel 2008, "Maximum mipmaps for fast, accurate, and scalable dynamic height
field rendering"). In each cell, the signed height of the ray over the surface is
linear on each triangle, and its value at a cell's exit is carried into the next cell
instead of being recomputed, so a ray cannot slip between two triangles through
rounding: the test is watertight by construction (the same holds across the two
diagonals inside a cell). A ray leaving a facet is never
tested against that facet's plane again (a straight ray cannot return to a plane it
leaves), which is the self-intersection offset, with no epsilon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from noise.hashing import seed_key
from render._gonio_kernels import _CHUNKS, _gonio, _primary_origin, _trace
from render.fresnel import diffuse_fresnel_reflectance


def max_mipmap(heights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Max-mipmap of a periodic height field's cells, packed flat.

    Level 0 holds each cell's highest corner (cells wrap: the last column's cells
    reach back to the first column). Level L holds the maximum over blocks of
    2^L x 2^L cells; blocks never straddle the tile's seam (the last block in a row
    or column is truncated), so the hierarchy works for any grid size.

    Returns ``(flat, offsets, level_nx, n_levels)``.
    """
    h = np.asarray(heights, dtype=np.float64)
    cell = np.maximum(
        np.maximum(h, np.roll(h, -1, axis=1)), np.maximum(np.roll(h, -1, axis=0), np.roll(h, -1, axis=(0, 1)))
    )
    levels = [cell]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        prev = levels[-1]
        rows = np.maximum.reduceat(prev, np.arange(0, prev.shape[0], 2), axis=0)
        levels.append(np.maximum.reduceat(rows, np.arange(0, prev.shape[1], 2), axis=1))
    offsets = np.cumsum([0] + [lv.size for lv in levels[:-1]]).astype(np.int64)
    flat = np.concatenate([lv.ravel() for lv in levels])
    level_nx = np.array([lv.shape[1] for lv in levels], dtype=np.int64)
    return flat, offsets, level_nx, len(levels)


def facet_slopes(heights: np.ndarray, pitch_x: float, pitch_y: float) -> tuple[np.ndarray, np.ndarray]:
    """Slopes ``dh/dx`` and ``dh/dy`` of the tracer's facets, four per periodic cell, of equal area.

    Triangle k of every cell (0 bottom, 1 right, 2 top, 3 left, as :func:`first_hit`
    numbers them) fills rows ``k * ny * nx`` to ``(k + 1) * ny * nx`` of the result, cells
    row by row. Each facet covers a quarter of its cell, so the plain histogram of these
    slopes is the relief's slope distribution per unit of macro area.
    """
    h = np.asarray(heights, dtype=np.float64)
    h10 = np.roll(h, -1, axis=1)
    h01 = np.roll(h, -1, axis=0)
    h11 = np.roll(h10, -1, axis=0)
    hc = 0.25 * ((h + h11) + (h10 + h01))
    gx = [h10 - h, (h10 + h11) - 2.0 * hc, h11 - h01, 2.0 * hc - (h + h01)]
    gy = [2.0 * hc - (h + h10), h11 - h10, (h01 + h11) - 2.0 * hc, h01 - h]
    return (
        np.concatenate([g.ravel() for g in gx]) / pitch_x,
        np.concatenate([g.ravel() for g in gy]) / pitch_y,
    )


@njit(cache=True)
def first_hit(h, px, py, mip, mip_off, mip_nx, n_levels, zmax, zmin, ox, oy, oz, dx, dy, dz):
    """First hit of one ray with the periodic height field: the estimator's tracer, alone.

    The query :func:`estimate_brdf` makes for every ray, without Fresnel splitting,
    bounces or binning, so that it can be compared with other ray tracers on the same
    rays. Compiled with numba: callable from other ``@njit`` functions (one ray per call).

    Parameters
    ----------
    h : ndarray of float64, shape (ny, nx)
        Heights (mm) relative to their mean, C-contiguous; rows along y, columns along x.
    px, py : float
        Sample spacing along x and along y (mm).
    mip, mip_off, mip_nx, n_levels
        The max-mipmap of ``h``: the four values :func:`max_mipmap` returns.
    zmax, zmin : float
        Highest and lowest value of ``h`` (mm).
    ox, oy, oz : float
        Ray origin (mm); x and y in the tile's frame, any period.
    dx, dy, dz : float
        Unit ray direction.

    Returns
    -------
    status : int
        0 escaped (above every sample, going up), 1 hit, 2 lost (step budget exhausted).
    t : float
        Distance along the ray (mm): to the hit, or as far as the ray was followed.
    nx, ny, nz : float
        Unit normal of the facet hit (zero unless ``status`` is 1).
    ci, cj : int
        Unwrapped cell (column, row) where the ray ended; outside ``0..nx-1`` after wrapping.
    tri : int
        Triangle hit, of the four around the cell's centre c: 0 bottom (v00, v10, c),
        1 right (v10, v11, c), 2 top (v11, v01, c), 3 left (v01, v00, c); -1 unless a hit.
    steps : int
        Cells and mipmap blocks visited.
    """
    return _trace(h, px, py, mip, mip_off, mip_nx, n_levels, zmax, zmin, ox, oy, oz, dx, dy, dz, 0, 0, -1)


@njit(cache=True, inline="always")
def primary_origin(ray_key, window, d_idx, px, py, wix, wiy, wiz, zmax, period_x, period_y):
    """Where the estimator starts a primary ray, bit for bit, to regenerate its rays elsewhere.

    Compiled with numba: callable from other ``@njit`` functions. :func:`estimate_brdf`
    keys ray ``k`` of incident direction ``d_idx`` as
    ``mix64(seed_key(seed) ^ (d_idx << 40) ^ k)`` (:mod:`noise.hashing`) and starts it
    here, at height ``zmax``, travelling along ``-wi``.

    Parameters
    ----------
    ray_key : uint64
        The ray's key; the first two numbers of its stream place it.
    window : ndarray of float64, shape (n_directions, 4)
        Per direction, the lit window in cells: first cell and extent along x, then along y.
    d_idx : int
        Row of ``window`` (the incident direction's index).
    px, py : float
        Sample spacing along x and along y (mm).
    wix, wiy, wiz : float
        Unit incident direction (towards the light), ``wiz > 0``.
    zmax : float
        Height of the start (mm): the highest sample, heights relative to their mean.
    period_x, period_y : float
        Tile size along x and along y (mm).

    Returns
    -------
    x0, y0 : float
        Start of the ray (mm), wrapped into ``[0, period_x)`` and ``[0, period_y)``.
    """
    return _primary_origin(ray_key, window, d_idx, px, py, wix, wiy, wiz, zmax, period_x, period_y)


@dataclass
class BrdfTable:
    """A tabulated, bin-averaged BRDF from the virtual gonioreflectometer.

    Attributes
    ----------
    wi : (n_in, 3) array
        Incident directions (unit, pointing away from the surface; z is the macro normal).
    theta_o_edges, phi_o_edges : arrays
        Bin edges of the outgoing direction (radians): theta in [0, pi/2], phi in [0, 2 pi).
    f : (n_in, n_theta, n_phi) array
        Bin-averaged BRDF (1/sr): the fraction of incident power reflected into the bin
        divided by the bin's projected solid angle, ``integral cos(theta_o) d omega_o``.
    stderr : array like ``f``
        Standard error of ``f`` (from the spread over independent primary rays).
    f_specular, stderr_specular : arrays like ``f``
        The part of ``f`` carried by paths that never entered the resin body
        (surface reflection only, any number of bounces).
    albedo, albedo_stderr : (n_in,) arrays
        Directional albedo: the fraction of incident power that escapes.
    lost : (n_in,) array
        Fraction of incident power dropped by safety limits (stack depth, bounce
        count, step budget); zero in practice, and reported so that it can be checked.
    aperture, aperture_stderr : (n_in,) arrays
        Fraction of incident power reflected into the receptor aperture around the
        mirror direction (for gloss; zero where no aperture was asked for).
    ior, body_albedo : float
        Refractive index of the resin and albedo of its body.
    rays : (n_in,) int array
        Primary rays per incident direction.
    """

    wi: np.ndarray
    theta_o_edges: np.ndarray
    phi_o_edges: np.ndarray
    f: np.ndarray
    stderr: np.ndarray
    f_specular: np.ndarray
    stderr_specular: np.ndarray
    albedo: np.ndarray
    albedo_stderr: np.ndarray
    lost: np.ndarray
    aperture: np.ndarray
    aperture_stderr: np.ndarray
    ior: float
    body_albedo: float
    rays: np.ndarray
    extra: dict = field(default_factory=dict)

    @property
    def projected_solid_angle(self) -> np.ndarray:
        """``integral_bin cos(theta) d omega`` for every (theta, phi) bin (sr)."""
        return projected_solid_angle(self.theta_o_edges, self.phi_o_edges)

    def arrays(self) -> dict[str, np.ndarray]:
        """The table as the arrays of ``brdf.npz``."""
        return {
            "wi": self.wi,
            "theta_o_edges": self.theta_o_edges,
            "phi_o_edges": self.phi_o_edges,
            "f": self.f,
            "stderr": self.stderr,
            "f_specular": self.f_specular,
            "stderr_specular": self.stderr_specular,
            "albedo": self.albedo,
            "albedo_stderr": self.albedo_stderr,
            "lost": self.lost,
            "ior": np.float64(self.ior),
            "body_albedo": np.float64(self.body_albedo),
            "rays": self.rays,
        }


def projected_solid_angle(theta_edges: np.ndarray, phi_edges: np.ndarray) -> np.ndarray:
    """``integral cos(theta) sin(theta) dtheta dphi`` over each bin (sr): (n_theta, n_phi)."""
    s2 = np.sin(np.asarray(theta_edges)) ** 2
    return 0.5 * np.outer(np.diff(s2), np.diff(np.asarray(phi_edges)))


LOBE_FRACTION = 0.9  # the bins holding this much of the specular energy are "the lobe"


def lobe_bins(f_specular: np.ndarray, omega: np.ndarray, fraction: float = LOBE_FRACTION) -> np.ndarray:
    """Flat indices of the fewest bins holding ``fraction`` of the specular energy ``f omega``."""
    energy = (f_specular * omega).ravel()
    order = np.argsort(energy, kind="stable")[::-1]
    cumulative = np.cumsum(energy[order])
    if cumulative[-1] <= 0.0:
        return order[:0]
    return order[: int(np.searchsorted(cumulative, fraction * cumulative[-1])) + 1]


def lobe_error(f: np.ndarray, stderr: np.ndarray, omega: np.ndarray, bins: np.ndarray | None = None) -> float:
    """Energy-weighted mean relative standard error over the lobe: ``sum omega s / sum omega f``.

    The error of a traced highlight: inf where nothing was reflected at the surface.
    """
    if bins is None:
        bins = lobe_bins(f, omega)
    w = omega.ravel()[bins]
    total = float(np.sum(w * f.ravel()[bins]))
    return float(np.sum(w * stderr.ravel()[bins])) / total if total > 0.0 else math.inf


def table_lobe_errors(table: BrdfTable) -> np.ndarray:
    """:func:`lobe_error` of each incident direction's surface-reflection lobe."""
    omega = table.projected_solid_angle
    return np.array(
        [lobe_error(table.f_specular[k], table.stderr_specular[k], omega) for k in range(len(table.wi))]
    )


def rays_for_lobe_error(
    errors: np.ndarray, rays: np.ndarray, target: float, max_rays: int = 100_000_000
) -> np.ndarray:
    """Primary rays per direction for a lobe error of ``target``, from a run's ``errors`` with ``rays``.

    The error falls as 1/sqrt(rays) (checked in ``printapp bench brdf``: log-log slopes
    -0.496 to -0.501), so a direction needs ``rays (error / target)^2``; never fewer than
    were traced, never more than ``max_rays`` (a direction without a lobe gets the
    calibration's rays).
    """
    errors = np.asarray(errors, dtype=np.float64)
    rays = np.asarray(rays, dtype=np.int64)
    ratio = np.where(np.isfinite(errors), (errors / target) ** 2, 1.0)
    needed = np.ceil(rays * np.maximum(ratio, 1.0))
    return np.maximum(np.minimum(needed, max_rays), rays).astype(np.int64)


def direction_from_angles(theta_rad: np.ndarray, phi_rad: np.ndarray) -> np.ndarray:
    """Unit vectors (n, 3) from polar angle (from +z) and azimuth (from +x towards +y)."""
    theta = np.atleast_1d(np.asarray(theta_rad, dtype=np.float64))
    phi = np.atleast_1d(np.asarray(phi_rad, dtype=np.float64))
    return np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def body_factor(body_albedo: float, ior: float) -> float:
    """``rho / (n^2 (1 - rho F_dr,int))``: the body's outgoing weight per ``(1-R_i)(1-R_o)``."""
    if body_albedo <= 0.0:
        return 0.0
    f_int = diffuse_fresnel_reflectance(1.0 / ior)
    return body_albedo / (ior * ior * (1.0 - body_albedo * f_int))


def lit_window(
    heights_mm: np.ndarray, pitch_x_mm: float, pitch_y_mm: float, wi: np.ndarray, periodic: bool
) -> np.ndarray:
    """First cell and extent (cells) of the window :func:`estimate_brdf` lights, per direction: ``(n_in, 4)``.

    Columns: first cell along x, cells along x, first cell along y, cells along y. The
    whole tile where it is periodic; else the patch's interior, kept as far from the seams
    as light at that incidence travels down through the relief's height range, and at
    least an eighth and at most a quarter of the patch from each side.
    """
    h = np.asarray(heights_mm, dtype=np.float64)
    wis = np.atleast_2d(np.asarray(wi, dtype=np.float64))
    ny, nx = h.shape
    window = np.zeros((wis.shape[0], 4))
    window[:, 1], window[:, 3] = nx, ny
    if not periodic:
        travel = float(h.max() - h.min()) * np.hypot(wis[:, 0], wis[:, 1]) / wis[:, 2]
        # At least an eighth of the patch too, for reflected light that travels sideways.
        margin_x = np.minimum(np.maximum(np.ceil(travel / pitch_x_mm) + 2.0, nx // 8), nx // 4)
        margin_y = np.minimum(np.maximum(np.ceil(travel / pitch_y_mm) + 2.0, ny // 8), ny // 4)
        window[:, 0], window[:, 1] = margin_x, nx - 2 * margin_x
        window[:, 2], window[:, 3] = margin_y, ny - 2 * margin_y
    return window


def estimate_brdf(
    heights_mm: np.ndarray,
    pitch_x_mm: float,
    pitch_y_mm: float,
    wi: np.ndarray,
    *,
    rays: int | np.ndarray = 200_000,
    ior: float = 1.5,
    body_albedo: float = 0.0,
    n_theta: int = 90,
    n_phi: int = 180,
    seed: int = 0,
    aperture_rad: np.ndarray | None = None,
    perfect_reflector: bool = False,
    periodic: bool = True,
) -> BrdfTable:
    """Bin-averaged BRDF of a periodic height field by tracing rays through it.

    Parameters
    ----------
    heights_mm : (ny, nx) array
        Heights (mm) on a regular grid; the tile is treated as periodic (sample
        ``nx`` is sample 0 again), so an ``ny x nx`` grid is ``ny x nx`` cells.
    pitch_x_mm, pitch_y_mm : float
        Sample spacing (mm). Only ratios of heights to pitches matter.
    wi : (n_in, 3) array
        Incident directions, unit, pointing away from the surface (z > 0).
    rays : int or (n_in,) int array
        Primary rays per direction. The error of each bin falls as 1/sqrt(rays).
    ior : float
        Refractive index of the resin (air outside).
    body_albedo : float
        Albedo of the pigmented body under the interface (0 for a black resin).
    n_theta, n_phi : int
        Uniform bins over theta_o in [0, 90 deg] and phi_o in [0, 360 deg).
    seed : int
        Seed of the rays; the same seed gives byte-identical tables.
    aperture_rad : (n_in, 2) array, optional
        Half-widths (in the plane of incidence, across it) of a receptor aperture
        centred on the mirror direction, for gloss; 0 switches it off.
    perfect_reflector : bool
        Reflect everything (R = 1, no body): a white-furnace test of the tracer.
    periodic : bool
        True when the tile really repeats (its last sample continues into its first).
        False for a patch cut out of a larger relief: the seam between its opposite
        edges is then a step that is not part of the relief, so the beam lights only
        the patch's interior, kept as far from the seams as light at each incidence
        travels down through the relief's height range (at least an eighth and at
        most a quarter of the patch on each side).

    Returns
    -------
    BrdfTable
    """
    h = np.ascontiguousarray(heights_mm, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise ValueError("heights_mm: expected a finite 2-D array of at least 2x2 samples")
    if not h.flags.writeable:  # read-only is another type to numba: another compilation
        h = h.copy()
    if not (pitch_x_mm > 0 and pitch_y_mm > 0):
        raise ValueError("pitch: expected positive pixel pitches (mm)")
    wis = np.atleast_2d(np.asarray(wi, dtype=np.float64))
    if wis.shape[1] != 3 or not np.all(np.isfinite(wis)):
        raise ValueError("wi: expected an (n, 3) array of finite directions")
    wis = wis / np.linalg.norm(wis, axis=1, keepdims=True)
    if np.any(wis[:, 2] <= 0.0):
        raise ValueError("wi: incident directions must point away from the surface (z > 0)")
    if not (ior >= 1.0 and math.isfinite(ior)):
        raise ValueError(f"ior: expected a refractive index >= 1, got {ior}")
    if not 0.0 <= body_albedo <= 1.0:
        raise ValueError(f"body_albedo: expected a value in [0, 1], got {body_albedo}")
    n_in = wis.shape[0]
    ray_counts = np.broadcast_to(np.asarray(rays, dtype=np.int64), (n_in,)).copy()
    if np.any(ray_counts < 2):
        raise ValueError("rays: expected at least 2 rays per direction")
    ap = np.zeros((n_in, 2)) if aperture_rad is None else np.asarray(aperture_rad, dtype=np.float64)
    ap = np.broadcast_to(ap, (n_in, 2))
    mirror = wis * np.array([-1.0, -1.0, 1.0])
    e_perp = np.column_stack([-wis[:, 1], wis[:, 0], np.zeros(n_in)])
    norm = np.linalg.norm(e_perp, axis=1)
    e_perp[norm == 0.0] = (0.0, 1.0, 0.0)
    e_perp /= np.linalg.norm(e_perp, axis=1, keepdims=True)

    # Heights relative to their mean keep coordinates small; pitches stay in mm.
    h = h - h.mean()
    mip, mip_off, mip_nx, n_levels = max_mipmap(h)
    zmax, zmin = float(h.max()), float(h.min())
    ny, nx = h.shape
    window = lit_window(h, pitch_x_mm, pitch_y_mm, wis, periodic)
    n_jobs = n_in * _CHUNKS
    n_bins = n_theta * n_phi
    acc_all = np.zeros((n_jobs, n_bins))
    sq_all = np.zeros((n_jobs, n_bins))
    acc_spec = np.zeros((n_jobs, n_bins))
    sq_spec = np.zeros((n_jobs, n_bins))
    scalars = np.zeros((n_jobs, 7))
    _gonio(
        h,
        float(pitch_x_mm),
        float(pitch_y_mm),
        mip,
        mip_off,
        mip_nx,
        n_levels,
        zmax,
        zmin,
        wis,
        ray_counts,
        window,
        mirror,
        e_perp,
        # Copies: a view of the broadcast apertures is read-only for one direction and not for
        # several, and numba compiles each flag apart (a second compilation of this kernel).
        np.array(ap[:, 0]),
        np.array(ap[:, 1]),
        float(ior),
        0.0 if perfect_reflector else body_factor(body_albedo, ior),
        bool(perfect_reflector),
        int(n_theta),
        int(n_phi),
        seed_key(seed),
        acc_all,
        sq_all,
        acc_spec,
        sq_spec,
        scalars,
    )

    def per_dir(a: np.ndarray) -> np.ndarray:
        return a.reshape(n_in, _CHUNKS, *a.shape[1:]).sum(axis=1)

    n = ray_counts.astype(np.float64)
    theta_edges = np.linspace(0.0, math.pi / 2, n_theta + 1)
    phi_edges = np.linspace(0.0, 2 * math.pi, n_phi + 1)
    omega = projected_solid_angle(theta_edges, phi_edges)

    def mean_and_error(acc: np.ndarray, sq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mean = acc / n.reshape((-1,) + (1,) * (acc.ndim - 1))
        second = sq / n.reshape((-1,) + (1,) * (acc.ndim - 1))
        var = np.clip(second - mean * mean, 0.0, None) / (n.reshape((-1,) + (1,) * (acc.ndim - 1)) - 1.0)
        return mean, np.sqrt(var)

    f, se = mean_and_error(per_dir(acc_all), per_dir(sq_all))
    fs, ses = mean_and_error(per_dir(acc_spec), per_dir(sq_spec))
    shape = (n_in, n_theta, n_phi)
    s = per_dir(scalars)
    albedo, albedo_se = mean_and_error(s[:, 0], s[:, 1])
    aperture, aperture_se = mean_and_error(s[:, 2], s[:, 3])
    return BrdfTable(
        wi=wis,
        theta_o_edges=theta_edges,
        phi_o_edges=phi_edges,
        f=f.reshape(shape) / omega,
        stderr=se.reshape(shape) / omega,
        f_specular=fs.reshape(shape) / omega,
        stderr_specular=ses.reshape(shape) / omega,
        albedo=albedo,
        albedo_stderr=albedo_se,
        lost=s[:, 4] / n,
        aperture=aperture,
        aperture_stderr=aperture_se,
        ior=float(ior),
        body_albedo=float(body_albedo),
        rays=ray_counts,
        extra={"segments": s[:, 6], "steps": s[:, 5]},
    )
