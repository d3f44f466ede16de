"""``printapp bench fit``: fitting noise to photos, time against quality.

For every photo in ``printapp/samples/marble`` and ``printapp/samples/textures`` (512 px copies; see
``printapp/samples/SOURCES.md``): the time of a full ``printapp fit`` (all three models, the
baselines and the score; median of repeats, warm), the chosen model, its score, and
the three quality measures beside the two baselines computed in the same run: random
parameters of the same model and the random-phase texture with the photo's spectrum
(the peer: the best any stationary Gaussian texture does on the spectrum, for the
price of two FFTs). A gallery (``fit_gallery.jpg``) shows photo, fit and random-phase texture per row.

Then quality against fitting time as the optimiser's budget grows, per model, on two
veined marbles.
"""

from __future__ import annotations

from importlib.resources import as_file, files
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from printapp.bench.timing import StageResult, interleaved_seconds
from printapp.errors import PrintappError

if TYPE_CHECKING:
    from printapp.photo import Photo

BUDGETS = (8, 32, 64, 160, 320)
SWEEP_PHOTOS = ("Marble006_512.jpg", "Marble020_512.jpg")
_THUMB = 160
_PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp")


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


def _recovery() -> dict[str, Any]:
    """Parameter recovery on the project's own noise at 512 px: random cases, errors and misses."""
    import noise
    from printapp.fit_measures import Target
    from printapp.fit_search import fit_model

    rng = np.random.default_rng(5)
    n = 512
    out: dict[str, Any] = {}
    for lacunarity in (2.0, 2.5):
        errors = []
        for k in range(12):
            H, feature = rng.uniform(0.2, 0.9), float(np.exp(rng.uniform(np.log(10), np.log(64))))
            x = (np.arange(n) + 0.5) / feature
            image = noise.fbm_grid(
                x, x, octaves=8, lacunarity=lacunarity, H=H, seed=500 + k, min_pitch=1 / feature
            )
            target = Target.of(image, f_max=0.4, glcm_distances=(1, 2, 4, 8, 16))
            values = fit_model("fbm", image, target, seed=0).values
            errors.append((values["H"] - H, feature / values["feature_px"] - 1.0))
        e = np.array(errors)
        out[f"fbm, lacunarity {lacunarity:g}"] = {
            "cases": len(e),
            "H_rms_error": round(float(np.sqrt(np.mean(e[:, 0] ** 2))), 4),
            "H_outside_0.1": int(np.sum(np.abs(e[:, 0]) > 0.1)),
            "frequency_rms_rel_error": round(float(np.sqrt(np.mean(e[:, 1] ** 2))), 4),
            "frequency_outside_15pc": int(np.sum(np.abs(e[:, 1]) > 0.15)),
        }
    errors = []
    for k in range(12):
        feature, low = float(np.exp(rng.uniform(np.log(12), np.log(80)))), int(rng.integers(0, 2))
        high = low + int(rng.integers(1, 5))
        x = (np.arange(n) + 0.5) / feature
        image = noise.turbulence_grid(x, x, low=low, high=high, seed=600 + k, min_pitch=1 / feature)
        target = Target.of(image, f_max=0.4, glcm_distances=(1, 2, 4, 8, 16))
        values = fit_model("turbulence", image, target, seed=0).values
        kept = noise.octaves_for_pitch(high - low + 1, 2.0, 2.0**low / feature)
        errors.append((feature / 2.0**low / values["feature_px"] - 1.0, values["octaves"] - kept))
    e = np.array(errors)
    out["turbulence"] = {
        "cases": len(e),
        "frequency_rms_rel_error": round(float(np.sqrt(np.mean(e[:, 0] ** 2))), 4),
        "frequency_outside_15pc": int(np.sum(np.abs(e[:, 0]) > 0.15)),
        "octave_errors": [int(v) for v in e[:, 1]],
    }
    return out


def _thumb(rgb: np.ndarray):
    from PIL import Image

    image = Image.fromarray(np.round(np.clip(rgb[::-1], 0, 1) * 255).astype(np.uint8), mode="RGB")
    return image.resize((_THUMB, _THUMB), Image.Resampling.LANCZOS)


