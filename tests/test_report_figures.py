"""The report's BRDF maps, drawn without matplotlib: their colours against matplotlib's own."""

import io

import matplotlib
import numpy as np
import pytest
from matplotlib.colors import LogNorm
from PIL import Image

from printapp.report_figures import _log_ticks, colormap, log_colours


@pytest.fixture(scope="module")
def demo_appearance():
    import noise
    from noise.heightfield import HeightField
    from render.appearance import predict_appearance

    x = np.linspace(0.0, 6.0, 96)
    heights = 0.05 * noise.fbm_grid(x, x, octaves=3, seed=2)
    return predict_appearance(HeightField(heights, 4.0, 4.0), rays=20_000, n_theta=18, n_phi=36)


@pytest.mark.parametrize("name", ["magma", "RdBu_r"])
def test_stored_colour_maps_are_matplotlibs(name):
    ours = colormap(name).astype(float)
    theirs = matplotlib.colormaps[name](np.arange(256))[:, :3] * 255.0
    assert ours.shape == (256, 3)
    assert np.max(np.abs(ours - theirs)) <= 0.5 + 1e-9  # rounded to 8 bits, nothing else


@pytest.mark.parametrize("name", ["magma", "RdBu_r"])
def test_log_colours_map_values_as_lognorm_and_colormap_do(name):
    rng = np.random.default_rng(3)
    vmin, vmax = 0.03, 7.0
    # Across the scale, beyond both ends, and on the ends themselves.
    values = np.concatenate([np.exp(rng.uniform(np.log(1e-3), np.log(50.0), 20_000)), [vmin, vmax]])
    ours = log_colours(values, vmin, vmax, name).astype(float)
    norm = LogNorm(vmin=vmin, vmax=vmax)
    theirs = matplotlib.colormaps[name](norm(values))[:, :3] * 255.0
    assert np.max(np.abs(ours - theirs)) <= 0.5 + 1e-9


def test_log_ticks_are_one_two_five_decades_within_the_scale():
    assert _log_ticks(0.03, 0.7) == pytest.approx([0.05, 0.1, 0.2, 0.5])
    assert _log_ticks(1.0, 10.0) == pytest.approx([1.0, 2.0, 5.0, 10.0])


def test_brdf_figure_shows_the_table_and_model_in_their_colours(demo_appearance):
    from printapp.report_figures import DISC_PX, brdf_figure_png

    image = np.asarray(Image.open(io.BytesIO(brdf_figure_png(demo_appearance))).convert("RGB"))
    assert image.shape[0] > 400 and image.shape[1] > 400
    # The first row's first disc: the traced table at normal incidence, in magma's colours.
    cx, cy = 120, 50 + DISC_PX // 2
    patch = image[cy - 20 : cy + 20, cx - 20 : cx + 20].reshape(-1, 3).astype(int)
    lut = colormap("magma").astype(int)
    distance = np.min(np.abs(patch[:, None, :] - lut[None, :, :]).sum(-1), axis=1)
    assert np.median(distance) == 0 and np.mean(distance <= 3) > 0.9  # the rings cross it a little
