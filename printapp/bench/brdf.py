"""``printapp bench brdf``: the virtual gonioreflectometer beside Embree and Mitsuba 3.

Two 512 x 512 tiles: the default design's relief patch (resampled with a cubic spline
from its 424 x 424 grid to 512 x 512 over the same 20 mm) and a periodic Gaussian
random surface (white noise smoothed with a Gaussian of 4 pixels, wrapped, scaled to
an RMS slope ``Sdq`` of 0.2). The design patch does not tile, so it is traced as the
pipeline traces it (``periodic=False``: the beam lights the patch's interior).

Throughput: primary rays per second of the whole estimator (``render.gonio.estimate_brdf``:
every bounce, Fresnel splitting, the pigmented body, binning), with a black body and
with a pigmented one, beside raw first-hit queries on the *same* primary rays (the
estimator's own origins, regenerated bit for bit from its random stream, direction
``-wi``) by ``embreex`` (Embree) and by Mitsuba 3's ``scene.ray_intersect`` on the
``llvm_ad_rgb`` variant, over a mesh that is the tracer's surface exactly: four
triangles per cell around a centre vertex at the mean of its corners, the wrap-around
cells included, and a ring of periodic copies wide enough that every first hit of a
primary ray lies on the mesh. The numba tracer's own first-hit query (``render.gonio.first_hit``)
is timed on the same rays too, and the peers' first hits are checked against it.

Time against error: rays per direction from 1e3 to 1e6 (1e7 at normal incidence) on
the design tile, for the specular lobe (the bins of ``f_specular`` that hold the top
90 % of its energy ``E_b = f_b omega_b``): the estimator's own standard error, weighted
by energy, ``sum E_b (s_b / f_b) / sum E_b = sum omega_b s_b / sum omega_b f_b``, and the
actual deviation from an independent 1e7-ray reference run (another seed), weighted
the same way.

Target: the default 7-direction table of the design tile to 1 % specular-lobe error in
under 10 s, and the estimator at least as fast per primary ray as Embree's first hits.

The rays, the mesh and the first-hit queries live in :mod:`printapp.bench.brdf_hits`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from printapp.bench.brdf_hits import (
    Peers,
    TracerFirstHit,
    hit_agreement,
    mesh_margin_cells,
    periodic_mesh,
    primary_rays,
)
from printapp.bench.timing import StageResult, interleaved_seconds
from render.gonio import lobe_bins, lobe_error

SIDE = 512
ANGLES_DEG = (0.0, 60.0, 85.0)
BODY_ALBEDOS = (0.0, 0.8)
THROUGHPUT_RAYS = 500_000
SWEEP_RAYS = (1_000, 10_000, 100_000, 1_000_000)
BIG_RAYS = 10_000_000  # only at normal incidence, once
REFERENCE_RAYS = 10_000_000
REFERENCE_SEED = 1
TARGET_ERROR = 0.01
TARGET_SECONDS = 10.0
CALIBRATION_RAYS = 500_000
GAUSSIAN_CORR_PX = 4.0
GAUSSIAN_SDQ = 0.2


# --- the tiles --------------------------------------------------------------------------------


def design_tile(side: int = SIDE) -> tuple[np.ndarray, float, float, str]:
    """The default design's relief patch on a ``side x side`` grid: heights (mm), pitches (mm), how."""
    from scipy.ndimage import zoom

    from printapp.design_io import load_default_design
    from printapp.relief import build_relief

    patch = build_relief(load_default_design()).patch
    ny, nx = patch.shape
    if (ny, nx) == (side, side):
        return patch.heights_mm.copy(), patch.pitch_x_mm, patch.pitch_y_mm, f"{nx}x{ny} as built"
    # Same extent, corner samples kept (grid_mode=False): only the sample spacing changes.
    heights = zoom(patch.heights_mm, (side / ny, side / nx), order=3, mode="nearest", grid_mode=False)
    px = patch.pitch_x_mm * (nx - 1) / (side - 1)
    py = patch.pitch_y_mm * (ny - 1) / (side - 1)
    how = (
        f"resampled (cubic spline) from {nx}x{ny} at {patch.pitch_x_mm * 1000:.2f} um "
        f"to {side}x{side} at {px * 1000:.2f} um over the same {patch.width_mm:.1f} mm"
    )
    return heights, px, py, how


def tracer_slopes(heights: np.ndarray, px: float, py: float) -> tuple[np.ndarray, np.ndarray]:
    """x and y slopes of the four triangles of every periodic cell, as the tracer sees them."""
    from render.gonio import facet_slopes

    return facet_slopes(heights, px, py)


