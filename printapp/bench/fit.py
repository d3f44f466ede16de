"""``printapp bench fit``: textures fitted to photos, beside the random-phase texture and the previous method.

For every photo in ``printapp/samples/marble`` and ``printapp/samples/textures`` (512 px copies;
see ``printapp/samples/SOURCES.md``), ``printapp fit`` with its defaults (every model, the
chosen one's report): each measure of :mod:`printapp.fit_measures` as a ratio to the photo's
own variation, for the fit, for the random-phase texture with the photo's exact spectrum
(Galerne et al. 2011; the best any stationary Gaussian texture does on the spectrum) and
for the previous method (``printapp fit`` before issue #16, its fragments kept in
``printapp/bench/previous_fits``), side by side; and the gallery (photo | fit | random
phase | previous method) as ``fit_gallery.jpg``.

Then: the whole ``printapp fit`` command, timed as a user runs it (a fresh process,
Python's start-up and imports included, numba's compilation cached by an earlier run),
median of repeats, on two photos; quality against fitting time as the veins' budget
grows; and the recovery of textures made independently of the project's noise
(spectral-synthesis fBm, Perlin marble; :mod:`printapp.bench.reference`).
"""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.resources import as_file, files
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from printapp.bench.timing import StageResult
from printapp.errors import PrintappError

if TYPE_CHECKING:
    from printapp.photo import Photo

BUDGETS = (30, 60, 120, 240)
SWEEP_PHOTOS = ("Marble006_512.jpg", "Marble021_512.webp")
COMMAND_PHOTOS = ("Marble020_512.jpg", "gravel.png")
_THUMB = 160
_PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp")
MEASURE_KEYS = ("spectrum", "orientation", "values", "lines", "layout", "continuity")


def _photos() -> list[Traversable]:
    """The package's sample photos: marble/, then textures/, each in name order."""
    # Resources, not paths beside this file: an installed wheel has the samples too.
    root = files("printapp") / "samples"
    photos = [
        entry
        for folder in ("marble", "textures")
        if (root / folder).is_dir()
        for entry in sorted((root / folder).iterdir(), key=lambda e: e.name)
        if entry.name.lower().endswith(_PHOTO_SUFFIXES)
    ]
    if not photos:
        raise PrintappError(f"{root}: bench fit found no photos in the package's samples/marble and textures")
    return photos


def _read(photo: Traversable, max_side: int = 512) -> Photo:
    from printapp.photo import read_photo

    with as_file(photo) as path:
        return read_photo(path, max_side)


def previous_method(photo: Photo, name: str) -> np.ndarray | None:
    """The previous method's synthesis of a photo (its stored fragment, rendered as ``texture --from``)."""
    from printapp.design_io import load_design
    from printapp.fit import synthesise
    from printapp.texture import palette_colours

    fragment = files("printapp") / "bench" / "previous_fits" / f"{Path(name).stem}.toml"
    if not fragment.is_file():
        return None
    with as_file(fragment) as path:
        texture = load_design(path).texture
    scale_mm = 20.0 / photo.analysed_px[0]  # the previous fits' default: the photo spans 20 mm
    values = synthesise(texture, photo.lum.shape, scale_mm)
    return palette_colours(values, texture)


def _ratios_of(rgb: np.ndarray, photo_halves, own) -> dict[str, float]:
    from printapp.fit_measures import half_stats, halves_distance, ratios
    from printapp.photo import LUMA

    return ratios(halves_distance(half_stats(rgb @ LUMA, rgb), photo_halves), own)


def command_seconds(photo: Traversable, repeats: int) -> list[float]:
    """Wall times of the whole ``printapp fit`` command on ``photo``, each in a fresh process."""
    times = []
    with as_file(photo) as path, tempfile.TemporaryDirectory() as folder:
        command = [
            sys.executable,
            "-c",
            "from printapp.cli import main; main()",
            "fit",
            str(path),
            "-o",
            str(Path(folder) / "fitted.toml"),
            "--json",
            str(Path(folder) / "metrics.json"),
            "--quiet",
        ]
        subprocess.run(command, check=True, capture_output=True, timeout=900)  # warm: numba's cache
        for _ in range(repeats):
            start = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True, timeout=900)
            times.append(time.perf_counter() - start)
    return times