def bench_fit(repeats: int) -> StageResult:
    """Photos to noise parameters: time, score and quality beside the baselines, and the budget sweep."""
    from noise.spectra import random_phase
    from printapp.fit import fit_photo

    reps = max(1, min(repeats, 3))
    rows: list[dict[str, Any]] = []
    gallery: list[tuple[str, Any, Any, Any]] = []
    measures: dict[str, Any] = {}
    photos = _photos()
    fit_photo(_read(photos[0], max_side=64), budget=8)  # warm: numba caches, noise spectra, imports
    for path in photos:
        photo = _read(path)
        timed = {"fit": lambda p=photo: fit_photo(p), "phase": lambda p=photo: random_phase(p.rgb, 0)}
        medians, last, _ = interleaved_seconds(timed, reps)
        seconds, result, phase_s = medians["fit"], last["fit"], medians["phase"]
        m = result.metrics()["measures"]
        row: dict[str, Any] = {
            "image": path.name,
            "px": photo.analysed_px[0],
            "model": result.chosen.name,
            "score": round(result.score, 3),
            "warned": any("does not explain" in w or "constant" in w for w in result.warnings),
            "fit_s": round(seconds, 3),
            "phase_s": round(phase_s, 4),
        }
        # Each measure as fit / random parameters / random phase / photo halves.
        for key, short in (
            ("log_spectrum_distance", "spectrum"),
            ("wasserstein", "W1"),
            ("glcm_difference", "GLCM"),
        ):
            row[short] = " / ".join(
                f"{m[k][key]:.3g}" for k in ("fit", "random_parameters", "random_phase", "photo_halves")
            )
        others = (f"{k} {r.score:.2f}" for k, r in result.reports.items() if r is not result.chosen)
        row["other scores"] = ", ".join(others)
        rows.append(row)
        measures[path.name] = m
        gallery.append((path.name, photo.rgb, result.chosen.rgb, result.random_phase_rgb))

    sweep: list[dict[str, Any]] = []
    for name in SWEEP_PHOTOS:
        photo = _read(next(p for p in photos if p.name == name))
        for model in ("fbm", "turbulence", "marble"):
            for budget in BUDGETS:
                medians, last, _ = interleaved_seconds(
                    {"fit": lambda p=photo, m=model, b=budget: fit_photo(p, model=m, budget=b)}, 1
                )
                seconds, result = medians["fit"], last["fit"]
                report = result.chosen
                sweep.append(
                    {
                        "image": name,
                        "model": model,
                        "budget": budget,
                        "evaluations": report.fit.evaluations,
                        "fit_s": round(seconds, 3),
                        "objective": round(report.fit.objective, 4),
                        "score": round(result.score, 3),
                        "spec_fit": round(report.measures.spectrum, 4),
                    }
                )

    recovery = _recovery()

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from PIL import Image

        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), dpi=110)
        for name, marker in zip(SWEEP_PHOTOS, ("o", "s"), strict=True):
            for model, colour in (("fbm", "C0"), ("turbulence", "C1"), ("marble", "C2")):
                sel = [r for r in sweep if r["image"] == name and r["model"] == model]
                axes[0].plot(
                    [r["fit_s"] for r in sel],
                    [r["score"] for r in sel],
                    marker + "-",
                    color=colour,
                    label=f"{model}, {name.split('_')[0]}",
                )
                for r in sel:
                    axes[0].annotate(str(r["budget"]), (r["fit_s"], r["score"]), fontsize=6)
        axes[0].set_xscale("log")
        axes[0].set_xlabel("fit time, one model + report (s)")
        axes[0].set_ylabel("score (1 = as close as the photo's halves)")
        axes[0].set_title("quality against time as the budget grows (labels)")
        axes[0].legend(fontsize=6)
        x = np.arange(len(rows))
        axes[1].bar(x - 0.2, [r["score"] for r in rows], 0.4, label="score")
        axes[1].bar(x + 0.2, [r["fit_s"] / 10.0 for r in rows], 0.4, label="fit time / 10 s")
        axes[1].axhline(0.5, color="grey", ls=":", label="warning below 0.5")
        axes[1].set_xticks(
            x, [r["image"].split(".")[0][:14] for r in rows], rotation=40, ha="right", fontsize=7
        )
        axes[1].set_title("every photo, auto model, 512 px")
        axes[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

        label_h = 14
        sheet = Image.new("RGB", (3 * _THUMB + 8, len(gallery) * (_THUMB + label_h)), (255, 255, 255))
        from PIL import ImageDraw

        draw = ImageDraw.Draw(sheet)
        for i, (name, photo_rgb, fit_rgb, phase_rgb) in enumerate(gallery):
            top = i * (_THUMB + label_h)
            row = rows[i]
            draw.text(
                (2, top + 1), f"{name}: photo | {row['model']} fit {row['score']:.2f} | random phase", fill=0
            )
            for j, rgb in enumerate((photo_rgb, fit_rgb, phase_rgb)):
                sheet.paste(_thumb(rgb), (j * (_THUMB + 4), top + label_h))
        # JPEG: a sheet of photos is ten times smaller than as PNG, and is not a chart.
        target = path.parent / "fit_gallery.jpg"
        partial = path.parent / ".fit_gallery.jpg.partial"
        sheet.save(partial, format="JPEG", quality=88)
        partial.replace(target)

    notes = [
        "fit_s: printapp fit (three models, report, baselines) on the 512 px copy, warm, median; "
        "phase_s: the peer, the random-phase texture (two FFTs per channel)",
        "spectrum (decades), W1 (luminance), GLCM: fit / random parameters / random phase / photo halves",
        "gallery: fit_gallery.jpg beside the chart; the budget sweep is in bench.json",
        *(f"recovery, {name}: {summary}" for name, summary in recovery.items()),
    ]
    return StageResult(
        "fit",
        "fitting noise to photos: time, score and quality against the baselines",
        rows,
        chart,
        notes,
        {"budget_sweep": sweep, "measures": measures, "recovery": recovery},
    )
