"""``printapp brdf``: the predicted BRDF of a design, a height map or a mesh tile, and its files.

The numerics are :mod:`render.gonio` (the tracer), :mod:`render.brdf_model` (the compact
model) and :mod:`render.appearance` (gloss, haze, highlight); this module reads the
inputs, writes ``brdf.npz`` byte for byte the same for the same input and seed, and
draws the plot.
"""

from __future__ import annotations

import io
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from noise.heightfield import HeightField
from printapp.errors import PrintappError
from printapp.memory import BASE_BYTES, BRDF_BYTES_PER_SAMPLE, fits, require

if TYPE_CHECKING:
    from render.appearance import Appearance

MESH_SUFFIXES = (".stl", ".ply", ".obj", ".off", ".3mf")
REC709_LUMA = (0.2126, 0.7152, 0.0722)


def grey_albedo(rgb: tuple[float, float, float]) -> float:
    """The body albedo the (grey) gonioreflectometer uses: the Rec. 709 luminance of the RGB albedo."""
    return float(sum(w * c for w, c in zip(REC709_LUMA, rgb, strict=True)))


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An ``.npz`` archive (readable by ``numpy.load``) with fixed timestamps: byte-identical runs."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(arrays):
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(arrays[name]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, member.getvalue())
    return buffer.getvalue()


def brdf_arrays(appearance) -> dict[str, np.ndarray]:
    """The arrays of ``brdf.npz``: the table (see :class:`render.gonio.BrdfTable`) and the models.

    ``model_*`` are the compact model's tables (:class:`render.tabulated_ndf.TabulatedMicrofacet`:
    the NDF over its nodes, the masking, multiple-scattering, albedo and body tables),
    ``model_relative_error`` and ``model_table_noise`` its error against the table and the
    table's own noise, ``model_used`` 1 where it stands in for the table (0: the table is
    used); ``fit_*`` the analytic fit beside it (distribution; alpha_u, alpha_v, azimuth,
    body albedo; its error).
    """
    arrays = appearance.table.arrays()
    compact = appearance.fit
    if hasattr(compact.model, "arrays"):
        arrays.update(compact.model.arrays())
    arrays["model_relative_error"] = np.float64(compact.relative_error)
    arrays["model_table_noise"] = np.float64(compact.table_noise)
    use = appearance.metrics.get("representation", {}).get("use")
    arrays["model_used"] = np.int8(1 if use == "model" else 0)
    analytic = appearance.analytic if appearance.analytic is not None else compact
    fit = analytic.model
    arrays["fit_distribution"] = np.array(fit.distribution)
    arrays["fit_params"] = np.array([fit.alpha_u, fit.alpha_v, fit.azimuth_rad, fit.body_albedo])
    arrays["fit_relative_error"] = np.float64(analytic.relative_error)
    return arrays


@njit(cache=True)
def _top_surface(vertices, faces, x0, y0, pitch_x, pitch_y, heights):
    ny, nx = heights.shape
    for f in range(faces.shape[0]):
        ax, ay, az = vertices[faces[f, 0], 0], vertices[faces[f, 0], 1], vertices[faces[f, 0], 2]
        bx, by, bz = vertices[faces[f, 1], 0], vertices[faces[f, 1], 1], vertices[faces[f, 1], 2]
        cx, cy, cz = vertices[faces[f, 2], 0], vertices[faces[f, 2], 1], vertices[faces[f, 2], 2]
        area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if area <= 0.0:
            continue  # facing down or vertical: never the top surface
        c0 = max(int(math.ceil((min(ax, bx, cx) - x0) / pitch_x - 1e-9)), 0)
        c1 = min(int(math.floor((max(ax, bx, cx) - x0) / pitch_x + 1e-9)), nx - 1)
        r0 = max(int(math.ceil((min(ay, by, cy) - y0) / pitch_y - 1e-9)), 0)
        r1 = min(int(math.floor((max(ay, by, cy) - y0) / pitch_y + 1e-9)), ny - 1)
        for r in range(r0, r1 + 1):
            py = y0 + r * pitch_y
            for c in range(c0, c1 + 1):
                px = x0 + c * pitch_x
                w0 = ((bx - px) * (cy - py) - (cx - px) * (by - py)) / area
                w1 = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / area
                w2 = 1.0 - w0 - w1
                if w0 >= -1e-12 and w1 >= -1e-12 and w2 >= -1e-12:
                    z = w0 * az + w1 * bz + w2 * cz
                    if z > heights[r, c]:
                        heights[r, c] = z