def recovery() -> dict[str, Any]:
    """Independently made textures fitted back: spectral fBm's H, Perlin marble's period and direction."""
    from printapp.bench.reference.perlin_marble import perlin_marble
    from printapp.bench.reference.spectral_fbm import spectral_fbm
    from printapp.fit import fit_photo
    from printapp.fit_spectral import fit_spectral
    from printapp.photo import Photo

    fbm_rows = []
    for H in (0.2, 0.3, 0.5, 0.7, 0.9):
        for seed in (1, 2, 3):
            image = spectral_fbm(512, H, seed=seed)
            fbm_rows.append({"H": H, "seed": seed, "fitted_H": round(fit_spectral("fbm", image)[0]["H"], 4)})
    marble_rows = []
    for period, angle, strength, scale in (
        (24.0, 30.0, 1.0, 32.0),
        (32.0, 120.0, 2.0, 48.0),
        (40.0, 75.0, 3.0, 64.0),
    ):
        image = perlin_marble(
            256, period_px=period, angle_deg=angle, strength=strength, turbulence_px=scale, seed=4
        )
        photo = Photo("perlin marble", np.repeat(image[..., None], 3, axis=-1), image, (256, 256))
        for seed in range(5):
            params = fit_photo(photo, model="marble", seed=seed, budget=8).reports["marble"].params
            marble_rows.append(
                {
                    "period_px": period,
                    "angle_deg": angle,
                    "strength": strength,
                    "seed": seed,
                    "period_error": round(params["vein_period_px"] / period - 1.0, 4),
                    "angle_error_deg": round((params["vein_angle_deg"] - angle + 90.0) % 180.0 - 90.0, 3),
                }
            )
    errors = [abs(r["fitted_H"] - r["H"]) for r in fbm_rows]
    return {
        "spectral_fbm": fbm_rows,
        "spectral_fbm_max_H_error": round(max(errors), 4),
        "perlin_marble": marble_rows,
        "perlin_marble_max_period_error": max(abs(r["period_error"]) for r in marble_rows),
        "perlin_marble_max_angle_error_deg": max(abs(r["angle_error_deg"]) for r in marble_rows),
    }


def _thumb(rgb: np.ndarray):
    from PIL import Image

    image = Image.fromarray(np.round(np.clip(rgb[::-1], 0, 1) * 255).astype(np.uint8), mode="RGB")
    return image.resize((_THUMB, _THUMB), Image.Resampling.LANCZOS)


def _cell(fit: float, phase: float, previous: float | None) -> str:
    prev = "-" if previous is None else f"{previous:.2f}"
    return f"{fit:.2f} / {phase:.2f} / {prev}"


