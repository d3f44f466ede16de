"""The preview's stratified sampler (render.progressive) against independent references: an image
must not move with a sampling parameter, must agree with Mitsuba's own film loop and its independent
sampler, and passes above 64 samples must lower the variance as their count says. Statistical,
with fixed seeds; the "where it fails" case is Mitsuba's ``ldsampler``, which this module used
until it was found to fail the first check."""

import numpy as np
import pytest

from render.convergence import LUMINANCE
from tests.scenes import coated_grooves_renderer

WIDTH, HEIGHT = 96, 72
SPP = 64
SEEDS = 16


def _renderer(mirror_probability: float):
    """The V-groove tile, its coat drawing the mirror with this probability."""
    from render.mitsuba_adapter import choose_variant

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("the stratified sampler runs on Mitsuba's vectorised variants")
    return coated_grooves_renderer(mirror_probability, WIDTH, HEIGHT)


@pytest.fixture(scope="module")
def mask():
    """The tile's pixels, fixed once (the means below must be over the same pixels)."""
    return _renderer(0.7).aovs(16, 0)["coverage"] >= 0.5


def _means(renderer, mask, spp=SPP, seeds=range(SEEDS)):
    """The object's mean luminance in independent renders."""
    return np.array([(renderer.render(spp, 1000 + s) @ LUMINANCE)[mask].mean() for s in seeds])


def _z(a: np.ndarray, b: np.ndarray) -> float:
    """How many standard errors apart two sets of independent estimates' means are."""
    se = np.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    return abs(a.mean() - b.mean()) / se


def test_the_image_does_not_move_with_the_coats_mirror_probability(mask):
    drawn_often, drawn_less = _means(_renderer(0.7), mask), _means(_renderer(0.4), mask)
    assert _z(drawn_often, drawn_less) < 4.0
    assert drawn_often.mean() == pytest.approx(drawn_less.mean(), rel=0.002)


@pytest.mark.slow
def test_the_image_agrees_with_mitsubas_film_loop_and_independent_sampler(mask):
    import mitsuba as mi

    renderer = _renderer(0.4)
    ours = _means(renderer, mask)
    scene_dict = dict(renderer.scene_dict)
    sensor = dict(scene_dict["sensor"])
    sensor["film"] = dict(sensor["film"], rfilter={"type": "box"})  # each sample in its own pixel
    sensor["sampler"] = {"type": "independent", "sample_count": SPP}
    scene_dict["sensor"] = sensor
    scene = mi.load_dict(scene_dict)

    def film_loop(seed: int) -> np.ndarray:
        return np.asarray(mi.render(scene, seed=seed), dtype=np.float64)[..., :3] @ LUMINANCE

    theirs = np.array([film_loop(7 + 131 * s)[mask].mean() for s in range(2 * SEEDS)])
    assert _z(ours, theirs) < 4.0
    # and stratified: a pixel's variance well under the independent sampler's (2.3x on this tile)
    ours_pixels = np.stack([renderer.render(SPP, 1000 + s) @ LUMINANCE for s in range(8)])[:, mask]
    theirs_pixels = np.stack([film_loop(7 + 131 * s) for s in range(8)])[:, mask]
    assert ours_pixels.var(0, ddof=1).mean() < 0.7 * theirs_pixels.var(0, ddof=1).mean()


def test_mitsubas_ldsampler_fails_the_mirror_probability_check(mask, monkeypatch):
    """Where it fails: ``ldsampler`` scrambles every dimension of a pixel with the same bits, so the
    lobe choices at two bounces are correlated; its mean moves by about 1.2 % (60 standard errors)."""
    import render.progressive

    monkeypatch.setattr(render.progressive, "SAMPLER", "ldsampler")
    drawn_often, drawn_less = _means(_renderer(0.7), mask), _means(_renderer(0.4), mask)
    assert _z(drawn_often, drawn_less) > 10.0


def test_a_pass_above_64_samples_is_deterministic_and_as_good_as_its_count():
    renderer = _renderer(0.7)
    one = renderer.render(256, 5)
    assert np.array_equal(one, renderer.render(256, 5))
    many = np.stack([renderer.render(256, 10 + s) @ LUMINANCE for s in range(6)])
    few = np.stack([renderer.render(64, 20 + s) @ LUMINANCE for s in range(6)])
    ratio = many.var(0, ddof=1).mean() / few.var(0, ddof=1).mean()
    assert 0.18 < ratio < 0.32  # four independent passes of 64: a quarter of the variance