def heightfield_from_mesh(path: Path, pitch_mm: float | None = None) -> HeightField:
    """The top surface of a mesh tile (the highest upward-facing triangle over each point).

    Sampled on a grid of ``pitch_mm`` (default: the median edge length of the upward
    triangles, the grid's own spacing for a slab from ``printapp emboss``, whose samples
    are then met exactly) over the tile's footprint, one pitch inside its outline. Undercuts are
    not seen: this is the surface a camera and a light straight above would see.
    """
    from printapp.mesh import read_mesh

    mesh = read_mesh(path)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    up = mesh.face_normals[:, 2] > 0.1
    if not np.any(up):
        raise PrintappError(f"{path}: the mesh has no upward-facing surface to measure")
    if pitch_mm is None:
        # The top's own edges (walls and floor have long ones): on a grid slab, two of each
        # triangle's three edges are the grid's spacing, so the median is the spacing.
        top = faces[up]
        edges = np.linalg.norm(vertices[top] - vertices[np.roll(top, 1, axis=1)], axis=2).ravel()
        pitch_mm = float(np.median(edges))
    if not (math.isfinite(pitch_mm) and pitch_mm > 0):
        raise PrintappError(f"--pitch-mm: expected a positive, finite pitch, got {pitch_mm}")
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    nx_f, ny_f = (hi[0] - lo[0]) / pitch_mm - 1, (hi[1] - lo[1]) / pitch_mm - 1
    if nx_f < 8 or ny_f < 8:
        raise PrintappError(
            f"{path}: the tile is too small for pitch {pitch_mm:g} mm (fewer than 8 x 8 samples)"
        )
    area = float((hi[0] - lo[0]) * (hi[1] - lo[1]))
    require(
        BASE_BYTES + nx_f * ny_f * BRDF_BYTES_PER_SAMPLE,
        what=f"a {nx_f:.0f} x {ny_f:.0f}-sample top surface",
        setting="--pitch-mm",
        fitting=f"--pitch-mm {math.sqrt(area / max(fits(BRDF_BYTES_PER_SAMPLE), 1.0)):.4g} fits",
    )
    nx, ny = int(nx_f), int(ny_f)
    heights = np.full((ny, nx), -np.inf)
    _top_surface(vertices, faces, lo[0] + pitch_mm, lo[1] + pitch_mm, pitch_mm, pitch_mm, heights)
    if not np.all(np.isfinite(heights)):
        raise PrintappError(f"{path}: the top surface has holes; expected a closed tile seen from above")
    return HeightField(heights, pitch_mm, pitch_mm, lo[0] + pitch_mm, lo[1] + pitch_mm)


def parse_incident(spec: str | None) -> tuple[tuple[float, float], ...] | None:
    """``"THETA:PHI,THETA:PHI"`` in degrees (or bare ``THETA`` for phi = 0)."""
    if spec is None:
        return None
    pairs = []
    for item in spec.split(","):
        theta, _, phi = item.strip().partition(":")
        try:
            t, p = float(theta), float(phi) if phi else 0.0
        except ValueError:
            raise PrintappError(
                f"--incident-deg: expected THETA:PHI pairs in degrees, got '{item}'"
            ) from None
        if not (0.0 <= t < 90.0) or not math.isfinite(p):
            raise PrintappError(f"--incident-deg: polar angles must lie in [0, 90) degrees, got '{item}'")
        pairs.append((t, p))
    if not pairs:
        raise PrintappError("--incident-deg: expected at least one THETA:PHI pair")
    return tuple(pairs)