def gaussian_tile(
    side: int = SIDE, pitch_mm: float = 0.04, sdq: float = GAUSSIAN_SDQ, seed: int = 0
) -> np.ndarray:
    """A periodic Gaussian random surface (mm) with RMS slope ``sqrt(<|grad h|^2>) = sdq``."""
    from scipy.ndimage import gaussian_filter

    base = gaussian_filter(
        np.random.default_rng(seed).normal(size=(side, side)), GAUSSIAN_CORR_PX, mode="wrap"
    )
    gx, gy = tracer_slopes(base, pitch_mm, pitch_mm)
    return base * (sdq / math.sqrt(np.mean(gx * gx + gy * gy)))


# --- the specular lobe's error -------------------------------------------------------------


def lobe_deviation(f: np.ndarray, reference: np.ndarray, omega: np.ndarray, bins: np.ndarray) -> float:
    """Energy-weighted (by the reference) mean relative deviation from the reference over ``bins``."""
    w = omega.ravel()[bins]
    return float(
        np.sum(w * np.abs(f.ravel()[bins] - reference.ravel()[bins])) / np.sum(w * reference.ravel()[bins])
    )


# --- timing helpers ------------------------------------------------------------------------


def _loglog_slope(x: list[float], y: list[float]) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


# --- the stage -----------------------------------------------------------------------------


def _throughput(geometries, estimate, repeats, notes, rates) -> tuple[list[dict[str, Any]], dict]:
    """Part 1 and 2: the whole estimator beside first-hit queries on the same primary rays."""
    from render.gonio import direction_from_angles

    rows: list[dict[str, Any]] = []
    peers_by_geometry: dict[str, tuple[Peers, int, int]] = {}
    for name, h, px, py, periodic in geometries:
        mx = mesh_margin_cells(h, px, max(ANGLES_DEG))
        my = mesh_margin_cells(h, py, max(ANGLES_DEG))
        vertices, faces = periodic_mesh(h, px, py, mx, my)
        peers = Peers(vertices, faces, notes if not peers_by_geometry else [])
        peers_by_geometry[name] = (peers, mx, my)
        tracer = TracerFirstHit(h, px, py)
        for theta in ANGLES_DEG:
            wi = direction_from_angles(np.radians([theta]), np.radians([0.0]))
            origins, dirs = primary_rays(h, px, py, wi, THROUGHPUT_RAYS, periodic=periodic)
            fns: dict[str, Callable[[], Any]] = {}
            warm: dict[str, Callable[[], Any]] = {}
            for albedo, tag in zip(BODY_ALBEDOS, ("black", "pigment"), strict=True):
                args = (h, px, py, wi, albedo, periodic)
                fns[tag] = lambda a=args: estimate(*a, THROUGHPUT_RAYS)
                warm[tag] = lambda a=args: estimate(*a, 2000)
            fns["tracer"] = lambda o=origins, d=dirs, f=tracer: f(o, d)
            warm["tracer"] = lambda o=origins, d=dirs, f=tracer: f(o[:2000], d[:2000])
            if peers.embree is not None:
                o32, d32 = origins.astype(np.float32), dirs.astype(np.float32)
                fns["embreex"] = lambda o=o32, d=d32, p=peers: p.embree_hits(o, d)
                warm["embreex"] = lambda o=o32, d=d32, p=peers: p.embree_hits(o[:2000], d[:2000])
            if peers.mitsuba is not None:
                ray = peers.mitsuba_ray(origins, dirs)
                fns["mitsuba"] = lambda r=ray, p=peers: p.mitsuba_hits(r)
                warm["mitsuba"] = fns["mitsuba"]  # the kernel compiles for this ray count
            seconds, last, cores = interleaved_seconds(fns, repeats, warm)
            rate = {k: THROUGHPUT_RAYS / s for k, s in seconds.items()}
            row: dict[str, Any] = {"geometry": name, "theta_i_deg": theta}
            for tag in ("black", "pigment"):
                segments = float(last[tag].extra["segments"][0])
                row[f"est_{tag}_Mrays_s"] = round(rate[tag] / 1e6, 3)
                row[f"est_{tag}_seg_per_ray"] = round(segments / THROUGHPUT_RAYS, 3)
                row[f"est_{tag}_Mseg_s"] = round(segments / seconds[tag] / 1e6, 3)
            t_ref, cells_ref = last["tracer"]
            row["tracer_first_hit_Mrays_s"] = round(rate["tracer"] / 1e6, 3)
            row["embreex_Mrays_s"] = None
            row["mitsuba_Mrays_s"] = None
            if "embreex" in last:
                hits = last["embreex"]
                same, dt = hit_agreement(t_ref, cells_ref, hits["tfar"], hits["primID"], h.shape, mx, my)
                row["embreex_Mrays_s"] = round(rate["embreex"] / 1e6, 3)
                row["embreex_cpu_per_wall"] = round(cores["embreex"], 2)
                row["embreex_same_triangle"] = round(same, 5)
                row["embreex_median_rel_dt"] = float(f"{dt:.2g}")
                row["est_black_vs_embreex"] = round(rate["black"] / rate["embreex"], 3)
                row["est_pigment_vs_embreex"] = round(rate["pigment"] / rate["embreex"], 3)
            if "mitsuba" in last:
                si = last["mitsuba"]
                prim = np.where(np.asarray(si.is_valid()), np.asarray(si.prim_index).astype(np.int64), -1)
                same, dt = hit_agreement(t_ref, cells_ref, np.asarray(si.t), prim, h.shape, mx, my)
                row["mitsuba_Mrays_s"] = round(rate["mitsuba"] / 1e6, 3)
                row["mitsuba_same_triangle"] = round(same, 5)
                row["mitsuba_median_rel_dt"] = float(f"{dt:.2g}")
            rates[(name, theta)] = rate
            rows.append(row)
        notes.append(
            f"{name}: mesh of {faces.shape[0]:,} triangles (the 512^2 tile's {4 * SIDE * SIDE:,} and a "
            f"ring of {mx} x {my} periodic cells so every first hit is on it)"
            + (f"; Embree BVH {peers.embree_build_s:.2f} s" if peers.embree is not None else "")
            + (f", Mitsuba scene {peers.mitsuba_build_s:.2f} s" if peers.mitsuba is not None else "")
            + " (builds not in the rates)"
        )
    return rows, peers_by_geometry


