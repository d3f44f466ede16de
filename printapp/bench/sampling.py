"""``printapp bench sampling``: a preview sampled adaptively beside the same preview sampled uniformly.

The geometry previews of the CAD examples (``part_relief``, ``brushed_part_fbm``) and of
``brushed_cylinder`` (where an earlier, per-pixel-capped allocation gained nothing), from
``./examples`` (run from a checkout), are built by whole ``printapp design`` processes with
``[render] sampling = "uniform"`` and ``"adaptive"`` in turn within each repeat, the time cap
raised to 20 minutes so that both reach the 2 % noise goal. Each row gives the median seconds
of the render stage (from the manifest) and of the whole command, the mean samples per object
pixel and their range (which depend on the image only, so are the same in every repeat), and
the noise reached. The accuracy side needs no reference: both previews are held to the same
noise goal, measured the same way (:mod:`render.convergence`), and the samples each took are
the cost of it; the image's mean luminance, the same within the noise, shows that steering the
samples biased nothing.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from printapp.bench.timing import StageResult

EXAMPLES = ("part_relief", "brushed_part_fbm", "brushed_cylinder")
SAMPLINGS = ("uniform", "adaptive")
TIME_CAP_S = 1200.0


def _design_file(example: Path, sampling: str, folder: Path) -> Path:
    """The example resolved, with ``sampling`` and a time cap both samplings stay under."""
    from printapp.design import MeshBase
    from printapp.design_io import load_design, resolved_toml

    design = load_design(example)
    update: dict[str, Any] = {
        "render": design.render.model_copy(update={"sampling": sampling, "time_cap_s": TIME_CAP_S})
    }
    if isinstance(design.base, MeshBase):  # the copy lives elsewhere: its mesh by absolute path
        update["base"] = design.base.model_copy(update={"path": str(Path(design.base.path).resolve())})
    path = folder / f"{example.stem}-{sampling}.toml"
    path.write_text(resolved_toml(design.model_copy(update=update)))
    return path


def _build(design_file: Path, out: Path) -> dict[str, Any]:
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "printapp", "design", str(design_file), "-o", str(out), "--quiet", "--force"],
        check=True,
        capture_output=True,
        timeout=3600,
    )
    seconds = time.perf_counter() - start
    manifest = json.loads((out / "manifest.json").read_text())
    noise = manifest["render"]["noise"]
    return {
        "whole_s": seconds,
        "render_s": manifest["stages_s"]["render"],
        "spp": noise["spp"],
        "spp_range": noise.get("spp_range"),
        "noise": noise["raw_relative_noise"],
        "stopped_by": noise["stopped_by"],
        "mean_luminance": round(
            sum(
                w * c
                for w, c in zip((0.2126, 0.7152, 0.0722), manifest["render"]["mean_linear_rgb"], strict=True)
            ),
            5,
        ),
    }


def bench_sampling(repeats: int) -> StageResult:
    """Uniform and adaptive sampling of the CAD examples' previews to the same goal: seconds, samples."""
    import numpy as np

    folder_of_examples = Path.cwd() / "examples"
    notes: list[str] = []
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="printapp-bench-sampling-") as tmp:
        folder = Path(tmp)
        for name in EXAMPLES:
            example = folder_of_examples / f"{name}.toml"
            if not example.is_file():
                notes.append(f"{example}: not found (run from a checkout): no row")
                continue
            files = {s: _design_file(example, s, folder) for s in SAMPLINGS}
            runs: dict[str, list[dict[str, Any]]] = {s: [] for s in SAMPLINGS}
            for _ in range(max(1, repeats)):
                for sampling in SAMPLINGS:  # in turn: the machine's load falls on both alike
                    runs[sampling].append(_build(files[sampling], folder / f"{name}-{sampling}"))
            for sampling in SAMPLINGS:
                last = runs[sampling][-1]
                rows.append(
                    {
                        "example": name,
                        "sampling": sampling,
                        "render_s": round(statistics.median(r["render_s"] for r in runs[sampling]), 2),
                        "whole_s": round(statistics.median(r["whole_s"] for r in runs[sampling]), 2),
                        "spp_mean": last["spp"],
                        "spp_range": last["spp_range"],
                        "noise": last["noise"],
                        "stopped_by": last["stopped_by"],
                        "mean_luminance": last["mean_luminance"],
                    }
                )
            uniform, adaptive = rows[-2], rows[-1]
            rows.append(
                {
                    "example": name,
                    "sampling": "uniform / adaptive",
                    "render_s": round(uniform["render_s"] / adaptive["render_s"], 2),
                    "whole_s": round(uniform["whole_s"] / adaptive["whole_s"], 2),
                    "spp_mean": round(uniform["spp_mean"] / adaptive["spp_mean"], 2),
                }
            )

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        pairs = [r for r in rows if r["sampling"] in SAMPLINGS]
        names = list(dict.fromkeys(r["example"] for r in pairs))
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.2), dpi=110)
        x = np.arange(len(names))
        for k, sampling in enumerate(SAMPLINGS):
            mine = {r["example"]: r for r in pairs if r["sampling"] == sampling}
            axes[0].bar(x + (k - 0.5) * 0.4, [mine[n]["render_s"] for n in names], 0.4, label=sampling)
            axes[1].bar(x + (k - 0.5) * 0.4, [mine[n]["spp_mean"] for n in names], 0.4, label=sampling)
        for ax, label in zip(
            axes, ("render seconds (median)", "samples per object pixel (mean)"), strict=True
        ):
            ax.set_xticks(x, names, fontsize=8)
            ax.set_ylabel(label)
            ax.legend(fontsize=8)
        fig.suptitle("previews to 2 % noise: uniform against adaptive sampling", fontsize=9)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "sampling",
        "CAD previews to the same noise goal, sampled uniformly and adaptively (whole printapp design)",
        rows,
        chart if rows else None,
        notes,
    )