def brdf_plot_png(appearance, title: str) -> bytes:
    """The table as polar maps (one per incident direction, log scale) and cuts in the plane of
    incidence, as PNG bytes."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from render.tabulated_bins import model_bins

    table = appearance.table
    n_in = table.wi.shape[0]
    cols = min(n_in, 4)
    rows = -(-n_in // cols)
    fig = plt.figure(figsize=(3.0 * cols, 3.0 * rows + 3.2), dpi=100)
    theta_c = 0.5 * (table.theta_o_edges[:-1] + table.theta_o_edges[1:])
    f_pos = table.f[table.f > 0]
    vmin = float(np.percentile(f_pos, 5)) if f_pos.size else 1e-3
    vmax = float(table.f.max()) if f_pos.size else 1.0
    for k in range(n_in):
        ax = fig.add_subplot(rows + 1, cols, k + 1, projection="polar")
        mesh = ax.pcolormesh(
            table.phi_o_edges,
            np.degrees(table.theta_o_edges),
            np.clip(table.f[k], vmin, None),
            norm=LogNorm(vmin=vmin, vmax=max(vmax, vmin * 10)),
            cmap="magma",
            shading="flat",
        )
        wi = table.wi[k]
        ax.set_title(
            f"in {math.degrees(math.acos(wi[2])):.0f}°, {math.degrees(math.atan2(wi[1], wi[0])) % 360:.0f}°",
            fontsize=8,
        )
        ax.set_yticks([30, 60, 90])
        ax.tick_params(labelsize=6)
    fig.colorbar(mesh, ax=fig.axes, shrink=0.6, label="f (1/sr)")
    # Cuts through the plane of incidence: the table with its error bars, and the fit.
    fitted = model_bins(appearance.fit.model, table.wi, table.theta_o_edges, table.phi_o_edges)
    ax = fig.add_subplot(rows + 1, 1, rows + 1)
    n_phi = table.f.shape[2]
    for k in range(n_in):
        phi_i = math.atan2(table.wi[k, 1], table.wi[k, 0]) % (2 * math.pi)
        forward = int(((phi_i + math.pi) % (2 * math.pi)) / (2 * math.pi) * n_phi) % n_phi
        back = int(phi_i / (2 * math.pi) * n_phi) % n_phi
        angle = np.concatenate([-np.degrees(theta_c[::-1]), np.degrees(theta_c)])
        measured = np.concatenate([table.f[k, ::-1, back], table.f[k, :, forward]])
        error = np.concatenate([table.stderr[k, ::-1, back], table.stderr[k, :, forward]])
        model = np.concatenate([fitted[k, ::-1, back], fitted[k, :, forward]])
        line = ax.errorbar(angle, measured, yerr=error, fmt=".", ms=2, lw=0.5)
        ax.plot(angle, model, "-", lw=0.8, color=line[0].get_color())
    ax.set_yscale("log")
    ax.set_xlabel("outgoing angle in the plane of incidence (deg, + towards the mirror side)")
    ax.set_ylabel("f (1/sr)")
    fit = appearance.fit
    ax.set_title(
        f"{title}: dots the traced table, lines the compact {fit.model.distribution} model "
        f"(relative error {fit.relative_error:.1%}, table noise {fit.table_noise:.1%})",
        fontsize=9,
    )
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


@dataclass(frozen=True)
class PredictedFile:
    """``printapp brdf``'s result: the prediction, the relief it came from, and the files written."""

    predicted: Appearance
    field: HeightField
    origin: str
    """What the relief is: the as-printed relief of a design, a height map, a mesh tile's top."""
    written: list[Path]