def _sweep(estimate, geometry, repeats) -> tuple[list[dict[str, Any]], dict[float, tuple[float, float]]]:
    """Part 3: time against the specular lobe's error, per incident angle, on one geometry."""
    from render.gonio import direction_from_angles

    _, h, px, py, periodic = geometry
    sweep: list[dict[str, Any]] = []
    slopes: dict[float, tuple[float, float]] = {}
    for theta in ANGLES_DEG:
        wi = direction_from_angles(np.radians([theta]), np.radians([0.0]))
        args = (h, px, py, wi, None, periodic)
        reference = estimate(*args, REFERENCE_RAYS, seed=REFERENCE_SEED)
        omega = reference.projected_solid_angle
        f_ref, s_ref = reference.f_specular[0], reference.stderr_specular[0]
        bins = lobe_bins(f_ref, omega)
        w = omega.ravel()[bins]
        for n in list(SWEEP_RAYS) + ([BIG_RAYS] if theta == 0.0 else []):
            reps = repeats if n <= 1_000_000 else 1
            seconds, last, _ = interleaved_seconds(
                {"est": lambda n=n, a=args: estimate(*a, n)}, reps, {"est": lambda a=args: estimate(*a, 1000)}
            )
            fs, ses = last["est"].f_specular[0], last["est"].stderr_specular[0]
            combined = np.sqrt(ses.ravel()[bins] ** 2 + s_ref.ravel()[bins] ** 2)
            expected = math.sqrt(2.0 / math.pi) * float(
                np.sum(w * combined) / np.sum(w * f_ref.ravel()[bins])
            )
            sweep.append(
                {
                    "theta_i_deg": theta,
                    "rays": n,
                    "median_s": round(seconds["est"], 4),
                    "timed_runs": reps,
                    "segments_per_ray": round(float(last["est"].extra["segments"][0]) / n, 4),
                    "lobe_bins": int(bins.size),
                    "lobe_stderr": float(f"{lobe_error(fs, ses, omega, bins):.4g}"),
                    "lobe_deviation": float(f"{lobe_deviation(fs, f_ref, omega, bins):.4g}"),
                    "expected_deviation": float(f"{expected:.4g}"),
                    "reference_stderr": float(f"{lobe_error(f_ref, s_ref, omega, bins):.4g}"),
                }
            )
        sel = [r for r in sweep if r["theta_i_deg"] == theta and r["rays"] >= 10_000]
        # The deviation from an equal-ray reference is the reference's noise too: fit below it.
        dev = [r for r in sel if r["rays"] < REFERENCE_RAYS]
        slopes[theta] = (
            _loglog_slope([r["rays"] for r in sel], [r["lobe_stderr"] for r in sel]),
            _loglog_slope([r["rays"] for r in dev], [r["lobe_deviation"] for r in dev]),
        )
    return sweep, slopes