def bench_fit(repeats: int) -> StageResult:
    """Photos to textures: ratios beside the random phase and the previous method, time, budget, recovery."""
    from printapp.fit import fit_photo
    from printapp.fit_measures import half_stats, line_maps, own_distance

    reps = max(3, min(repeats, 5))
    photos = _photos()
    fit_photo(_read(photos[0], max_side=96), budget=8)  # warm: numba caches, noise spectra, imports
    rows: list[dict[str, Any]] = []
    gallery: list[tuple[str, Any, Any, Any, Any, str]] = []
    details: dict[str, Any] = {}
    for path in photos:
        photo = _read(path)
        start = time.perf_counter()
        result = fit_photo(photo)
        seconds = time.perf_counter() - start
        maps = line_maps(photo.lum)
        pieces = half_stats(photo.lum, photo.rgb, maps)
        own = own_distance(pieces)
        previous_rgb = previous_method(photo, path.name)
        previous = None if previous_rgb is None else _ratios_of(previous_rgb, pieces, own)
        phase = result.metrics()["ratios"]["random_phase"]
        row: dict[str, Any] = {
            "image": path.name,
            "model": result.chosen.name,
            "score": round(result.score, 3),
            "warned": any("does not explain" in w or "constant" in w for w in result.warnings),
            "fit_s": round(seconds, 2),
        }
        for key in MEASURE_KEYS:
            row[key] = _cell(
                result.chosen.ratios[key], phase[key], None if previous is None else previous[key]
            )
        row["other scores"] = ", ".join(
            f"{k} {r.score:.2f}" for k, r in result.reports.items() if r is not result.chosen
        )
        rows.append(row)
        details[path.name] = {
            "fit": result.chosen.ratios,
            "random_phase": phase,
            "previous": previous,
            "params": {
                k: v for k, v in result.chosen.params.items() if k not in ("palette", "palette_values")
            },
            "model_seconds": {k: round(r.seconds, 3) for k, r in result.reports.items()},
        }
        gallery.append(
            (path.name, photo.rgb, result.chosen.rgb, result.random_phase_rgb, previous_rgb, row["model"])
        )

    commands = {}
    for name in COMMAND_PHOTOS:
        photo_path = next((p for p in photos if p.name == name), None)
        if photo_path is not None:
            times = command_seconds(photo_path, reps)
            commands[name] = {
                "median_s": round(statistics.median(times), 2),
                "runs_s": [round(t, 2) for t in times],
            }

    sweep: list[dict[str, Any]] = []
    for name in SWEEP_PHOTOS:
        photo = _read(next(p for p in photos if p.name == name))
        for budget in BUDGETS:
            start = time.perf_counter()
            result = fit_photo(photo, model="veined", budget=budget)
            seconds = time.perf_counter() - start
            report = result.chosen
            sweep.append(
                {
                    "image": name,
                    "budget": budget,
                    "evaluations": report.evaluations,
                    "fit_s": round(seconds, 2),
                    "search_s": round(report.seconds, 2),
                    "objective": round(report.objective, 3),
                    "score": round(result.score, 3),
                    "worst_ratio": round(max(report.ratios.values()), 3),
                }
            )

    recovered = recovery()

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from PIL import Image, ImageDraw

        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), dpi=110)
        for name, marker in zip(SWEEP_PHOTOS, ("o", "s"), strict=True):
            sel = [r for r in sweep if r["image"] == name]
            axes[0].plot(
                [r["fit_s"] for r in sel], [r["score"] for r in sel], marker + "-", label=f"{name} score"
            )
            axes[0].plot(
                [r["fit_s"] for r in sel],
                [r["worst_ratio"] for r in sel],
                marker + ":",
                label=f"{name} worst ratio",
            )
            for r in sel:
                axes[0].annotate(str(r["budget"]), (r["fit_s"], r["score"]), fontsize=6)
        axes[0].axhline(1.5, color="grey", ls=":", lw=0.8)
        axes[0].set_xscale("log")
        axes[0].set_xlabel("fit time, veined model and its report (s)")
        axes[0].set_ylabel("score; worst measure's ratio (grey: 1.5)")
        axes[0].set_title("quality against time as the veins' budget grows (labels)")
        axes[0].legend(fontsize=6)
        x = np.arange(len(rows))
        for k, (label, key) in enumerate(
            (("fit", "fit"), ("random phase", "random_phase"), ("previous", "previous"))
        ):
            worst = [max((details[r["image"]][key] or {"-": math.nan}).values()) for r in rows]
            axes[1].bar(x + (k - 1) * 0.27, worst, 0.27, label=label)
        axes[1].axhline(1.5, color="grey", ls=":", label="1.5")
        axes[1].set_yscale("log")
        axes[1].set_xticks(
            x, [r["image"].split(".")[0][:14] for r in rows], rotation=40, ha="right", fontsize=7
        )
        axes[1].set_title("worst measure's ratio to the photo's own variation")
        axes[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

        label_h = 14
        sheet = Image.new("RGB", (4 * (_THUMB + 4), len(gallery) * (_THUMB + label_h)), (255, 255, 255))
        draw = ImageDraw.Draw(sheet)
        for i, (name, photo_rgb, fit_rgb, phase_rgb, previous_rgb, model) in enumerate(gallery):
            top = i * (_THUMB + label_h)
            draw.text(
                (2, top + 1),
                f"{name}: photo | {model} fit {rows[i]['score']:.2f} | random phase | previous",
                fill=0,
            )
            for j, rgb in enumerate((photo_rgb, fit_rgb, phase_rgb, previous_rgb)):
                if rgb is not None:
                    sheet.paste(_thumb(rgb), (j * (_THUMB + 4), top + label_h))
        # JPEG: a sheet of photos is ten times smaller than as PNG, and is not a chart.
        target = path.parent / "fit_gallery.jpg"
        partial = path.parent / ".fit_gallery.jpg.partial"
        sheet.save(partial, format="JPEG", quality=88)
        partial.replace(target)

    notes = [
        "each measure: fit / random phase / previous method, as a ratio to the photo's own variation "
        "(its halves against each other; 1 = as close as that, 1.5 = the tests' bar)",
        "fit_s: printapp fit's work in process (every model, the report, the baseline), default budget; "
        + "; ".join(
            f"whole command on {k}: median {v['median_s']} s of {v['runs_s']}" for k, v in commands.items()
        ),
        "gallery: fit_gallery.jpg beside the chart (photo | fit | random phase | previous method)",
        f"recovery: spectral fBm H within {recovered['spectral_fbm_max_H_error']} (15 cases); Perlin marble "
        f"period within {recovered['perlin_marble_max_period_error']:.1%}, direction within "
        f"{recovered['perlin_marble_max_angle_error_deg']} deg (15 fits)",
    ]
    return StageResult(
        "fit",
        "photos to textures: ratios to each photo's own variation, beside random phase and the previous fit",
        rows,
        chart,
        notes,
        {"measures": details, "command": commands, "budget_sweep": sweep, "recovery": recovered},
    )
