"""``printapp fit`` on the vein photos (Marble006, Marble020, Marble021): every measure within 1.5 times the
photo's own variation, a model that draws veins, and a side-by-side image for a person to look at."""

from pathlib import Path

import numpy as np
import pytest

from printapp.fit import fit_photo
from printapp.fit_outputs import side_by_side
from printapp.photo import read_photo

SAMPLES = Path(__file__).parent.parent / "printapp" / "samples" / "marble"
pytestmark = pytest.mark.slow  # three whole fits, 35 s: `make test` runs them, `make test-fast` does not

VEIN_PHOTOS = ("Marble006_512.jpg", "Marble020_512.jpg", "Marble021_512.webp")
BUDGET = 90
"""The command's default."""


@pytest.fixture(scope="module")
def vein_fits(tmp_path_factory):
    fits = {name: fit_photo(read_photo(SAMPLES / name), budget=BUDGET) for name in VEIN_PHOTOS}
    # The photos and their fits side by side, kept in pytest's temporary folder for a person to look at.
    rows = [
        side_by_side([r.photo.rgb, r.chosen.rgb], [name, f"{r.chosen.name}, score {r.score:.2f}"])
        for name, r in fits.items()
    ]
    folder = tmp_path_factory.mktemp("fit_vein_photos")
    for name, png in zip(VEIN_PHOTOS, rows, strict=True):
        (folder / f"{Path(name).stem}_fit.png").write_bytes(png)
    print(f"\nvein photo fits, photo | fit: {folder}")
    return fits


@pytest.mark.parametrize("name", VEIN_PHOTOS)
def test_vein_photos_come_back_as_veins_within_their_own_variation(vein_fits, name):
    result = vein_fits[name]
    scores = {k: round(r.score, 2) for k, r in result.reports.items()}
    assert result.chosen.name == "veined", (name, scores)
    for measure, ratio in result.chosen.ratios.items():
        assert ratio <= 1.5, (name, measure, result.chosen.ratios)
    assert not result.warnings
    # The fit beats the random-phase texture (the photo's own spectrum) where veins show: lines,
    # their layout and their continuity.
    phase = result.metrics()["ratios"]["random_phase"]
    for measure in ("lines", "continuity"):
        assert result.chosen.ratios[measure] < phase[measure], (measure, result.chosen.ratios, phase)


def test_vein_fits_print_their_veins(vein_fits):
    from printapp.design import design_from_dict
    from printapp.texture import relief_heightfield

    for result in vein_fits.values():
        texture = result.chosen.texture.model_dump(mode="python")
        design = design_from_dict(
            {"base": {"width_mm": 8.0, "depth_mm": 8.0}, "relief": {"pitch_mm": 0.05}, "texture": texture}
        )
        heights = relief_heightfield(design).heights_mm
        # Veins are thin: the top tenth of the relief's range covers little of the surface.
        top = heights > heights.max() - 0.1 * np.ptp(heights)
        assert 0.0 < top.mean() < 0.05