def _round_up(x: float) -> int:
    """``x`` rounded up to two significant digits."""
    scale = 10 ** max(0, int(math.floor(math.log10(max(x, 1.0)))) - 1)
    return int(math.ceil(x / scale) * scale)


def _target(estimate, geometry, peers_entry, repeats) -> dict[str, Any]:
    """Part 4: the default 7-direction table of the design tile to 1 % specular-lobe error."""
    from render.appearance import DEFAULT_INCIDENT_DEG
    from render.gonio import direction_from_angles

    _, h, px, py, periodic = geometry
    inc = np.asarray(DEFAULT_INCIDENT_DEG, dtype=np.float64)
    n_in = len(inc)
    wi7 = direction_from_angles(np.radians(inc[:, 0]), np.radians(inc[:, 1]))
    args = (h, px, py, wi7, None, periodic)
    fns: dict[str, Callable[[], Any]] = {"est": lambda: estimate(*args, CALIBRATION_RAYS)}
    warm: dict[str, Callable[[], Any]] = {"est": lambda: estimate(*args, 1000)}
    peers, _, _ = peers_entry
    sub = 100_000  # per direction for embreex: a rate, on a subset of the same rays
    if peers.embree is not None:
        origins, dirs = primary_rays(h, px, py, wi7, sub, periodic=periodic)
        o32, d32 = origins.astype(np.float32), dirs.astype(np.float32)
        fns["embreex"] = lambda: peers.embree_hits(o32, d32)
        warm["embreex"] = lambda: peers.embree_hits(o32[:2000], d32[:2000])
    seconds, last, _ = interleaved_seconds(fns, repeats, warm)
    cal = last["est"]
    omega = cal.projected_solid_angle
    cal_err = [lobe_error(cal.f_specular[k], cal.stderr_specular[k], omega) for k in range(n_in)]
    # The error falls as 1/sqrt(rays) (checked in part 3): the rays each direction needs.
    per_dir = np.array(
        [_round_up(CALIBRATION_RAYS * (e / TARGET_ERROR) ** 2) for e in cal_err], dtype=np.int64
    )
    # The warm-up is the calibration run above; the same seed gives the same table every time.
    check_run = {"check": lambda: estimate(*args, per_dir)}
    t_check_all, last, _ = interleaved_seconds(check_run, min(repeats, 3), {})
    t_check, check = t_check_all["check"], last["check"]
    check_err = [lobe_error(check.f_specular[k], check.stderr_specular[k], omega) for k in range(n_in)]
    est_rate = n_in * CALIBRATION_RAYS / seconds["est"]
    target: dict[str, Any] = {
        "incident_deg": inc.tolist(),
        "calibration_rays_per_direction": CALIBRATION_RAYS,
        "calibration_median_s": round(seconds["est"], 3),
        "calibration_lobe_error": [round(e, 5) for e in cal_err],
        "rays_needed_per_direction": per_dir.tolist(),
        "rays_needed_total": int(per_dir.sum()),
        "per_direction_run_s": round(t_check, 2),
        "per_direction_timed_runs": max(1, min(repeats, 3)),
        "per_direction_run_lobe_error": [round(e, 5) for e in check_err],
        "per_direction_run_rays_per_s": round(float(per_dir.sum()) / t_check, 1),
        "uniform_rays_needed": int(per_dir.max()),
        "uniform_seconds_extrapolated": round(n_in * int(per_dir.max()) / est_rate, 1),
        "target_s": TARGET_SECONDS,
        "estimator_rays_per_s": round(est_rate, 1),
    }
    if "embreex" in seconds:
        emb_rate = n_in * sub / seconds["embreex"]
        target["embreex_first_hit_rays_per_s"] = round(emb_rate, 1)
        target["estimator_vs_embreex"] = round(est_rate / emb_rate, 3)
    return target