def predict_file(
    source: Path,
    out: Path,
    *,
    plot: Path | None = None,
    json_out: Path | None = None,
    ior: float | None = None,
    body_albedo: float | None = None,
    incident_deg: str | None = None,
    rays: int = 200_000,
    lobe_error: float | None = None,
    max_rays: int = 100_000_000,
    theta_bins: int = 45,
    phi_bins: int = 90,
    distribution: str = "auto",
    seed: int | None = None,
    periodic: bool = False,
    width_mm: float | None = None,
    depth_mm: float | None = None,
    pitch_mm: float | None = None,
    flatten: str | None = None,
) -> PredictedFile:
    """Predict the BRDF of a design (``.toml``: its as-printed relief and material), a mesh tile
    (its top surface) or a height map, and write the table, the metrics and the plot.

    Options left None take the design's values (index, grey body albedo, lobe error,
    BRDF seed), else 1.5, 0.8, none and 0. All outputs are written, or none.
    """
    import json

    from printapp.outputs import atomic_write_files
    from printapp.topography import load_corrected
    from render.appearance import DEFAULT_INCIDENT_DEG, predict_appearance

    if out.suffix.lower() != ".npz":
        raise PrintappError(f"{out}: expected an output file ending in .npz")
    if plot is not None and plot.suffix.lower() != ".png":
        raise PrintappError(f"{plot}: expected a plot file ending in .png")
    incident = parse_incident(incident_deg) or DEFAULT_INCIDENT_DEG
    suffix = source.suffix.lower()
    design_ior, design_albedo, design_lobe_error, design_seed = 1.5, 0.8, None, 0
    if suffix == ".toml":
        from printapp.design_io import load_design
        from printapp.relief import appearance_field

        design = load_design(source)
        field, origin = appearance_field(design)
        design_ior = design.material.refractive_index
        design_albedo = grey_albedo(design.material.body_albedo)
        design_lobe_error = design.brdf.lobe_error
        design_seed = design.brdf.seed
    elif suffix in MESH_SUFFIXES:
        field, origin = heightfield_from_mesh(source, pitch_mm), "mesh tile's top surface"
    else:
        corrected = load_corrected(
            source, width_mm=width_mm, depth_mm=depth_mm, pitch_mm=pitch_mm, flatten=flatten
        )
        field, origin = corrected.field(), "height map"
        ny, nx = field.shape
        require(
            BASE_BYTES + float(nx) * ny * BRDF_BYTES_PER_SAMPLE,
            what=f"tracing a {nx} x {ny}-sample height map",
            setting=str(source),
        )
    n_ior = design_ior if ior is None else ior
    rho = design_albedo if body_albedo is None else body_albedo
    if not (1.0 <= n_ior <= 3.0):
        raise PrintappError(f"--ior: expected a refractive index in [1, 3], got {n_ior:g}")
    if not (0.0 <= rho <= 1.0):
        raise PrintappError(f"--body-albedo: expected a value in [0, 1], got {rho:g}")
    target = design_lobe_error if lobe_error is None else lobe_error
    if target is not None and not (0.0 < target < 1.0):
        raise PrintappError(f"--lobe-error: expected a fraction in (0, 1), e.g. 0.01, got {target:g}")
    predicted = predict_appearance(
        field,
        ior=n_ior,
        body_albedo=rho,
        incident_deg=incident,
        rays=rays,
        n_theta=theta_bins,
        n_phi=phi_bins,
        seed=design_seed if seed is None else seed,
        periodic=periodic,
        distribution=distribution,
        lobe_error_target=target,
        max_rays=max_rays,
    )
    outputs = [(out, npz_bytes(brdf_arrays(predicted)))]
    metrics = {"source": str(source), "from": origin, "grid": list(field.shape), **predicted.metrics}
    if json_out is not None:
        outputs.append((json_out, (json.dumps(metrics, indent=2) + "\n").encode()))
    if plot is not None:
        outputs.append((plot, brdf_plot_png(predicted, source.name)))
    return PredictedFile(predicted, field, origin, atomic_write_files(outputs))