def bench_brdf(repeats: int) -> StageResult:
    """Throughput beside Embree and Mitsuba, time against error, and the 1 % target."""
    from numba import get_num_threads

    from printapp.brdf import grey_albedo
    from printapp.design_io import load_default_design
    from render.gonio import estimate_brdf

    stage_start = time.perf_counter()
    notes: list[str] = []
    design = load_default_design()
    design_albedo = grey_albedo(design.material.body_albedo)
    ior = design.material.refractive_index
    n_theta, n_phi = design.brdf.theta_bins, design.brdf.phi_bins

    def estimate(h, px, py, wi, albedo, periodic, rays, seed: int = 0) -> Any:
        return estimate_brdf(
            h, px, py, wi, rays=rays, ior=ior, body_albedo=design_albedo if albedo is None else albedo,
            n_theta=n_theta, n_phi=n_phi, seed=seed, periodic=periodic,
        )  # fmt: skip

    h_design, px_design, py_design, how = design_tile()
    geometries = [
        ("design tile", h_design, px_design, py_design, False),
        ("Gaussian", gaussian_tile(pitch_mm=px_design), px_design, px_design, True),
    ]
    notes.append(f"design tile: default design's relief patch, {how}; traced with periodic=False")
    notes.append(
        f"Gaussian: white noise, gaussian_filter sigma {GAUSSIAN_CORR_PX:g} px (wrap), RMS slope "
        f"Sdq {GAUSSIAN_SDQ} on the tracer's facets, pitch {px_design * 1000:.2f} um, periodic=True"
    )
    load_before = os.getloadavg()[0]
    rates: dict[tuple[str, float], dict[str, float]] = {}
    rows, peers_by_geometry = _throughput(geometries, estimate, repeats, notes, rates)
    sweep, slopes = _sweep(estimate, geometries[0], repeats)
    target = _target(estimate, geometries[0], peers_by_geometry[geometries[0][0]], repeats)
    stage_s = time.perf_counter() - stage_start
    load_after = os.getloadavg()[0]

    peers = peers_by_geometry[geometries[0][0]][0]
    notes.append(
        f"threads: numba {get_num_threads()}"
        + (", embreex 1 (its run() loops over rays holding the GIL)" if peers.embree is not None else "")
        + (f", Dr.Jit {peers.dr.thread_count()} ({peers.variant})" if peers.mitsuba is not None else "")
        + f"; load average {load_before:.1f} before, {load_after:.1f} after (2 cores, shared)"
    )
    notes.append(
        f"throughput: {THROUGHPUT_RAYS:,} primary rays per direction, phi_i = 0, median of {repeats} after a "
        f"warm-up, engines timed in turn within each repeat; ior {ior}, bins {n_theta} x {n_phi}; "
        "est_*_Mrays_s counts primary rays, est_*_Mseg_s traced segments (every ray the tracer follows: "
        "primaries, reflections, rays leaving the body); cpu_per_wall: cores kept busy"
    )
    notes.append(
        "same_triangle: fraction of primary rays whose peer first hit is the tracer's own (cell, triangle); "
        "median_rel_dt: median relative difference of the hit distance (float32 peers against float64)"
    )
    for theta, (s_err, s_dev) in slopes.items():
        sel = [r for r in sweep if r["theta_i_deg"] == theta and r["rays"] == 1_000_000][0]
        to_target = sel["median_s"] * (sel["lobe_stderr"] / TARGET_ERROR) ** 2
        notes.append(
            f"time vs error at {theta:g} deg: log-log slope of the lobe's standard error against rays "
            f"{s_err:.3f}, of its deviation from the reference {s_dev:.3f} (1/sqrt(rays) is -0.5); "
            f"1 % in this one direction: about {to_target:.1f} s (from the 1e6 row)"
        )
    worst = max(target["per_direction_run_lobe_error"])
    met = target["per_direction_run_s"] <= TARGET_SECONDS and worst <= TARGET_ERROR * 1.05
    notes.append(
        f"target, default 7-direction table of the design tile ({n_theta} x {n_phi} bins, body albedo "
        f"{design_albedo:.3f}): 1 % specular-lobe error takes {target['rays_needed_total']:,} rays, per "
        f"direction from a {CALIBRATION_RAYS:,}-ray run "
        f"({', '.join(f'{n:,}' for n in target['rays_needed_per_direction'])}); that run took "
        f"{target['per_direction_run_s']:.1f} s (median of {target['per_direction_timed_runs']}; worst "
        f"direction {100 * worst:.2f} %): the 10 s target is "
        + ("met" if met else "NOT met")
        + "; with one ray count for all directions (as predict_appearance has) "
        f"{target['uniform_rays_needed']:,} each, about {target['uniform_seconds_extrapolated']} s "
        "(extrapolated from the calibration rate)"
    )
    if "estimator_vs_embreex" in target:
        notes.append(
            "target, estimator rays/s against embreex first-hit rays/s on the same 7-direction primary "
            f"rays: {target['estimator_vs_embreex']:.2f} (>= 1 wanted: "
            + ("met)" if target["estimator_vs_embreex"] >= 1.0 else "NOT met)")
        )
    notes.append(
        f"the 1e7-ray run at 0 deg is timed once; the reference runs ({REFERENCE_RAYS:,} rays, seed "
        f"{REFERENCE_SEED}) carry errors of their own: expected_deviation is sqrt(2/pi) times the combined "
        f"standard error (the mean absolute value of a normal error); stage wall time {stage_s:.0f} s"
    )

    def chart(path: Path) -> None:
        _chart(path, rows, sweep, rates, target, geometries[0][0])

    result = StageResult(
        "brdf",
        "virtual gonioreflectometer (numba) beside Embree (embreex) and Mitsuba 3 first hits, 512^2 tiles",
        rows,
        chart,
        notes,
    )
    result.extra = {"time_vs_error": sweep, "target": target}
    return result


def _chart(path: Path, rows, sweep, rates, target, name) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import ScalarFormatter

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), dpi=110)
    ax = axes[0]
    for k, theta in enumerate(ANGLES_DEG):
        colour = f"C{k}"
        sel = [r for r in sweep if r["theta_i_deg"] == theta]
        t = [r["median_s"] for r in sel]
        ax.loglog(t, [r["lobe_stderr"] for r in sel], "o-", color=colour, label=f"{theta:g} deg, std error")
        ax.loglog(
            t, [r["lobe_deviation"] for r in sel], "x--", color=colour, label=f"{theta:g} deg, vs reference"
        )
        rate = rates[(name, theta)]
        if "embreex" in rate:
            # Embree's queries alone for the estimator's segments: a floor for an Embree-based estimator.
            n = np.array([r["rays"] for r in sel], dtype=float)
            ax.loglog(
                n * np.array([r["segments_per_ray"] for r in sel]) / rate["embreex"],
                [r["lobe_stderr"] for r in sel], ":",
                color=colour, alpha=0.7, label=f"{theta:g} deg, embreex queries alone, same segments",
            )  # fmt: skip
    worst = max(target["per_direction_run_lobe_error"])
    ax.loglog([target["per_direction_run_s"]], [worst], "k*", ms=12, label="7-direction table, 1 % in each")
    ax.axhline(TARGET_ERROR, color="grey", ls=":", lw=1)
    ax.axvline(TARGET_SECONDS, color="grey", ls="-.", lw=1)
    ax.set_xlabel("seconds per incident direction (median; star: the whole table)")
    ax.set_ylabel("specular-lobe relative error (energy-weighted)")
    ax.set_title("design tile 512², time against error (1 % and 10 s lines)")
    ax.legend(fontsize=6, ncol=1, loc="lower left")
    ax = axes[1]
    labels = [f"{r['geometry']}\n{r['theta_i_deg']:g} deg" for r in rows]
    series = [
        ("est_black_Mrays_s", "estimator, black body", "0.2", None),
        ("est_pigment_Mrays_s", "estimator, pigmented body (0.8)", "C1", None),
        ("tracer_first_hit_Mrays_s", "numba tracer, first hit only", "C2", "//"),
        ("embreex_Mrays_s", "embreex first hit (1 core)", "C0", None),
        ("mitsuba_Mrays_s", "Mitsuba llvm_ad_rgb first hit", "C3", None),
    ]
    x = np.arange(len(rows))
    width = 0.8 / len(series)
    for j, (key, label, colour, hatch) in enumerate(series):
        values = [r.get(key) or 0.0 for r in rows]
        ax.bar(x + (j - (len(series) - 1) / 2) * width, values, width, label=label, color=colour, hatch=hatch)
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_yscale("log")
    # Bars on a log axis start at its bottom: put it well below the smallest bar.
    smallest = min(r.get(key) or math.inf for r in rows for key, *_ in series)
    ax.set_ylim(bottom=0.5 * smallest)
    ax.yaxis.set_major_formatter(ScalarFormatter())
    ax.yaxis.set_minor_formatter(ScalarFormatter())
    ax.tick_params(axis="y", which="minor", labelsize=7)
    ax.set_ylabel("million primary rays per second (2 cores)")
    ax.set_title("throughput on the same primary rays (medians)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
